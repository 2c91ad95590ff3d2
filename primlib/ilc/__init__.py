"""Iterative learning control: the basic loop and its convergence check.

``learn`` runs a law object (``PLaw``, ``PDLaw``, ``PIDLaw``: Arimoto type;
``NormOptimal``: lifted; ``MasterSlave``: the cross-coupled laws of ``learn_master_slave``),
each with its optional zero-phase Q-filter, or a law's name, on any Machine, all axes in
parallel; ``check_learning`` computes the spectral radius and largest singular value of the
lifted learning matrix Q (I - L G) before running. Notation: see :mod:`primlib.ilc._learn`.
"""

from primlib.ilc._check import ConvergenceWarning, LearningCheck
from primlib.ilc._design import design_gains
from primlib.ilc._laws import (
    LAW_NAMES,
    LearnOptions,
    MasterSlave,
    NormOptimal,
    PDLaw,
    PIDLaw,
    PLaw,
    law_from_name,
)
from primlib.ilc._learn import NORM_OPTIMAL_MAX_N, ILCResult, check_learning, learn
from primlib.ilc._lifted import LiftedMasterSlave, lifted_master_slave
from primlib.ilc._master_slave import MasterSlaveCheck, MasterSlaveResult, learn_master_slave
from primlib.ilc._ms_law import MasterSlaveGains, contour_error_estimate, master_slave_law
from primlib.ilc._noise import NoiseEstimate, TrialLearner, TrialUpdate, estimate_noise
from primlib.ilc._qfilter import QFilter

__all__ = [
    "learn",
    "PLaw",
    "PDLaw",
    "PIDLaw",
    "NormOptimal",
    "MasterSlave",
    "LearnOptions",
    "LAW_NAMES",
    "NORM_OPTIMAL_MAX_N",
    "law_from_name",
    "ILCResult",
    "LearningCheck",
    "ConvergenceWarning",
    "check_learning",
    "design_gains",
    "QFilter",
    "learn_master_slave",
    "MasterSlaveResult",
    "MasterSlaveCheck",
    "MasterSlaveGains",
    "master_slave_law",
    "contour_error_estimate",
    "LiftedMasterSlave",
    "lifted_master_slave",
    "TrialLearner",
    "TrialUpdate",
    "NoiseEstimate",
    "estimate_noise",
]
