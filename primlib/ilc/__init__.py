"""Iterative learning control: the basic loop and its convergence check.

``learn`` runs Arimoto-type P / PD / PID laws or the lifted norm-optimal law, with an
optional zero-phase Q-filter, on any Machine, all axes in parallel; ``check_learning``
computes the spectral radius and largest singular value of the lifted learning matrix
Q (I - L G) before running. Notation: see :mod:`primlib.ilc._learn`.
"""

from primlib.ilc._check import ConvergenceWarning, LearningCheck
from primlib.ilc._learn import ILCResult, check_learning, design_gains, learn
from primlib.ilc._lifted import LiftedMasterSlave, lifted_master_slave
from primlib.ilc._master_slave import MasterSlaveCheck, MasterSlaveResult, learn_master_slave
from primlib.ilc._ms_law import MasterSlaveGains, contour_error_estimate, master_slave_law
from primlib.ilc._qfilter import QFilter

__all__ = [
    "learn",
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
]
