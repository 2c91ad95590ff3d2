"""Least squares and filtering shared by the grey-box fit and its ripple searches: ridge
least squares on standardised columns, its cross-validated error holding out folds, and the
axis model run over each stored pair from rest."""

from __future__ import annotations

import numpy as np
from scipy import signal

__all__ = ["RIDGE", "cv_error", "fold_totals", "rms", "solve", "standardised", "through_model"]

RIDGE = 1e-8  # relative to the mean diagonal of the standardised normal matrix


def standardised(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the columns of ``A`` of any size, each divided by its RMS; which those are; every
    column's RMS): a column the data does not excite gets no weight instead of a huge one."""
    scale = np.sqrt(np.mean(A**2, axis=0))
    live = scale > 1e-12 * max(float(scale.max(initial=0.0)), 1e-300)
    return A[:, live] / scale[live], live, scale


def solve(F: np.ndarray, r: np.ndarray, cols: list[int]) -> np.ndarray:
    """Ridge least squares on the standardised columns ``cols`` (others get 0)."""
    coef = np.zeros(F.shape[1])
    A, live, scale = standardised(F[:, cols])
    if not np.any(live):
        return coef
    G = A.T @ A
    G[np.diag_indices_from(G)] += RIDGE * max(float(np.trace(G)) / len(G), 1e-300)
    sol = np.linalg.solve(G, A.T @ r)
    coef[np.asarray(cols)[live]] = sol / scale[live]
    return coef


def _solve_normal(G: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """:func:`solve` from the normal equations of its columns over ``n`` rows (``G`` = MᵀM,
    ``b`` = Mᵀr): the same standardisation (each column's RMS from G's diagonal), the same
    ridge; the coefficients of those columns."""
    scale = np.sqrt(np.maximum(np.diag(G), 0.0) / max(n, 1))
    live = scale > 1e-12 * max(float(scale.max(initial=0.0)), 1e-300)
    coef = np.zeros(G.shape[0])
    if not np.any(live):
        return coef
    s = scale[live]
    Gs = G[np.ix_(live, live)] / np.outer(s, s)
    Gs[np.diag_indices_from(Gs)] += RIDGE * max(float(np.trace(Gs)) / len(Gs), 1e-300)
    coef[live] = np.linalg.solve(Gs, b[live] / s) / s
    return coef


def cv_error(F: np.ndarray, r: np.ndarray, cols: list[int], folds: np.ndarray) -> np.ndarray:
    """Each row's error when its fold is held out of the fit (:func:`solve` on the other
    folds' rows), shape (n,).

    Each fold's normal equations are formed once and a training set's are the sum of the
    other folds' (:func:`fold_totals`; one pass over the rows, where five copies of 80 % of
    them before stop 47 were most of a cross-validation's time on a 400,000-row axis)."""
    err = np.empty_like(r)
    M = F[:, cols]
    tests = [folds == k for k in np.unique(folds)]
    Ms = [M[t] for t in tests]
    G = fold_totals(np.stack([Mk.T @ Mk for Mk in Ms]))[1:]
    b = fold_totals(np.stack([Mk.T @ r[t] for Mk, t in zip(Ms, tests, strict=True)]))[1:]
    n = fold_totals(np.array([Mk.shape[0] for Mk in Ms]))[1:]
    for t, Mk, Gk, bk, nk in zip(tests, Ms, G, b, n, strict=True):
        err[t] = r[t] - Mk @ _solve_normal(Gk, bk, int(nk))
    return err


def fold_totals(parts: np.ndarray) -> np.ndarray:
    """Per-fold sums (J, ...) to the sums of every objective (1 + J, ...): all folds, then
    all but each fold. Summed, not the whole's less the fold's: a subtraction cancels a
    column the training rows barely hold into noise, which a standardisation then takes
    for a live column."""
    every = np.arange(parts.shape[0])
    rest = [parts[every != k].sum(axis=0) for k in every]
    return np.stack([parts.sum(axis=0), *rest])


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def through_model(X: np.ndarray, starts: np.ndarray, b: np.ndarray, a: np.ndarray):
    """Each pair's rows of ``X`` (n,) or (n, c) filtered by the axis's model from rest."""
    out = np.empty_like(X)
    for lo, hi in zip(starts[:-1], starts[1:], strict=True):
        out[lo:hi] = signal.lfilter(b, a, X[lo:hi], axis=0)
    return out
