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
  n_r <= ``dense_limit``, else by Lanczos on M^T M (300 steps, full reorthogonalisation)
  with M applied through FFTs.
- Norm-optimal without Q: M = w (G^T G + w I)^-1 is symmetric positive definite, so
  rho = sigma_max = w / (sigma_min(G)^2 + w) < 1 by construction (``monotonic`` is True
  even when the value rounds to 1.0, as it does on non-minimum-phase axes where
  sigma_min(G) is exponentially small); sigma_min(G) by a dense symmetric eigenvalue
  solve for n_r <= ``dense_limit``, else as 1 / sigma_max(G^-1) with G^-1 the Toeplitz
  matrix of the power series of 1 / g, by Lanczos on its FFT operator.
- With Q the product is full. Q is a symmetric Toeplitz matrix (the zero-padded
  filtfilt, see ``_qfilter``). For n_r <= ``dense_limit``: dense product, all eigenvalues
  and the 2-norm. Beyond: the product is applied through FFTs, sigma_max by Lanczos and rho
  estimated by Gelfand's formula, ||M^k x||^(1/k) with k = 64 from a seeded random x
  (capped by sigma_max; an estimate, as the method string says).

Every learning matrix has a cluster of eigen- and singular values near 1 (the high
frequencies where the law barely learns); ARPACK (svds / eigs) stalls on such clusters,
whereas the largest Ritz value of a few hundred Lanczos steps converges (from below, to
~1e-7 relative on these matrices).

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
    sigma = max_singular_value(op, method="lanczos")
    # Gelfand: rho <= ||M^k||^(1/k) -> rho; ARPACK stalls on the cluster of eigenvalues
    # near 1 that every learning matrix has at high frequency, so estimate from M^k x
    x = np.random.default_rng(0).standard_normal(op.shape[0])
    x /= np.linalg.norm(x)
    log_norm = 0.0
    for _ in range(_GELFAND_K):
        x = op @ x
        nx = float(np.linalg.norm(x))
        if nx == 0.0:
            return 0.0, sigma, f"Lanczos; rho: M^k x vanished (k <= {_GELFAND_K})"
        log_norm += np.log(nx)
        x /= nx
    rho = min(float(np.exp(log_norm / _GELFAND_K)), sigma)
    return rho, sigma, f"Lanczos; rho ~ ||M^k x||^(1/k), k = {_GELFAND_K}"


def check_arimoto(col: np.ndarray, qfilter, dense_limit: int) -> tuple[float, float, str]:
    """rho and sigma_max of Q (I - L G) with I - L G lower-triangular Toeplitz (first column
    ``col``)."""
    n = len(col)
    if qfilter is None:
        rho = abs(float(col[0]))
        if n <= dense_limit:
            return rho, float(np.linalg.norm(_dense_lower(col), 2)), "diagonal; dense SVD"
        sigma = max_singular_value(toeplitz_operator(col), method="lanczos")
        return rho, sigma, "diagonal; Lanczos on the FFT Toeplitz operator"
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


def check_norm_optimal(G: np.ndarray, w: float, cho, qfilter, dense_limit: int):
    """rho and sigma_max of Q w (G^T G + w I)^-1 (``cho``: Cholesky factor of G^T G + w I)."""
    n = G.shape[0]

    def apply(x):
        return w * linalg.cho_solve(cho, x)

    if qfilter is None:
        if n <= dense_limit:
            lam_min = float(linalg.eigvalsh(G.T @ G, subset_by_index=[0, 0])[0])
            value = w / (max(lam_min, 0.0) + w)
            return value, value, "w / (sigma_min(G)^2 + w), dense eigvalsh"
        # sigma_min(G) = 1 / sigma_max(G^-1); G^-1 is lower-triangular Toeplitz too, its
        # first column the power series of 1 / g (one IIR filter); Lanczos on its FFT
        # operator. On a non-minimum-phase axis that series grows geometrically and
        # sigma_min(G)^2 underflows against w: the value rounds to 1 (still < 1 exactly)
        imp = np.zeros(n)
        imp[0] = 1.0
        with np.errstate(over="ignore", invalid="ignore"):
            inv_col = signal.lfilter([1.0], G[:, 0], imp)
        if np.all(np.isfinite(inv_col)) and np.max(np.abs(inv_col)) < 1e30:
            s_inv = max_singular_value(toeplitz_operator(inv_col), method="lanczos")
            lam_min = 1.0 / s_inv**2
        else:  # sigma_max(G^-1) >= 1e30: sigma_min(G)^2 <= 1e-60, far below any w
            lam_min = 0.0
        value = w / (lam_min + w)
        return value, value, "w / (sigma_min(G)^2 + w), Lanczos on the Toeplitz inverse"
    if n <= dense_limit:
        M = qfilter.matrix(n) @ apply(np.eye(n))
        return (
            float(np.max(np.abs(np.linalg.eigvals(M)))),
            float(np.linalg.norm(M, 2)),
            "dense eigenvalues and SVD",
        )
    k = qfilter.kernel(n)
    inv = LinearOperator((n, n), matvec=apply, rmatvec=apply, dtype=float)
    op = toeplitz_operator(k, k) @ inv
    rho, sigma, how = _rho_sigma_operator(op)
    return rho, sigma, f"FFT operators; {how}"


def arimoto_column(g: np.ndarray, c: np.ndarray, den: np.ndarray) -> np.ndarray:
    """First column of I - L G: delta minus the learning filter c/den applied to g."""
    col = -signal.lfilter(c, den, g)
    col[0] += 1.0
    return col
