"""Convergence check of a learning law on the lifted (trial-domain) model.

A law u_{j+1} = Q (u_j + L e_j) with e_j = y_d - G u_j iterates u_{j+1} = M u_j + const,

    M = Q (I - L G),                                    (learning matrix, per axis)

on the n_r = n - r inputs that act inside the horizon (r = relative degree: the output at k
responds first to the input at k - r, so G is the n_r x n_r lower-triangular Toeplitz
matrix of h[r], h[r+1], ...). The iteration converges for every reference iff the spectral
radius rho(M) < 1, and the error norm decreases monotonically from any start if the
largest singular value sigma_max(M) < 1 (sufficient).

How the two numbers are computed (``LearningCheck.method`` names the way taken):

- Arimoto laws (p, pd, pid) without Q: M is lower-triangular Toeplitz with first column
  delta - L*g, so rho = |1 - L_0 h[r]| exactly (its diagonal); sigma_max by dense SVD for
  n_r <= ``dense_limit``, else by Lanczos on M^T M (full reorthogonalisation, at most 300
  steps, stopped by the top Ritz pair's residual bound) with M applied through FFTs.
- Norm-optimal without Q: M = w (G^T G + w I)^-1 is symmetric positive definite, so
  rho = sigma_max = w / (sigma_min(G)^2 + w) < 1 by construction (``monotonic`` is True
  even when the value rounds to 1.0, as it does on non-minimum-phase axes where
  sigma_min(G) is exponentially small); sigma_min(G) by a dense symmetric eigenvalue
  solve for n_r <= ``dense_limit``, else as 1 / sigma_max(G^-1) with G^-1 the Toeplitz
  matrix of the power series of 1 / g (den / num of the model, O(n)), by Lanczos on its FFT
  operator to 1e-6, the value rounded *up* with the Lanczos error bound. No n x n matrix,
  no ARPACK: ~0.6 s per axis at n = 20,000.
- With Q the product is full. Q is a symmetric Toeplitz matrix (the zero-padded
  filtfilt, see ``_qfilter``). For n_r <= ``dense_limit``: dense product, all eigenvalues
  and the 2-norm. Beyond: the product is applied through FFTs, sigma_max by Lanczos and rho
  estimated by Gelfand's formula, ||M^k x||^(1/k) with k = 64 from a seeded random x
  (capped by sigma_max; an estimate, as the method string says). Norm-optimal on a long
  trial (CG path, no Cholesky factor): the bound ||Q M|| <= ||Q|| ||M|| <= w /
  (sigma_min(G)^2 + w) (||Q|| <= 1) for both numbers, which says monotonic by construction.

Every learning matrix has a cluster of eigen- and singular values near 1 (the high
frequencies where the law barely learns); ARPACK (svds / eigs) stalls on such clusters,
whereas the largest Ritz value of a few hundred Lanczos steps converges (from below). When
the Lanczos residual bound has not reached the tolerance in its steps, the method string
says "estimate, error <= ..." with that bound (``primlib.plant.max_singular_value``).

Reference: D. A. Bristow, M. Tharayil, A. G. Alleyne, "A survey of iterative learning
control", IEEE Control Systems Magazine 26(3), 2006 (lifted analysis, Q-filter, norm-optimal).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, signal
from scipy.sparse.linalg import LinearOperator

from primlib.plant import max_singular_value, toeplitz_operator

__all__ = ["LearningCheck", "ConvergenceWarning"]

_GELFAND_K = 64


class ConvergenceWarning(UserWarning):
    """Monotonic convergence of a learning law is not assured (sigma_max of its learning
    matrix is >= 1), or the law diverges (spectral radius >= 1)."""


@dataclass(frozen=True)
class LearningCheck:
    """Spectral radius and largest singular value of the learning matrices Q (I - L G).

    Attributes
    ----------
    spectral_radius : float
        Largest over the axes (the axes are decoupled, so the composite matrix is block
        diagonal and its radius and norm are the largest of the blocks').
    max_singular_value : float
        Largest over the axes.
    monotonic : bool
        ``max_singular_value < 1``: the error norm decreases in every iteration.
    spectral_radius_axes, max_singular_value_axes : tuple of float
        Per axis.
    method : str
        How they were computed (see :mod:`primlib.ilc._check`).
    n : int
        Number of samples of the trial.
    """

    spectral_radius: float
    max_singular_value: float
    monotonic: bool
    spectral_radius_axes: tuple
    max_singular_value_axes: tuple
    method: str
    n: int

    @property
    def convergent(self) -> bool:
        """``spectral_radius < 1``: the iteration converges (maybe not monotonically)."""
        return self.spectral_radius < 1.0


def _dense_lower(col: np.ndarray) -> np.ndarray:
    return linalg.toeplitz(col, np.r_[col[0], np.zeros(len(col) - 1)])


def _rho_sigma_operator(op: LinearOperator) -> tuple[float, float, str]:
    est = max_singular_value(op, method="lanczos", full_output=True)
    sigma = est.value
    # Gelfand: rho <= ||M^k||^(1/k) -> rho; ARPACK stalls on the cluster of eigenvalues
    # near 1 that every learning matrix has at high frequency, so estimate from M^k x
    x = np.random.default_rng(0).standard_normal(op.shape[0])
    x /= np.linalg.norm(x)
    log_norm = 0.0
    for _ in range(_GELFAND_K):
        x = op @ x
        nx = float(np.linalg.norm(x))
        if nx == 0.0:
            return 0.0, sigma, f"sigma: {est.method}; rho: M^k x vanished (k <= {_GELFAND_K})"
        log_norm += np.log(nx)
        x /= nx
    rho = min(float(np.exp(log_norm / _GELFAND_K)), sigma)
    return rho, sigma, f"sigma: {est.method}; rho ~ ||M^k x||^(1/k), k = {_GELFAND_K}"


def check_arimoto(col: np.ndarray, qfilter, dense_limit: int) -> tuple[float, float, str]:
    """rho and sigma_max of Q (I - L G) with I - L G lower-triangular Toeplitz (first column
    ``col``)."""
    n = len(col)
    if qfilter is None:
        rho = abs(float(col[0]))
        if n <= dense_limit:
            return rho, float(np.linalg.norm(_dense_lower(col), 2)), "diagonal; dense SVD"
        est = max_singular_value(toeplitz_operator(col), method="lanczos", full_output=True)
        return rho, est.value, f"diagonal; FFT Toeplitz operator, {est.method}"
    if n <= dense_limit:
        M = qfilter.matrix(n) @ _dense_lower(col)
        return (
            float(np.max(np.abs(np.linalg.eigvals(M)))),
            float(np.linalg.norm(M, 2)),
            "dense eigenvalues and SVD",
        )
    k = qfilter.kernel(n)
    op = toeplitz_operator(k, k) @ toeplitz_operator(col)
    rho, sigma, how = _rho_sigma_operator(op)
    return rho, sigma, f"FFT operators; {how}"


def check_norm_optimal(g: np.ndarray, w: float, cho, qfilter, dense_limit: int, polys=None):
    """rho and sigma_max of Q w (G^T G + w I)^-1, G the lower-triangular Toeplitz matrix of
    ``g`` (n,).

    ``cho``: Cholesky factor of G^T G + w I, or None (long trials: never formed);
    ``polys``: (num, den) with g = num / den, or None (used for G^-1's power series).
    """
    n = g.size

    if qfilter is None or n <= dense_limit:
        if n <= dense_limit:
            G = _dense_lower(g)
            if qfilter is None:
                lam_min = float(linalg.eigvalsh(G.T @ G, subset_by_index=[0, 0])[0])
                value = w / (max(lam_min, 0.0) + w)
                return value, value, "w / (sigma_min(G)^2 + w), dense eigvalsh"
            if cho is None:
                H = G.T @ G
                H[np.diag_indices(n)] += w
                cho = linalg.cho_factor(H, lower=True)
            M = qfilter.matrix(n) @ (w * linalg.cho_solve(cho, np.eye(n)))
            return (
                float(np.max(np.abs(np.linalg.eigvals(M)))),
                float(np.linalg.norm(M, 2)),
                "dense eigenvalues and SVD",
            )
    if qfilter is None or cho is None:
        value, how = _norm_optimal_bound(g, w, polys)
        if qfilter is None:
            return value, value, how
        # ||Q M|| <= ||Q|| ||M|| and rho <= ||.||; ||Q|| <= max |B|^2 = 1 (Butterworth,
        # zero-padded filtfilt: the symmetric Toeplitz matrix of the kernel |B|^2)
        return value, value, f"upper bound ||Q|| {how}"

    def apply(x):
        return w * linalg.cho_solve(cho, x)

    k = qfilter.kernel(n)
    inv = LinearOperator((n, n), matvec=apply, rmatvec=apply, dtype=float)
    op = toeplitz_operator(k, k) @ inv
    rho, sigma, how = _rho_sigma_operator(op)
    return rho, sigma, f"FFT operators; {how}"


def _norm_optimal_bound(g: np.ndarray, w: float, polys) -> tuple[float, str]:
    """w / (sigma_min(G)^2 + w) for a long trial, rounded up (see ``check_norm_optimal``)."""
    n = g.size
    # sigma_min(G) = 1 / sigma_max(G^-1); G^-1 is lower-triangular Toeplitz too, its first
    # column the power series of 1 / g: den / num with the model's polynomials (O(n)),
    # else the IIR filter 1 / g (O(n^2)). Lanczos on its FFT operator. On a
    # non-minimum-phase axis that series grows geometrically and sigma_min(G)^2 underflows
    # against w: the value rounds to 1 (still < 1 exactly)
    imp = np.zeros(n)
    imp[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if polys is not None and polys[0][0] != 0.0:
            inv_col = signal.lfilter(polys[1], polys[0], imp)
        else:
            inv_col = signal.lfilter([1.0], g, imp)
    if not (np.all(np.isfinite(inv_col)) and np.max(np.abs(inv_col)) < 1e30):
        # sigma_max(G^-1) >= 1e30: sigma_min(G)^2 <= 1e-60, far below any w
        return 1.0, "w / (sigma_min(G)^2 + w), sigma_min(G) < 1e-30"
    # the value needs sigma_min only to ~1e-6: its relative error e moves the value by at
    # most e / 2. The top Ritz value s is a lower bound of sigma_max(G^-1), s + bound an
    # upper one, so lam_min from s + bound rounds the value *up* (never claims too much)
    est = max_singular_value(
        toeplitz_operator(inv_col), method="lanczos", tol=1e-6, lanczos_steps=200, full_output=True
    )
    lam_min = 1.0 / (est.value + est.error_bound) ** 2
    value = w / (lam_min + w)
    return value, f"w / (sigma_min(G)^2 + w), rounded up; sigma_max(G^-1): {est.method}"


def arimoto_column(g: np.ndarray, c: np.ndarray, den: np.ndarray) -> np.ndarray:
    """First column of I - L G: delta minus the learning filter c/den applied to g."""
    col = -signal.lfilter(c, den, g)
    col[0] += 1.0
    return col
