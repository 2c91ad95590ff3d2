"""B-spline basis functions and knot insertion, vectorised over points.

Algorithms A2.1/A2.2 (span and non-zero basis functions) and A5.1 (Boehm's knot insertion)
of Piegl & Tiller, *The NURBS Book*, 2nd ed., 1997, written over arrays of parameters.
"""

from __future__ import annotations

import numpy as np

__all__ = ["clamped_uniform_knots", "basis_functions", "insert_knot", "multiplicity"]


def clamped_uniform_knots(m: int, p: int) -> np.ndarray:
    """Clamped knot vector on [0, 1] with uniformly spaced interior knots.

    Parameters
    ----------
    m : int
        Number of control points, m >= p + 1.
    p : int
        Degree.

    Returns
    -------
    knots : array, shape (m + p + 1,)
        p + 1 zeros, m - p - 1 interior knots i / (m - p), p + 1 ones.
    """
    interior = np.arange(1, m - p) / (m - p)
    return np.concatenate([np.zeros(p + 1), interior, np.ones(p + 1)])


def basis_functions(x: np.ndarray, knots: np.ndarray, p: int) -> tuple[np.ndarray, np.ndarray]:
    """Knot spans and the p + 1 non-zero basis functions at each parameter.

    Parameters
    ----------
    x : array, shape (n,)
        Parameters inside [knots[p], knots[-p-1]].
    knots : array, shape (m + p + 1,)
        Non-decreasing knot vector.
    p : int
        Degree.

    Returns
    -------
    span : array of int, shape (n,)
        Index s with knots[s] <= x < knots[s + 1] (the last non-empty span at the right
        end); control points s - p .. s act at x.
    values : array, shape (n, p + 1)
        N_{s-p+j,p}(x) for j = 0 .. p; each row sums to 1.
    """
    x = np.asarray(x, dtype=np.float64)
    m = len(knots) - p - 1
    # the right end belongs to the last non-empty span (A2.1)
    last = m - 1
    while knots[last] == knots[last + 1]:
        last -= 1
    span = np.clip(np.searchsorted(knots, x, side="right") - 1, p, last)
    n = x.shape[0]
    values = np.zeros((n, p + 1))
    values[:, 0] = 1.0
    left = np.empty((n, p + 1))
    right = np.empty((n, p + 1))
    for j in range(1, p + 1):  # A2.2, each step vectorised over all x
        left[:, j] = x - knots[span + 1 - j]
        right[:, j] = knots[span + j] - x
        saved = np.zeros(n)
        for r in range(j):
            temp = values[:, r] / (right[:, r + 1] + left[:, j - r])
            values[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        values[:, j] = saved
    return span, values


def multiplicity(knots: np.ndarray, u: float) -> int:
    """How many knots equal u exactly."""
    return int(np.count_nonzero(knots == u))


def insert_knot(
    knots: np.ndarray, ctrl: np.ndarray, p: int, u: float, times: int
) -> tuple[np.ndarray, np.ndarray]:
    """Insert the knot u ``times`` times without changing the curve (Boehm, A5.1).

    Parameters
    ----------
    knots : array, shape (m + p + 1,)
        Knot vector; u must lie strictly inside its first and last knot.
    ctrl : array, shape (m, c)
        Control points; homogeneous (w * P, w) for a rational curve.
    p : int
        Degree.
    u : float
        The knot to insert.
    times : int
        Number of insertions (>= 0).

    Returns
    -------
    knots : array, shape (m + times + p + 1,)
    ctrl : array, shape (m + times, c)
    """
    for _ in range(times):
        k = int(np.searchsorted(knots, u, side="right")) - 1
        i = np.arange(k - p + 1, k + 1)
        alpha = (u - knots[i]) / (knots[i + p] - knots[i])  # A5.1
        new = alpha[:, None] * ctrl[i] + (1.0 - alpha)[:, None] * ctrl[i - 1]
        ctrl = np.concatenate([ctrl[: k - p + 1], new, ctrl[k:]])
        knots = np.insert(knots, k + 1, u)
    return knots, ctrl
