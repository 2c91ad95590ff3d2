"""Splice: stored inputs transformed and joined into a new path's first-iteration input.

Pipeline (primitive-matching paper §3.3): a :class:`~primlib.match.Match` says which stored
primitive covers which segment of the new path, with rotation R, translation p and time
scale k; each primitive's converged input is

1. time-scaled — model-based from one stored version, ``u_l(k t)`` through the filter
   ``G(s/k) / G(s)`` of the nominal model (:func:`time_scale`), or model-free from
   versions stored at several durations, eq. (20) (:func:`time_scale_direct`);
2. superposed — axes mixed through ``P_j / P_i`` (exactly R between identical axes) plus the
   holding input of the translation (:func:`superpose`, :func:`holding_input`);
3. spliced — windows cut from the whole transformed primitive and joined by linear
   transition bands at the junctions, the paper's three cases overlap / gap / continuous
   (:func:`splice`); unmatched segments get the nominal-model inverse;
4. corrected — the model inverse of the path minus the model's error that the pieces'
   stored pairs measured (:func:`piece_error`), so the model's error only multiplies what
   the library does not already know (:class:`ErrorCorrection`, one implementation of the
   :class:`Correction` protocol), inverted without the near-Nyquist band in which the
   sampled model's sampling zeros make an exact inverse ring (:func:`band_limited_inverse`).

:func:`splice` runs the stages in order: :func:`plan_junctions` (segments and bands),
:func:`place_piece` / :func:`place_unmatched` (each segment's input on the new grid),
:func:`blend` (across the bands) and the correction.

:class:`primlib.pipeline.WarmStarter` does all of it from a library, by default on the
machine model refined on the matched primitives' own (input, path) pairs
(:func:`refine_machine`: the stored signals were learned on the real machine, so they tell
how it differs from its model), and runs ILC from it.

Which time scaling is used when: a piece with k = 1 on the grid uses the stored input as it
is; otherwise ``method="auto"`` uses eq. (20) when the primitive is stored at as many
distinct durations as the model's inverse has derivative orders (:func:`derivative_orders`
of the model the warm start uses: 2 for the XYZ machine of eq. (24), 3 once refinement has
found a lag) on an open-loop all-pole machine, and the model-based transform in every
other case (one version, plants with zeros such as the non-minimum-phase PDCCILC stage,
PID loops). ``method="model"`` / ``"direct"`` force one.

Notation: signals ``u`` have shape (n, d) on the machine's dt grid; ``k`` = primitive
duration / new duration; signals and outputs are deviations from the path's first point.
"""

from primlib.splice._blend import blend
from primlib.splice._continuous import continuous_output, resample_zoh
from primlib.splice._correct import Correction, CorrectionJob, ErrorCorrection
from primlib.splice._inverse import (
    band_limit,
    band_limited_inverse,
    model_inverse,
    sampling_zero_band,
)
from primlib.splice._place import METHODS, PlacedPiece, Placement, place_piece, place_unmatched
from primlib.splice._plan import Band, JunctionPlan, StoredSignal, plan_junctions
from primlib.splice._refine import RefinedModel, refine_machine
from primlib.splice._splice import SpliceResult, splice
from primlib.splice._transform import (
    derivative_orders,
    holding_input,
    piece_error,
    piece_path,
    superpose,
    time_scale,
    time_scale_direct,
    transform,
)

__all__ = [
    "time_scale",
    "time_scale_direct",
    "superpose",
    "transform",
    "holding_input",
    "piece_path",
    "piece_error",
    "model_inverse",
    "band_limited_inverse",
    "band_limit",
    "sampling_zero_band",
    "derivative_orders",
    "splice",
    "plan_junctions",
    "place_piece",
    "place_unmatched",
    "blend",
    "Band",
    "JunctionPlan",
    "Placement",
    "PlacedPiece",
    "Correction",
    "CorrectionJob",
    "ErrorCorrection",
    "SpliceResult",
    "StoredSignal",
    "METHODS",
    "continuous_output",
    "resample_zoh",
    "refine_machine",
    "RefinedModel",
]
