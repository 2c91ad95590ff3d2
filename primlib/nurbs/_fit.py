"""Least-squares fit of uniformly timed samples to a clamped B-spline in normalised time.

Samples P_i at v_i = i / (n - 1) are fitted with m control points on clamped uniform knots by
linear least squares; the normal equations B^T B c = B^T P are banded (bandwidth p) and solved
by a banded Cholesky factorisation. The first and last control points are then set to the
end samples, so the curve starts and ends exactly on the path. The count m is searched: the
error of a degree-p fit scales like h^(p+1) with the knot spacing h, which predicts the next
count; a bracket [failing, passing] with bisection guarantees termination. When no count
below n reaches the tolerance, the curve interpolates the samples (m = n).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.linalg import LinAlgError, solveh_banded

from primlib.nurbs._basis import basis_functions, clamped_uniform_knots

__all__ = ["Fit", "fit_samples", "lsq_fit", "interpolate"]

# Stop the search once the passing count is within this fraction of the failing one: the
# result then has at most ~5 % more control points than the smallest count that passes.
_COUNT_SLACK = 0.05
# Predicted steps before falling back to plain bisection (keeps the worst case logarithmic).
_PREDICTED_STEPS = 6


@dataclass(frozen=True)
class Fit:
    """One fitted curve: knots (m + p + 1,), control points (m, d), max deviation at samples."""

    knots: np.ndarray
    ctrlpts: np.ndarray
    error: float


def _deviation(span: np.ndarray, basis: np.ndarray, ctrl: np.ndarray, points: np.ndarray):
    p = basis.shape[1] - 1
    idx = span[:, None] - p + np.arange(p + 1)
    fitted = np.einsum("ij,ijk->ik", basis, ctrl[idx])
    return float(np.sqrt(((fitted - points) ** 2).sum(axis=1)).max())


def lsq_fit(v: np.ndarray, points: np.ndarray, m: int, p: int) -> Fit | None:
    """Least-squares fit with m control points on clamped uniform knots; ends pinned.

    Parameters
    ----------
    v : array, shape (n,)
        Parameters of the samples in [0, 1].
    points : array, shape (n, d)
        Samples.
    m : int
        Number of control points, p + 1 <= m < n.
    p : int
        Degree.

    Returns
    -------
    Fit or None
        None when the normal equations are singular (too few samples per knot span).
    """
    knots = clamped_uniform_knots(m, p)
    span, basis = basis_functions(v, knots, p)
    first = span - p
    # Normal matrix in upper banded storage: ab[p + i - j, j] = (B^T B)[i, j] for i <= j.
    ab = np.zeros((p + 1, m))
    for a in range(p + 1):
        for b in range(a, p + 1):
            ab[p - (b - a)] += np.bincount(first + b, basis[:, a] * basis[:, b], minlength=m)
    rhs = np.empty((m, points.shape[1]))  # B^T P, one bincount per (basis, axis)
    for k in range(points.shape[1]):
        rhs[:, k] = sum(
            np.bincount(first + a, basis[:, a] * points[:, k], minlength=m) for a in range(p + 1)
        )
    try:
        ctrl = solveh_banded(ab, rhs, check_finite=False)
    except LinAlgError:
        return None
    ctrl[0] = points[0]
    ctrl[-1] = points[-1]
    error = _deviation(span, basis, ctrl, points)
    if not math.isfinite(error):
        return None
    return Fit(knots, ctrl, error)


def interpolate(v: np.ndarray, points: np.ndarray, p: int) -> Fit:
    """Interpolating spline through every sample (not-a-knot end conditions), m = n."""
    spl = make_interp_spline(v, points, k=p)
    ctrl = np.array(spl.c, dtype=np.float64)
    ctrl[0] = points[0]
    ctrl[-1] = points[-1]
    knots = np.array(spl.t, dtype=np.float64)
    span, basis = basis_functions(v, knots, p)
    return Fit(knots, ctrl, _deviation(span, basis, ctrl, points))


def fit_samples(points: np.ndarray, tol: float, p: int, n_ctrlpts: int | None = None) -> Fit:
    """Fit samples at v_i = i / (n - 1) to within ``tol`` (Euclidean) at every sample.

    Parameters
    ----------
    points : array, shape (n, d)
        Samples, n > p.
    tol : float
        Largest allowed Euclidean distance between the curve and a sample, > 0.
    p : int
        Degree.
    n_ctrlpts : int, optional
        Use exactly this many control points (p + 1 .. n) instead of searching; the fit
        error is then whatever it is.

    Returns
    -------
    Fit
        The fit with the smallest count found (within 5 %) whose error is <= tol; the
        interpolating curve (m = n) when no smaller count reaches tol.
    """
    n = points.shape[0]
    v = np.arange(n) / (n - 1)
    if n_ctrlpts is not None:
        if n_ctrlpts >= n:
            return interpolate(v, points, p)
        fit = lsq_fit(v, points, n_ctrlpts, p)
        return fit if fit is not None else interpolate(v, points, p)

    lo, hi = p, n  # lo: largest count known to fail; hi: smallest count known to pass
    best: Fit | None = None
    m = min(n, 2 * (p + 1))
    for step in range(64):
        fit = interpolate(v, points, p) if m >= n else lsq_fit(v, points, m, p)
        if fit is not None and (fit.error <= tol or m >= n):
            hi, best = m, fit
        else:
            lo = m
        if best is not None and hi - lo <= max(1, math.floor(_COUNT_SLACK * hi)):
            break
        ceiling = hi - 1 if best is not None else n
        if step < _PREDICTED_STEPS and fit is not None and fit.error > 0:
            # error ~ h^(p+1), h = 1 / (m - p): predict the count that just reaches tol
            ratio = (fit.error / tol) ** (1.0 / (p + 1))
            guess = p + (m - p) * ratio * (1.1 if fit.error > tol else 1.02)
            if fit.error > tol:
                guess = max(guess, 1.25 * m)
            m = math.ceil(guess)
        else:
            m = (lo + hi + 1) // 2
        m = min(max(m, lo + 1), ceiling)
    assert best is not None  # the loop always reaches m = n or a passing count
    return best
