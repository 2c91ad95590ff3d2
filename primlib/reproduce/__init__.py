"""The source papers' studies, re-run on primlib's own code (``primlib reproduce ...``).

Each study is a pure function returning plain data (dicts of floats and lists) that the CLI
prints as JSON and ``primlib.plot`` draws; where an honest reproduction disagrees with the
paper, the study's module docstring says so and why.
"""

from primlib.reproduce._cee_mfac import PAPER_TABLE2 as CEE_PAPER
from primlib.reproduce._cee_mfac import SWEEP_SPEEDS as CEE_SWEEP_SPEEDS
from primlib.reproduce._cee_mfac import (
    CEEStudy,
    CEESweep,
    cee_mfac_study,
    cee_mfac_sweep,
    linear_motor,
)
from primlib.reproduce._pdccilc import PAPER as PDCCILC_PAPER
from primlib.reproduce._pdccilc import (
    PdccilcStudy,
    contour_reference,
    paper_machine,
    pdccilc_study,
)

__all__ = [
    "CEE_PAPER",
    "CEE_SWEEP_SPEEDS",
    "CEEStudy",
    "CEESweep",
    "cee_mfac_study",
    "cee_mfac_sweep",
    "linear_motor",
    "PDCCILC_PAPER",
    "PdccilcStudy",
    "contour_reference",
    "paper_machine",
    "pdccilc_study",
]
