"""Lifted (lower-triangular Toeplitz) operators applied through the FFT.

The lifted matrix of an impulse response h (n,) is ``T[i, j] = h[i - j]`` for i >= j, else 0,
so ``T @ u`` is the causal convolution of h and u truncated to n samples and ``T.T @ e`` the
anti-causal (time-reversed) one. Both cost O(n log n) through a zero-padded real FFT, which
lets the largest singular value of a 20,000 x 20,000 lifted matrix be found with
``scipy.sparse.linalg.svds`` without forming it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft, linalg
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, svds

from primlib._errors import InputError

__all__ = ["toeplitz_operator", "max_singular_value", "SingularValueEstimate"]


def toeplitz_operator(h, first_row=None) -> LinearOperator:
    """Lifted operator of an impulse response, with FFT matvec and rmatvec.

    Parameters
    ----------
    h : array, shape (n,)
        First column (the Markov parameters h[0], h[1], ...).
    first_row : array, shape (n,), optional
        First row for a general (not lower-triangular) Toeplitz matrix; ``first_row[0]``
        must equal ``h[0]``. None (default): zeros, i.e. the causal lifted matrix.

    Returns
    -------
    scipy.sparse.linalg.LinearOperator, shape (n, n)
        ``op @ u`` and ``op.T @ e`` (also on (n, k) blocks).
    """
    h = np.asarray(h, dtype=float)
    if h.ndim != 1 or h.size == 0 or not np.all(np.isfinite(h)):
        raise InputError(f"h: expected a finite 1-D impulse response, got shape {h.shape}")
    n = h.size
    if first_row is None:
        row = np.zeros(n)
        row[0] = h[0]
    else:
        row = np.asarray(first_row, dtype=float)
        if row.shape != (n,) or row[0] != h[0]:
            raise InputError(
                f"first_row: expected shape ({n},) starting with h[0], got shape {row.shape}"
            )
    # circulant embedding of size 2n: column c = [h, 0, row[n-1:0:-1]]
    m = fft.next_fast_len(2 * n, real=True)
    c = np.zeros(m)
    c[:n] = h
    if n > 1:
        c[m - n + 1 :] = row[:0:-1]
    spec = fft.rfft(c)
    spec_conj = np.conj(spec)

    def _apply(x, s):
        x = np.asarray(x, dtype=float)
        one_d = x.ndim == 1
        xx = x.reshape(n, -1)
        y = fft.irfft(s[:, None] * fft.rfft(xx, n=m, axis=0), n=m, axis=0)[:n]
        return y.ravel() if one_d else y

    return LinearOperator(
        (n, n),
        matvec=lambda x: _apply(x, spec),
        rmatvec=lambda x: _apply(x, spec_conj),
        matmat=lambda x: _apply(x, spec),
        rmatmat=lambda x: _apply(x, spec_conj),
        dtype=float,
    )


@dataclass(frozen=True)
class SingularValueEstimate:
    """Largest singular value with how it was found (``max_singular_value(full_output=True)``).

    Attributes
    ----------
    value : float
        sigma_max, or its best estimate.
    error_bound : float
        Bound on ``sigma_max - value`` (the Krylov values are lower bounds). Converged: the
        Ritz residual bound (ARPACK's criterion). Not converged: the gap-free bound of
        Kuczynski & Wozniakowski that holds with probability >= 1 - 1e-6 over the random
        start (``inf`` when too few steps were taken for it, or for power iteration).
    converged : bool
        The Ritz residual reached ``tol * value``.
    method : str
        How it was computed, e.g. ``"Lanczos, 120 steps: converged"`` or
        ``"Lanczos, 300 steps: estimate, error <= 3.1e-06 (p >= 1 - 1e-6)"``.
    steps : int
        Operator applications of ``op.T @ op`` (0 for dense).
    """

    value: float
    error_bound: float
    converged: bool
    method: str
    steps: int


def max_singular_value(
    op,
    method: str = "svds",
    tol: float = 1e-10,
    seed: int = 0,
    lanczos_steps: int = 300,
    *,
    full_output: bool = False,
):
    """Largest singular value of a linear operator (or matrix).

    Parameters
    ----------
    op : LinearOperator or array, shape (m, n)
    method : {"svds", "lanczos", "power"}
        ``"svds"``: ARPACK (``scipy.sparse.linalg.svds``, k=1), falling back to
        ``"lanczos"`` when ARPACK does not converge in 50 restarts (a cluster of nearly
        equal largest singular values); never raises ``ArpackNoConvergence``.
        ``"lanczos"``: Lanczos on ``op.T @ op`` with full reorthogonalisation from a seeded
        start, at most ``lanczos_steps`` steps. The top Ritz value theta lies below
        lambda_max (interlacing) and within the residual ``beta_j |s_j|`` (``s`` the Ritz
        vector in the Krylov basis) of *some* eigenvalue of ``op.T @ op``; Lanczos stops
        when that residual, in sigma ``beta_j |s_j| / (2 sqrt(theta))``, is below ``tol``
        relative (ARPACK's criterion; it is the error to sigma_max once the top Ritz pair
        is isolated). When the steps run out first (a tight cluster of top singular values,
        where the residual only measures the distance to a cluster member), the value is
        returned as an *estimate* with the gap-free probabilistic bound of Kuczynski &
        Wozniakowski (SIAM J. Matrix Anal. Appl. 13(4), 1992: after k products from a
        uniformly random start, P[lambda_max (1 - eps) > theta] <= 1.648 sqrt(n)
        exp(-sqrt(eps) (2k - 1))), at failure probability 1e-6, in the method string and
        ``full_output``.
        ``"power"``: power iteration on ``op.T @ op`` from a seeded random start, until the
        estimate changes by less than ``tol`` relative (at most 3000 steps). It converges
        from below and its stopping rule is no error bound: on clustered spectra it stops
        early (relative error ~1e-5 seen where the change per step was 1e-10), so the
        result is flagged as an estimate (a lower bound) with no error bound (``inf``)
        unless its Rayleigh residual is below ``tol`` as for Lanczos.
    tol : float
        Relative tolerance.
    seed : int
        Seed of the start vector, so results are reproducible.
    lanczos_steps : int
        Largest number of Lanczos steps (memory: n x steps floats).
    full_output : bool
        Return a :class:`SingularValueEstimate` (value, error bound, method) instead of
        the float.

    Returns
    -------
    float or SingularValueEstimate
    """
    est = _max_singular_value(op, method, tol, seed, lanczos_steps)
    return est if full_output else est.value


def _max_singular_value(op, method, tol, seed, lanczos_steps) -> SingularValueEstimate:
    if method not in ("svds", "lanczos", "power"):
        raise InputError(f"method: expected 'svds', 'lanczos' or 'power', got {method!r}")
    if not isinstance(op, LinearOperator):
        op = np.asarray(op, dtype=float)
    m, n = op.shape
    rng = np.random.default_rng(seed)
    if min(m, n) <= 2:
        dense = op @ np.eye(n) if isinstance(op, LinearOperator) else op
        return SingularValueEstimate(float(np.linalg.norm(dense, 2)), 0.0, True, "dense SVD", 0)
    note = ""
    if method == "svds":
        v0 = rng.standard_normal(min(m, n))
        try:
            s = svds(op, k=1, which="LM", tol=tol, v0=v0, maxiter=50, return_singular_vectors=False)
            value = float(s[0])
            # ARPACK's own stopping rule: Ritz residual <= tol * |Ritz value| of op.T op
            return SingularValueEstimate(value, tol * value, True, "ARPACK svds", 0)
        except ArpackNoConvergence:
            # a cluster of nearly equal top singular values (common: I - L G of a learning
            # law flattens to ~1 at high frequency) stalls ARPACK's vector convergence
            method = "lanczos"
            note = "ARPACK did not converge; "
    if method == "lanczos":
        value, bound, steps = _lanczos_max(op, n, rng, steps=lanczos_steps, tol=tol)
        converged = bool(bound <= tol * value)
        if converged:
            state = "converged"
        else:
            bound = _gap_free_bound(value, n, steps)
            state = f"estimate, error <= {bound:.2g} (p >= 1 - {_FAIL:g})"
        return SingularValueEstimate(
            value, bound, converged, f"{note}Lanczos, {steps} steps: {state}", steps
        )
    x = rng.standard_normal(n)
    x /= np.linalg.norm(x)
    sigma = 0.0
    steps = 0
    for steps in range(1, 3001):
        y = op.T @ (op @ x)
        norm = float(np.linalg.norm(y))
        if norm == 0.0:
            return SingularValueEstimate(0.0, 0.0, True, "power iteration: zero operator", steps)
        x = y / norm
        new = np.sqrt(norm)
        if abs(new - sigma) <= tol * new:
            sigma = new
            break
        sigma = new
    # Rayleigh quotient and residual of the last vector: an eigenvalue of op.T op lies
    # within ||A x - theta x|| of theta (x normalised)
    y = op.T @ (op @ x)
    theta = float(x @ y)
    resid = float(np.linalg.norm(y - theta * x))
    value = float(np.sqrt(max(theta, 0.0)))
    bound = resid / (2 * value) if value > 0 else 0.0
    if bound <= tol * value:
        return SingularValueEstimate(
            value, bound, True, f"power iteration, {steps} steps: converged", steps
        )
    return SingularValueEstimate(
        value,
        float("inf"),
        False,
        f"power iteration, {steps} steps: estimate (a lower bound), Rayleigh residual "
        f"{bound:.2g} (to the nearest singular value, not necessarily the largest)",
        steps,
    )


_FAIL = 1e-6  # failure probability of the gap-free bound


def _gap_free_bound(value: float, n: int, steps: int) -> float:
    """sigma_max - value bound holding with probability >= 1 - _FAIL (Kuczynski &
    Wozniakowski 1992, Lanczos from a uniformly random start: k = steps - 1 products beyond
    the start, counted conservatively)."""
    k = steps - 1
    if k < 1:
        return float("inf")
    eps = (np.log(1.648 * np.sqrt(n) / _FAIL) / (2 * k - 1)) ** 2
    if eps >= 1.0:
        return float("inf")
    return float(value * (1.0 / np.sqrt(1.0 - eps) - 1.0))


def _lanczos_max(op, n: int, rng, steps: int, tol: float) -> tuple[float, float, int]:
    """(sqrt of the top Ritz value, its residual bound in sigma, steps taken)."""
    k = min(steps, n)
    basis = np.zeros((k + 1, n))  # rows: contiguous blocks for the reorthogonalisation
    alpha = np.zeros(k)
    beta = np.zeros(k)
    q = rng.standard_normal(n)
    basis[0] = q / np.linalg.norm(q)
    size = k
    for j in range(k):
        v = op.T @ (op @ basis[j])
        alpha[j] = basis[j] @ v
        # three-term recurrence, then full reorthogonalisation against every row; a second
        # pass only when the first cancelled much of v (Daniel-Gragg-Kaufman-Stewart:
        # "twice is enough")
        v -= alpha[j] * basis[j]
        if j > 0:
            v -= beta[j - 1] * basis[j - 1]
        block = basis[: j + 1]
        before = np.linalg.norm(v)
        v -= (block @ v) @ block
        beta[j] = np.linalg.norm(v)
        if beta[j] < 0.7071 * before:
            v -= (block @ v) @ block
            beta[j] = np.linalg.norm(v)
        if beta[j] <= 1e-14 * max(abs(alpha[j]), 1e-300):
            # invariant subspace: the Ritz values are eigenvalues
            return _ritz_top(alpha[: j + 1], beta[:j], 0.0) + (j + 1,)
        basis[j + 1] = v / beta[j]
        if (j + 1) % 10 == 0 or j + 1 == k:
            value, bound = _ritz_top(alpha[: j + 1], beta[:j], beta[j])
            if bound <= tol * value:
                return value, bound, j + 1
    value, bound = _ritz_top(alpha[:size], beta[: size - 1], beta[size - 1])
    return value, bound, size


def _ritz_top(alpha, beta, beta_next) -> tuple[float, float]:
    if alpha.size == 1:
        theta, s_last = float(alpha[0]), 1.0
    else:
        w, s = linalg.eigh_tridiagonal(alpha, beta, select="i", select_range=(alpha.size - 1,) * 2)
        theta, s_last = float(w[0]), float(s[-1, 0])
    value = float(np.sqrt(max(theta, 0.0)))
    resid = float(abs(beta_next * s_last))  # || A y - theta y || of the Ritz pair
    if value == 0.0:
        return 0.0, float(np.sqrt(resid))
    return value, resid / (2 * value)
