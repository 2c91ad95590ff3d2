"""The CEE-MFAC paper's real-time exact estimate for an ellipse: the closest-point quartic.

For the ellipse ``f = a x^2 + b y^2 - c = 0`` (eq. (7)) the closest point ``E`` to ``A``
satisfies ``f(E) = 0`` (eq. (8)) and ``(y_E - y_A)/(x_E - x_A) = b y_E / (a x_E)`` (eq. (9),
``AE`` along the gradient). Eliminating ``y_E = a x_E y_A / ((a - b) x_E + b x_A)`` gives

    a(a-b)^2 x^4 + 2ab(a-b) x_A x^3 + (ab^2 x_A^2 + a^2 b y_A^2 - c(a-b)^2) x^2
        - 2bc(a-b) x_A x - b^2 c x_A^2 = 0,                                   eq. (10)

which is the paper's eq. (10) except for the cubic coefficient: the paper prints
``(2a^2 b - 2ab^2) x_E^3`` without the factor ``x_A`` (dimensionally inconsistent; expanding
``(a x^2 - c)((a-b)x + b x_A)^2 + a^2 b y_A^2 x^2`` gives the ``x_A``).
"""

from __future__ import annotations

import numpy as np

from primlib._errors import InputError
from primlib.contour._curve import _check_points

__all__ = ["ellipse_closest_point", "ellipse_contour_error"]


def _check_axes(semi_x, semi_y):
    a, b = float(semi_x), float(semi_y)
    if not (np.isfinite(a) and np.isfinite(b) and a > 0 and b > 0):
        raise InputError(f"semi axes: expected two positive numbers, got {semi_x}, {semi_y}")
    if a == b:
        raise InputError(
            f"semi axes: expected an ellipse with unequal semi axes, got {a} and {b} "
            "(for a circle the contour error is |p| - radius)"
        )
    return a, b


def ellipse_closest_point(semi_x, semi_y, points) -> np.ndarray:
    """Closest point on the ellipse ``x^2/semi_x^2 + y^2/semi_y^2 = 1`` to each point.

    Solves the quartic (10) for all points at once (eigenvalues of stacked companion
    matrices), keeps the real roots inside ``|x| <= semi_x``, takes both ``y`` on the
    ellipse for each, and returns the nearest candidate. Points on an axis need no special
    case (the root ``x_E = 0`` brings both vertices ``(0, +-semi_y)`` as candidates).

    Parameters
    ----------
    semi_x, semi_y : float
        Semi axes along x and y, unequal.
    points : array, shape (m, 2)
        Points relative to the ellipse's centre.

    Returns
    -------
    array, shape (m, 2)

    Raises
    ------
    InputError
        Non-positive or equal semi axes, points not (m, 2) or not finite.
    """
    A, B = _check_axes(semi_x, semi_y)
    p = _check_points("points", points, dims=(2,))
    a, b, c = 1.0 / A**2, 1.0 / B**2, 1.0
    xa, ya = p[:, 0], p[:, 1]
    amb = a - b
    coef = np.stack(
        [
            np.full_like(xa, a * amb**2),
            2.0 * a * b * amb * xa,
            a * b * b * xa**2 + a * a * b * ya**2 - c * amb**2,
            -2.0 * b * c * amb * xa,
            -b * b * c * xa**2,
        ],
        axis=1,
    )  # eq. (10), corrected
    m = p.shape[0]
    comp = np.zeros((m, 4, 4))
    comp[:, 0, :] = -coef[:, 1:] / coef[:, :1]
    comp[:, np.arange(1, 4), np.arange(0, 3)] = 1.0
    roots = np.linalg.eigvals(comp)
    real = np.abs(roots.imag) <= 1e-7 * A
    xe = np.clip(roots.real, -A, A)
    ye = B * np.sqrt(np.maximum(1.0 - (xe / A) ** 2, 0.0))
    cx = np.concatenate([xe, xe], axis=1)
    cy = np.concatenate([ye, -ye], axis=1)
    ok = np.concatenate([real, real], axis=1)
    d2 = (cx - xa[:, None]) ** 2 + (cy - ya[:, None]) ** 2
    d2 = np.where(ok, d2, np.inf)
    # a numerically complex pair for every root can only happen for a degenerate quartic;
    # the vertices are then the candidates
    none = ~np.any(ok, axis=1)
    if np.any(none):
        vx = np.array([A, -A, 0.0, 0.0])
        vy = np.array([0.0, 0.0, B, -B])
        cx[none, :4], cy[none, :4] = vx, vy
        d2[none, :4] = (vx - xa[none, None]) ** 2 + (vy - ya[none, None]) ** 2
    k = np.argmin(d2, axis=1)
    return np.stack([cx[np.arange(m), k], cy[np.arange(m), k]], axis=1)


def ellipse_contour_error(semi_x, semi_y, points) -> np.ndarray:
    """Signed distance from each point to the ellipse, positive outside (eq. (13)).

    For the paper's clockwise ellipse ``x = 10 sin t, y = 5 cos t`` outside is the left of
    the direction of travel, so this equals :func:`contour_error` with ``method="exact"``.

    Parameters
    ----------
    semi_x, semi_y : float
    points : array, shape (m, 2)

    Returns
    -------
    array, shape (m,)
    """
    p = _check_points("points", points, dims=(2,))
    e = ellipse_closest_point(semi_x, semi_y, p)
    dist = np.linalg.norm(p - e, axis=1)
    outside = (p[:, 0] / float(semi_x)) ** 2 + (p[:, 1] / float(semi_y)) ** 2 > 1.0
    return np.where(outside, dist, -dist)
