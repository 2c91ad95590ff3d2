"""Paths in time: NURBS curves whose parameter is normalised time.

Notation (used throughout primlib.nurbs)
----------------------------------------
t : time in seconds, 0 <= t <= T; T the duration.
v : normalised time v = t / T in [0, 1], the NURBS parameter.
d : number of axes (2 or 3); n : number of samples; m : number of control points;
p : degree (3 unless asked otherwise).
U : knot vector, shape (m + p + 1,), clamped on [0, 1].
P_j, w_j : control points (m, d) and positive weights (m,).
N_{j,p}(v) : B-spline basis functions on U.
C(v) = sum_j N_{j,p}(v) w_j P_j / sum_j N_{j,p}(v) w_j  : the path; position at time t is C(t / T).
dC/dt = C'(v) / T and d2C/dt2 = C''(v) / T^2, with ' = d/dv.

A :class:`Trajectory` is fitted from uniformly timed samples by banded least squares (scipy),
held and exchanged as a geomdl ``NURBS.Curve`` (``.nurbs``, JSON), and evaluated with scipy
``BSpline`` in homogeneous coordinates (w P, w).
"""

from primlib.nurbs._batch import sample_many
from primlib.nurbs._files import is_json_path, read_path, read_path_samples
from primlib.nurbs._trajectory import DEFAULT_RTOL, MIN_SAMPLES, Trajectory

__all__ = [
    "Trajectory",
    "DEFAULT_RTOL",
    "MIN_SAMPLES",
    "sample_many",
    "read_path",
    "read_path_samples",
    "is_json_path",
]
