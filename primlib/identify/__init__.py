"""System identification: a machine model from one recorded experiment, and the
experiment's excitation.

``identify`` fits one continuous transfer function per axis (integrator, first- or
second-order, or the simplest that holds on held-out data) by output-error least squares on
the machine's own ZOH simulation, open loop or inside a known PID loop, and returns the
:class:`~primlib.plant.Machine` with its fit quality; ``excite`` makes the input to record
it with (a Schroeder-phased multisine or a PRBS within input, rate and velocity limits).
Notation: see :mod:`primlib.identify._fit`.
"""

from primlib.identify._excite import KINDS, PERIODS, excite
from primlib.identify._fit import AxisFit
from primlib.identify._identify import HOLDOUT, Identified, identify
from primlib.identify._structures import STRUCTURES, Structure

__all__ = [
    "identify",
    "excite",
    "KINDS",
    "PERIODS",
    "Identified",
    "AxisFit",
    "Structure",
    "STRUCTURES",
    "HOLDOUT",
]
