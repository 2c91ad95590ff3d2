"""Lifted analysis of the master–slave learning laws (master–slave PDCCILC paper, eqs. 20-32).

One trial maps the input ``u_j`` to the next ``u_{j+1} = M u_j + N`` (eq. 26) with

    M = Q (I - S L G),        N = Q S L e_0                                        (eq. 27-28)

where G is the closed-loop lifted plant (block diagonal, one lower-triangular Toeplitz block
per axis, from the Machine's impulse response: eqs. 21, 24 — the PID sensitivity is inside
it), L the learning functions with their coupling (sparse, LTV: diagonal and first
sub-diagonal, eqs. 16-19), S the lead shift, Q the zero-phase Q-filter and e_0 the error of a
trial with u = 0 (the PID alone; eqs. 24-25).

The paper writes the recursion per axis (M_x, M_y) and stacks them into a composite whose
largest singular value certifies monotonic convergence (eq. 30). With cross-coupling an
axis's next input depends on the other axis's error, hence on its input, so the honest
composite is the block matrix

    M = [[M_xx, M_xy],
         [M_yx, M_yy]]        (M_x = [M_xx M_xy], M_y = [M_yx M_yy], eq. 28)

acting on the stacked input [u_x; u_y]; for the uncoupled laws it is block diagonal.

Size. As in the paper's lifting (eq. 21: u(0..N-1) drives y(1..N)), the analysed system has
N = n - lead inputs per axis: the last ``lead`` samples of a trial's input reach no measured
error and are left out, so the composite is 2N x 2N (4,800 x 4,800 for the paper's 12 s at
5 ms).

Largest singular value. ``M`` is never formed: products with M and M^T cost a few FFTs
(``primlib.plant.toeplitz_operator``) plus O(N) sparse work, and ARPACK's Lanczos
bidiagonalisation (``scipy.sparse.linalg.svds``, via ``primlib.plant.max_singular_value``)
needs no gap between the top singular values; power iteration is offered too.

Spectral radius, and why primlib trusts it. Without a Q-filter and with the lead equal to the
relative degree (h[:lead] = 0 on both axes), M is block lower-triangular in sample order:
its eigenvalues are those of the 2 x 2 blocks on the diagonal, computed exactly (no
eigen-solver touches the big matrix). Otherwise M is full and far from normal: eigenvalues of
such a matrix are ill-conditioned (a perturbation of 1e-16 moves them by orders of
magnitude more; two dense ``eig`` runs of the same 4,800 x 4,800 matrix gave 259 and 1,690),
so primlib reports the certified upper bound of Gelfand's formula

    rho(M) <= min_k sigma_max(M^k)^(1/k),   k in (1, 2, 4, 8, ...)

whose ingredients are singular values (perfectly conditioned) computed by the same
Lanczos method on the operator M^k; ``spectral_radius_exact`` says which one was reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import linalg
from scipy.sparse.linalg import LinearOperator, gmres

from primlib._errors import InputError
from primlib.ilc._ms_law import MasterSlaveLaw
from primlib.plant import max_singular_value, toeplitz_operator

__all__ = ["LiftedMasterSlave", "lifted_master_slave"]


def _shift_down(x: np.ndarray, k: int) -> np.ndarray:
    """out[t] = x[t - k] along axis 1 (zeros first)."""
    if k == 0:
        return x
    out = np.zeros_like(x)
    out[:, k:] = x[:, :-k]
    return out


def _shift_up(x: np.ndarray, k: int) -> np.ndarray:
    """out[t] = x[t + k] along axis 1 (zeros last)."""
    if k == 0:
        return x
    out = np.zeros_like(x)
    out[:, :-k] = x[:, k:]
    return out


@dataclass(frozen=True)
class LiftedMasterSlave:
    """The lifted iteration ``u_{j+1} = M u_j + N`` of one law on one machine (eqs. 26-28).

    Vectors are stacked ``[u_x; u_y]`` (axis-major), each of the N = n - lead learnable
    samples. Build with :func:`lifted_master_slave`.

    Attributes
    ----------
    law : MasterSlaveLaw
    h : array, shape (n, 2)
        Closed-loop Markov parameters u -> y of the model (PID inside).
    e0 : array, shape (n, 2)
        Error of the trial with u = 0 (feedback alone).
    """

    law: MasterSlaveLaw
    h: np.ndarray
    e0: np.ndarray

    # ------------------------------------------------------------------ building blocks
    @property
    def n_learn(self) -> int:
        """N = n - lead, the learnable samples per axis."""
        return self.law.n - self.law.lead

    @cached_property
    def _g(self) -> list[LinearOperator]:
        return [toeplitz_operator(self.h[:, i]) for i in range(2)]

    def _pad(self, x: np.ndarray) -> np.ndarray:
        """(2, N, k) learnable samples -> (2, n, k) full trial with the tail at zero."""
        out = np.zeros((2, self.law.n, x.shape[2]))
        out[:, : self.n_learn] = x
        return out

    def _apply_g(self, x: np.ndarray, transpose: bool = False) -> np.ndarray:
        ops = [g.T if transpose else g for g in self._g]
        return np.stack([ops[i].matmat(x[i]) for i in range(2)])

    def _apply_l(self, e: np.ndarray) -> np.ndarray:
        """Learning functions and coupling, then the lead shift (eqs. 16-19), on (2, n, k)."""
        law = self.law
        a = law.a.T[:, :, None]
        b = law.b.T[:, :, None]
        out = a[:2] * e + b[:2] * _shift_down(e, 1)
        if law.coupled:
            nrm = law.normal.T[:, :, None]
            eps = np.sum(nrm * e, axis=0, keepdims=True)  # eq. (1)
            out += nrm * (a[2:] * eps + b[2:] * _shift_down(eps, 1))
        return _shift_up(out, law.lead)

    def _apply_l_t(self, w: np.ndarray) -> np.ndarray:
        law = self.law
        a = law.a.T[:, :, None]
        b = law.b.T[:, :, None]
        w = _shift_down(w, law.lead)
        out = a[:2] * w + _shift_up(b[:2] * w, 1)
        if law.coupled:
            nrm = law.normal.T[:, :, None]
            p = np.sum(nrm * w, axis=0, keepdims=True)
            out += nrm * (a[2:] * p + _shift_up(b[2:] * p, 1))
        return out

    def _apply_q(self, x: np.ndarray) -> np.ndarray:
        # (2, n, k): time is axis 1; Q is symmetric, so it is its own transpose
        if self.law.q_kernel is None:
            return x
        return np.moveaxis(self.law.q(np.moveaxis(x, 1, 0)), 0, 1)

    _apply_q_t = _apply_q

    # ------------------------------------------------------------------ the operator M
    def _matmat(self, v: np.ndarray) -> np.ndarray:
        nl = self.n_learn
        x = self._pad(np.asarray(v, dtype=float).reshape(2, nl, -1))
        y = self._apply_q(x - self._apply_l(self._apply_g(x)))  # eq. (28)
        return y[:, :nl].reshape(2 * nl, -1)

    def _rmatmat(self, w: np.ndarray) -> np.ndarray:
        nl = self.n_learn
        z = self._apply_q_t(self._pad(np.asarray(w, dtype=float).reshape(2, nl, -1)))
        y = z - self._apply_g(self._apply_l_t(z), transpose=True)
        return y[:, :nl].reshape(2 * nl, -1)

    @cached_property
    def operator(self) -> LinearOperator:
        """``M`` as a LinearOperator, shape (2N, 2N), FFT products both ways."""
        size = 2 * self.n_learn
        return LinearOperator(
            (size, size),
            matvec=lambda v: self._matmat(v).ravel(),
            rmatvec=lambda w: self._rmatmat(w).ravel(),
            matmat=self._matmat,
            rmatmat=self._rmatmat,
            dtype=float,
        )

    def dense(self) -> np.ndarray:
        """``M`` as a dense array, shape (2N, 2N), assembled from dense factors.

        Independent of the FFT operator (dense Toeplitz, dense L, dense Q), so tests and
        the benchmark can check one against the other. O(N^3): small N, or a baseline.
        """
        law = self.law
        n, lead, nl = law.n, law.lead, self.n_learn
        g = linalg.block_diag(*[linalg.toeplitz(self.h[:, i], np.zeros(n)) for i in range(2)])
        lmat = np.zeros((2 * n, 2 * n))
        for i in range(2):
            lmat[i * n : (i + 1) * n, i * n : (i + 1) * n] = np.diag(law.a[:, i]) + np.diag(
                law.b[1:, i], -1
            )
        if law.coupled:
            nrm = law.normal
            cmat = np.diag(law.a[:, 2]) + np.diag(law.b[1:, 2], -1)
            for i in range(2):
                for j in range(2):
                    # n_i[k] (a_eps[k] n_j[k] e_j[k] + b_eps[k] n_j[k-1] e_j[k-1])
                    lmat[i * n : (i + 1) * n, j * n : (j + 1) * n] += (
                        nrm[:, i, None] * cmat * nrm[None, :, j]
                    )
        shift = linalg.block_diag(*[np.eye(n, k=lead)] * 2)
        if law.q_kernel is None:
            q = np.eye(2 * n)
        else:
            half = law.q_kernel.size // 2
            col = np.zeros(n)
            col[: min(half + 1, n)] = law.q_kernel[half : half + n]
            k = linalg.toeplitz(col)
            w = law.q_weight
            qa = w[:, None] * k * w[None, :]
            q = linalg.block_diag(qa, qa)
        m_full = q @ (np.eye(2 * n) - shift @ lmat @ g)
        keep = np.concatenate([np.arange(nl), n + np.arange(nl)])
        return m_full[np.ix_(keep, keep)]

    def blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(M_x, M_y)`` of eq. (28), each shape (N, 2N): the rows of each axis."""
        m = self.dense()
        nl = self.n_learn
        return m[:nl], m[nl:]

    @cached_property
    def offset(self) -> np.ndarray:
        """``N = Q S L e_0`` of eq. (28), shape (2N,)."""
        x = self._apply_q(self._apply_l(self.e0.T[:, :, None]))
        return x[:, : self.n_learn, 0].reshape(-1)

    # ------------------------------------------------------------------ figures of merit
    def max_singular_value(self, method: str = "svds", tol: float = 1e-10) -> float:
        """sigma_max(M), eq. (30): < 1 guarantees monotonic convergence in the 2-norm."""
        return max_singular_value(self.operator, method=method, tol=tol)

    @property
    def triangular(self) -> bool:
        """True when M is block lower-triangular in sample order (no Q, h[:lead] = 0)."""
        lead = self.law.lead
        return self.law.q_kernel is None and (lead == 0 or not np.any(self.h[:lead]))

    def diagonal_blocks(self) -> np.ndarray:
        """The 2 x 2 diagonal blocks of M in sample order, shape (N, 2, 2).

        Exact eigenvalue carriers when :attr:`triangular`: block k is I - A[k+lead] diag(h[lead])
        with A the learning coefficients of the errors at one sample (own terms a, coupling
        a_eps n n^T)."""
        law = self.law
        lead, nl = law.lead, self.n_learn
        a = law.a[lead : lead + nl]
        amat = np.zeros((nl, 2, 2))
        amat[:, 0, 0] = a[:, 0]
        amat[:, 1, 1] = a[:, 1]
        if law.coupled:
            nrm = law.normal[lead : lead + nl]
            amat += a[:, 2, None, None] * nrm[:, :, None] * nrm[:, None, :]
        return np.eye(2)[None] - amat * self.h[lead][None, None, :]

    def spectral_radius(self, powers: tuple[int, ...] = (1, 2, 4, 8)) -> tuple[float, bool]:
        """rho(M), eq. (29), and whether it is exact.

        Exact (max |eigenvalue| of the 2 x 2 diagonal blocks) when :attr:`triangular`;
        otherwise the certified bound min_k sigma_max(M^k)^(1/k) over ``powers``.

        Returns
        -------
        rho : float
        exact : bool
        """
        if self.triangular:
            return float(np.max(np.abs(np.linalg.eigvals(self.diagonal_blocks())))), True
        op = self.operator
        best = np.inf
        for k in powers:
            if k < 1:
                raise InputError(f"powers: expected integers >= 1, got {powers!r}")
            mk = _power(op, int(k))
            best = min(best, max_singular_value(mk, tol=1e-8) ** (1.0 / k))
        return float(best), False

    def asymptotic(self, tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
        """Converged input and error (eqs. 31-32): u = (I - M)^-1 N, e = e_0 - G u.

        Solved with GMRES on the FFT operator (a dense LU when GMRES stalls and 2N <= 6,000).

        Returns
        -------
        u : array, shape (n, 2)
            Zero on the last ``lead`` samples (they reach no measured error).
        e : array, shape (n, 2)
        """
        size = 2 * self.n_learn
        op = self.operator
        a = LinearOperator((size, size), matvec=lambda v: v - op.matvec(v), dtype=float)
        rhs = self.offset
        x, info = gmres(a, rhs, rtol=tol, atol=0.0, restart=200, maxiter=50)
        if info != 0:
            if size > 6000:
                raise InputError(
                    f"asymptotic: GMRES did not converge for 2N = {size} (I - M is too "
                    "ill-conditioned); expected 2N <= 6000 for the dense fallback"
                )
            x = np.linalg.solve(np.eye(size) - self.dense(), rhs)  # eq. (31)
        u = self._pad(x.reshape(2, self.n_learn, 1))
        e = self.e0 - self._apply_g(u)[:, :, 0].T  # eq. (32)
        return u[:, :, 0].T, e


def _power(op: LinearOperator, k: int) -> LinearOperator:
    if k == 1:
        return op

    def mv(v):
        for _ in range(k):
            v = op.matmat(v) if v.ndim == 2 else op.matvec(v)
        return v

    def rmv(w):
        for _ in range(k):
            w = op.rmatmat(w) if w.ndim == 2 else op.rmatvec(w)
        return w

    return LinearOperator(op.shape, matvec=mv, rmatvec=rmv, matmat=mv, rmatmat=rmv, dtype=float)


def lifted_master_slave(law: MasterSlaveLaw, model, reference) -> LiftedMasterSlave:
    """Lifted iteration of ``law`` on ``model`` (a two-axis Machine) for ``reference``.

    Parameters
    ----------
    law : MasterSlaveLaw
        From :func:`primlib.ilc.master_slave_law` on the same reference.
    model : Machine
        Two-axis machine, its PID loops inside.
    reference : array, shape (n, 2)
        Reference relative to the start point (the PID reference and the desired output).

    Returns
    -------
    LiftedMasterSlave
    """
    r = np.asarray(reference, dtype=float)
    if model.dim != 2:
        raise InputError(f"model: expected a two-axis machine, got {model.dim} axes")
    if r.shape != (law.n, 2):
        raise InputError(f"reference: expected shape ({law.n}, 2) like the law's, got {r.shape}")
    h = model.impulse_response(law.n)
    e0 = r - model.reference_response(r)  # eq. (24) with u = 0
    return LiftedMasterSlave(law=law, h=h, e0=e0)
