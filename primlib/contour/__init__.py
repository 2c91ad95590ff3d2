"""Contour error: how far the actual position is from the path, not from the reference point.

Notation (used throughout the package). A path is a curve ``r(s)`` in 2-D or 3-D with time
``s`` in seconds (a :class:`~primlib.nurbs.Trajectory` evaluated at ``v = s / T``, or a cubic
spline in time through reference samples). The actual position at time ``t`` is ``p``; the
reference point is ``r(t)``; the tracking error is ``p - r(t)``. The *contour error* is the
distance from ``p`` to the path, signed in 2-D: **positive to the left of the direction of
travel** (``e = N . (p - r)`` with ``N`` the left unit normal, ``N = (-T_y, T_x)``). In 3-D
it is the unsigned distance.

Three estimators (``method``):

``"linear"``
    distance from ``p`` to the tangent line at the reference point ``r(t)`` (Koren 1980).
``"circular"``
    distance from ``p`` to the osculating circle at ``r(t)`` (Koren & Lo 1991; eq. (5) of the
    CEE-MFAC paper is its second-order expansion, computed here exactly and without a
    division by a vanishing curvature).
``"exact"``
    distance to the true closest point ``r(s*)`` on the path near the reference point: a
    coarse search over a polyline of the path in an arc-length window around ``r(t)``,
    then a safeguarded Newton iteration (bisection fallback inside a bracket) on ``s``.
    The CEE-MFAC paper's real-time estimate (eqs. (7)-(13)) is its special case for an
    ellipse, see :func:`ellipse_contour_error`.

Degenerate input degrades, never to NaN: where the reference speed vanishes (a stop, a
cusp) the tangent is taken from the curve's outgoing chord; where the curvature vanishes
the circular estimate is the linear one; at a self-intersection the exact estimate keeps to
the branch near the reference point (the arc-length window), which is the contour the
machine is following.

References
----------
ZHANG Baolin, CAO Rongmin, HOU Zhongsheng, Real-time contour error estimation and
model-free control for two-dimensional linear motor (``../shared/papers/realtime-cee-mfac.txt``).
"""

from primlib.contour._ellipse import ellipse_closest_point, ellipse_contour_error
from primlib.contour._estimate import (
    METHODS,
    ContourEstimate,
    ContourEstimator,
    brute_force_contour_error,
    contour_error,
)
from primlib.contour._online import OnlineContourEstimator

__all__ = [
    "METHODS",
    "ContourEstimate",
    "ContourEstimator",
    "OnlineContourEstimator",
    "brute_force_contour_error",
    "contour_error",
    "ellipse_closest_point",
    "ellipse_contour_error",
]
