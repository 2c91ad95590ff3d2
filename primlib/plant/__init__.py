"""Machine models: per-axis continuous transfer functions, zero-order hold, PID loops.

``Machine`` simulates (vectorised ``scipy.signal.lfilter``), gives impulse responses and the
lifted (lower-triangular Toeplitz) matrices ILC designs with; ``invert`` is the nominal-model
inverse feedforward; ``toeplitz_operator`` / ``max_singular_value`` apply and measure lifted
matrices through the FFT without forming them. Notation: see :mod:`primlib.plant._machine`.
"""

from primlib.plant._departures import DEPARTURE_KEYS, scale_departures, typical_scales
from primlib.plant._invert import invert
from primlib.plant._lifted import max_singular_value, toeplitz_operator
from primlib.plant._linear_motor import LinearMotor
from primlib.plant._machine import Machine, machine_kinds, register_kind
from primlib.plant._normal import CGInfo, NormalSolver
from primlib.plant._pid import pid_polynomials
from primlib.plant._realistic import RealisticMachine, TrialRunner
from primlib.plant._spec import DT_RANGE

__all__ = [
    "Machine",
    "register_kind",
    "machine_kinds",
    "invert",
    "toeplitz_operator",
    "max_singular_value",
    "LinearMotor",
    "RealisticMachine",
    "TrialRunner",
    "DEPARTURE_KEYS",
    "scale_departures",
    "typical_scales",
    "NormalSolver",
    "CGInfo",
    "pid_polynomials",
    "DT_RANGE",
]
