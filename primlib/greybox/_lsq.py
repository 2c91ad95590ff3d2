"""Least squares and filtering shared by the grey-box fit and its ripple searches: ridge
least squares on standardised columns, its cross-validated error holding out folds, and the
axis model run over each stored pair from rest."""

from __future__ import annotations

import numpy as np
from scipy import signal

__all__ = ["RIDGE", "cv_error", "rms", "solve", "standardised", "through_model"]

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


def cv_error(F: np.ndarray, r: np.ndarray, cols: list[int], folds: np.ndarray) -> np.ndarray:
    """Each row's error when its fold is held out of the fit, shape (n,)."""
    err = np.empty_like(r)
    for k in np.unique(folds):
        test = folds == k
        c = solve(F[~test], r[~test], cols)
        err[test] = r[test] - F[test] @ c
    return err


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def through_model(X: np.ndarray, starts: np.ndarray, b: np.ndarray, a: np.ndarray):
    """Each pair's rows of ``X`` (n,) or (n, c) filtered by the axis's model from rest."""
    out = np.empty_like(X)
    for lo, hi in zip(starts[:-1], starts[1:], strict=True):
        out[lo:hi] = signal.lfilter(b, a, X[lo:hi], axis=0)
    return out
