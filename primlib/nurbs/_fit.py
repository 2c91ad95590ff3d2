"""Least-squares fit of uniformly timed samples to a clamped B-spline in normalised time.

Samples P_i at v_i = i / (n - 1) are fitted with m control points on clamped uniform knots by
linear least squares; the normal equations B^T B c = B^T P are banded (bandwidth p) and solved
by a banded Cholesky factorisation, and the first and last control points are set to the end
samples, so the curve starts and ends exactly on the path. At an end where the samples are at
rest the fit is equality-constrained instead: the end control point and its neighbour both
equal the end sample (C'(v) = 0 there), so the curve cannot start by running backwards, a
cusp the samples do not have; the fixed control points are eliminated and the banded normal
equations B_f^T B_f c_f = B_f^T (P - B_x c_x) of the free ones are solved. The count m is
searched: the error of a degree-p fit scales like h^(p+1) with the knot spacing h, which
predicts the next count; a bracket [failing, passing] with bisection guarantees termination.
When no count below n reaches the tolerance, the curve interpolates the samples (m = n).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline
from scipy.linalg import LinAlgError, solveh_banded

from primlib.nurbs._basis import basis_functions, clamped_uniform_knots

__all__ = ["Fit", "fit_samples", "lsq_fit", "interpolate", "rest_ends", "REST_RTOL"]

# Stop the search once the passing count is within this fraction of the failing one: the
# result then has at most ~5 % more control points than the smallest count that passes.
_COUNT_SLACK = 0.05
# Predicted steps before falling back to plain bisection (keeps the worst case logarithmic).
_PREDICTED_STEPS = 6
# Samples are at rest at an end when their speed there is below this fraction of their mean
# speed: holding the end still then moves the curve by far less than the fit tolerance.
REST_RTOL = 1e-3


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


def rest_ends(points: np.ndarray, p: int) -> tuple[bool, bool]:
    """Whether the samples are at rest at their start and at their end.

    An end is at rest when the slope at the end sample of a degree-p polynomial fitted to
    the 2 (p + 1) samples there is below ``REST_RTOL`` of the mean speed. A minimum-jerk
    start (s ~ t^3) is at rest exactly; noise of any size is not.
    """
    k = min(points.shape[0], 2 * (p + 1))
    if p < 2 or k < p + 2:
        return False, False
    vander = np.vander(np.arange(k, dtype=np.float64), p + 1, increasing=True)
    weights = np.linalg.solve(vander.T @ vander, vander.T)[1]  # slope row of the LSQ fit
    start = weights @ (points[:k] - points[0])
    end = weights @ (points[: -k - 1 : -1] - points[-1])
    step = np.linalg.norm(np.diff(points, axis=0), axis=1).mean()  # mean speed per sample
    limit = REST_RTOL * step
    return bool(step > 0 and np.linalg.norm(start) <= limit), bool(
        step > 0 and np.linalg.norm(end) <= limit
    )


def _fixed_ctrl(points: np.ndarray, m: int, rest: tuple[bool, bool]) -> dict[int, np.ndarray]:
    """Control points fixed by the constraints: index -> value."""
    fixed = {0: points[0], m - 1: points[-1]}
    if rest[0]:
        fixed[1] = points[0]
    if rest[1]:
        fixed[m - 2] = points[-1]
    return fixed


def lsq_fit(
    v: np.ndarray, points: np.ndarray, m: int, p: int, rest: tuple[bool, bool] = (False, False)
) -> Fit | None:
    """Least-squares fit with m control points on clamped uniform knots; ends constrained.

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
    rest : (bool, bool)
        Whether the samples are at rest at the start / at the end: then the second (second
        to last) control point equals the first (last), so C'(0) = 0 (C'(1) = 0).

    Returns
    -------
    Fit or None
        None when the normal equations are singular (too few samples per knot span).
    """
    knots = clamped_uniform_knots(m, p)
    span, basis = basis_functions(v, knots, p)
    fixed = _fixed_ctrl(points, m, rest)
    ctrl = np.zeros((m, points.shape[1]))
    for j, value in fixed.items():
        ctrl[j] = value
    # free control points a .. b-1; with both ends moving, the plain solve of all m and the
    # end points set afterwards (cheaper, and what fits were before the rest constraint)
    a, b = (2, m - 2) if all(rest) else (2, m - 1) if rest[0] else (1, m - 2) if rest[1] else (0, m)
    if b > a:
        solved = _solve_free(span - p, basis, points, ctrl, a, b)
        if solved is None:
            return None
        ctrl[a:b] = solved
    for j, value in fixed.items():
        ctrl[j] = value
    error = _deviation(span, basis, ctrl, points)
    if not math.isfinite(error):
        return None
    return Fit(knots, ctrl, error)


def _solve_free(first, basis, points, ctrl, a: int, b: int) -> np.ndarray | None:
    """Control points a .. b-1 minimising |B c - P|^2 with the others held at ``ctrl``."""
    p = basis.shape[1] - 1
    m = ctrl.shape[0]
    # residual of the fixed control points: P - B_x c_x (they sit at the ends only)
    target = points
    if a > 0 or b < m:
        rows = np.flatnonzero((first < a) | (first + p >= b))  # samples in the end spans
        idx = first[rows, None] + np.arange(p + 1)
        held = np.where((idx < a) | (idx >= b), basis[rows], 0.0)
        target = points.copy()
        target[rows] -= np.einsum("ij,ijk->ik", held, ctrl[idx])
    # normal matrix of all m in upper banded storage: ab[p + i - j, j] = (B^T B)[i, j], i <= j
    ab = np.zeros((p + 1, m))
    for r in range(p + 1):
        for c in range(r, p + 1):
            ab[p - (c - r)] += np.bincount(first + c, basis[:, r] * basis[:, c], minlength=m)
    rhs = np.empty((m, points.shape[1]))  # B^T (P - B_x c_x), one bincount per (basis, axis)
    for k in range(points.shape[1]):
        rhs[:, k] = sum(
            np.bincount(first + r, basis[:, r] * target[:, k], minlength=m) for r in range(p + 1)
        )
    try:
        if a == 0 and b == m:
            return solveh_banded(ab, rhs, check_finite=False)
        return solveh_banded(ab[:, a:b], rhs[a:b], check_finite=False)
    except (LinAlgError, ValueError):
        return None


def interpolate(
    v: np.ndarray, points: np.ndarray, p: int, rest: tuple[bool, bool] = (False, False)
) -> Fit:
    """Interpolating spline through every sample, m = n: not-a-knot end conditions, or for
    a cubic with an end at rest C'(0) = 0 (C'(1) = 0) there and the samples' own end
    derivative (a cubic through the last four) at the other end."""
    bc = None
    if p == 3 and any(rest):
        ends = [np.zeros(points.shape[1]) if r else None for r in rest]
        if ends[0] is None:
            ends[0] = make_interp_spline(v[:4], points[:4], k=3)(v[0], 1)
        if ends[1] is None:
            ends[1] = make_interp_spline(v[-4:], points[-4:], k=3)(v[-1], 1)
        bc = ([(1, ends[0])], [(1, ends[1])])
    spl = make_interp_spline(v, points, k=p, bc_type=bc)
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
        interpolating curve (m = n) when no smaller count reaches tol. At an end where the
        samples are at rest (:func:`rest_ends`) the curve is at rest too.
    """
    n = points.shape[0]
    v = np.arange(n) / (n - 1)
    rest = rest_ends(points, p)
    if n_ctrlpts is not None:
        if n_ctrlpts >= n:
            return interpolate(v, points, p, rest)
        fit = lsq_fit(v, points, n_ctrlpts, p, rest)
        return fit if fit is not None else interpolate(v, points, p, rest)

    lo, hi = p, n  # lo: largest count known to fail; hi: smallest count known to pass
    best: Fit | None = None
    m = min(n, 2 * (p + 1))
    for step in range(64):
        fit = interpolate(v, points, p, rest) if m >= n else lsq_fit(v, points, m, p, rest)
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
