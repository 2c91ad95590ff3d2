"""Model-free adaptive control (CFDL-MFAC) and cross-coupled contouring loops.

Notation (CEE-MFAC paper, eqs. (14)-(20)). Per axis, the output ``y(k)`` (position) and
input ``u(k)`` satisfy the compact-form dynamic linearisation ``dy(k+1) = phi(k) du(k)``
(eq. (15)) with an unknown, time-varying pseudo partial derivative (PPD) ``phi(k)``. The
estimator (eq. (18)) tracks ``phi`` from input/output increments; the control law (eqs.
(17), (20)) minimises ``|y*(k+1) - y(k+1)|^2 + lambda |du(k)|^2``. The axes' controllers
are decentralised; cross-coupled control (eq. (6)) adds ``K_p C eps`` with the contour
error ``eps`` from a :mod:`primlib.contour` estimator. PID is the baseline.

References
----------
Hou Zhongsheng, Jin Shangtai, Model Free Adaptive Control: Theory and Applications (2013);
ZHANG Baolin, CAO Rongmin, HOU Zhongsheng, Real-time contour error estimation and
model-free control for two-dimensional linear motor (``../shared/papers/realtime-cee-mfac.txt``).
"""

from primlib.mfac._law import CFDLMFAC, PID, MFACGains, cross_coupled, mfac_increment, ppd_update
from primlib.mfac._loop import ContourRun, run_contouring

__all__ = [
    "CFDLMFAC",
    "ContourRun",
    "MFACGains",
    "PID",
    "cross_coupled",
    "mfac_increment",
    "ppd_update",
    "run_contouring",
]
