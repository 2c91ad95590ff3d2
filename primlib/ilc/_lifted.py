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

Largest singular value. ``M`` is never formed: a product with M or M^T costs four real FFTs
(both axes' Toeplitz blocks in one transform, the Q-filter in another) plus one sparse
product with S L; ARPACK's Lanczos on M^T M (``scipy.sparse.linalg.eigsh``, run to
convergence) needs no gap between the top singular values, which cluster near 1 for a
learning matrix; ``svds`` and power iteration (``primlib.plant.max_singular_value``) are
offered too.

Spectral radius, and why primlib trusts it. Without a Q-filter and with the lead equal to the
relative degree (h[:lead] = 0 on both axes), M is block lower-triangular in sample order:
its eigenvalues are those of the 2 x 2 blocks on the diagonal, computed exactly (no
eigen-solver touches the big matrix). Otherwise M is full and far from normal: eigenvalues of
such a matrix are ill-conditioned (a perturbation of 1e-16 moves them by orders of
magnitude more; two dense ``eig`` runs of the same 4,800 x 4,800 matrix gave 259 and 1,690),
so primlib reports the certified upper bound of Gelfand's formula

    rho(M) <= min_k sigma_max(M^k)^(1/k),   k in (1, 4, 16, 64)

whose ingredients are singular values (perfectly conditioned) computed by the same
Lanczos method on the operator M^k (k products per step, no matrix formed); the bound
tightens towards rho as k grows (PDCCILC on the paper's semicircle: 1.0136, 1.0115, 0.9978,
0.9604 for k = 1, 4, 16, 64), so it can certify rho < 1 (eq. 29: convergence) where
sigma_max >= 1 (eq. 30: no monotonic guarantee). ``spectral_radius_exact`` says which of
the two was reported.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import fft, linalg, sparse
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigsh, gmres, svds

from primlib._errors import InputError, PrimlibError
from primlib.ilc._ms_law import MasterSlaveLaw
from primlib.plant import max_singular_value

__all__ = ["LiftedMasterSlave", "lifted_master_slave"]


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
    def _spectra(self):
        """Plant FFT length and spectra (2, m); Q FFT length and kernel spectrum, or None."""
        n = self.law.n
        m = fft.next_fast_len(2 * n, real=True)
        hs = fft.rfft(self.h.T, n=m, axis=1)
        kern = self.law.q_kernel
        if kern is None:
            return m, hs, 0, None
        half = kern.size // 2
        mq = fft.next_fast_len(n + half + 1, real=True)
        c = np.zeros(mq)
        c[: half + 1] = kern[half:]
        if half:
            c[mq - half :] = kern[:half]  # centred: circular = 'same' with zero padding
        return m, hs, mq, fft.rfft(c).real  # symmetric kernel: real spectrum

    @cached_property
    def _sl(self):
        """The lead shift times the learning functions, S L, sparse (2n, 2n), and its
        transpose: own-axis terms a e[k] + b e[k-1] (eqs. 16-19), coupling
        n_i[k] (a_eps[k] n_j[k] e_j[k] + b_eps[k] n_j[k-1] e_j[k-1])."""
        law = self.law
        n = law.n
        blocks = [[None, None], [None, None]]
        for i in range(2):
            blocks[i][i] = sparse.diags([law.a[:, i], law.b[1:, i]], [0, -1])
        if law.coupled:
            nrm = law.normal
            cmat = sparse.diags([law.a[:, 2], law.b[1:, 2]], [0, -1])
            for i in range(2):
                for j in range(2):
                    coupling = sparse.diags(nrm[:, i]) @ cmat @ sparse.diags(nrm[:, j])
                    blocks[i][j] = coupling if blocks[i][j] is None else blocks[i][j] + coupling
        lmat = sparse.bmat(blocks, format="csr")
        shift = sparse.block_diag([sparse.eye(n, k=law.lead)] * 2, format="csr")
        sl = (shift @ lmat).tocsr()
        return sl, sl.T.tocsr()

    def _pad(self, x: np.ndarray) -> np.ndarray:
        """(2, N, k) learnable samples -> (2, n, k) full trial with the tail at zero."""
        out = np.zeros((2, self.law.n, x.shape[2]))
        out[:, : self.n_learn] = x
        return out

    def _apply_g(self, x: np.ndarray, transpose: bool = False) -> np.ndarray:
        # (2, n, k): one causal Toeplitz product per axis through a zero-padded real FFT
        m, hs, _, _ = self._spectra
        spec = np.conj(hs) if transpose else hs
        y = fft.irfft(fft.rfft(x, n=m, axis=1) * spec[:, :, None], n=m, axis=1)
        return y[:, : x.shape[1]]

    def _apply_q(self, x: np.ndarray) -> np.ndarray:
        # (2, n, k). Q = W K W (see MasterSlaveLaw.q) is symmetric: its own transpose.
        _, _, mq, ks = self._spectra
        if ks is None:
            return x
        w = self.law.q_weight[None, :, None]
        y = fft.irfft(fft.rfft(w * x, n=mq, axis=1) * ks[None, :, None], n=mq, axis=1)
        return w * y[:, : x.shape[1]]

    def _apply_sl(self, x: np.ndarray, transpose: bool = False) -> np.ndarray:
        sl, slt = self._sl
        k = x.shape[2]
        return ((slt if transpose else sl) @ x.reshape(2 * self.law.n, k)).reshape(x.shape)

    # ------------------------------------------------------------------ the operator M
    def _matmat(self, v: np.ndarray) -> np.ndarray:
        nl = self.n_learn
        x = self._pad(np.asarray(v, dtype=float).reshape(2, nl, -1))
        y = self._apply_q(x - self._apply_sl(self._apply_g(x)))  # eq. (28)
        return y[:, :nl].reshape(2 * nl, -1)

    def _rmatmat(self, w: np.ndarray) -> np.ndarray:
        nl = self.n_learn
        z = self._apply_q(self._pad(np.asarray(w, dtype=float).reshape(2, nl, -1)))
        y = z - self._apply_g(self._apply_sl(z, transpose=True), transpose=True)
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

        Independent of the FFT products (dense Toeplitz and Q; the same sparse S L), so
        tests and the benchmark can check one against the other. O(N^3): small N, or a baseline.
        """
        law = self.law
        n, nl = law.n, self.n_learn
        sl = self._sl[0].tocsc()  # sparse, so S L G costs O(nnz n)
        a_mat = np.eye(2 * n)
        for j in range(2):
            gj = linalg.toeplitz(self.h[:, j], np.zeros(n))
            a_mat[:, j * n : (j + 1) * n] -= sl[:, j * n : (j + 1) * n] @ gj
        keep = np.concatenate([np.arange(nl), n + np.arange(nl)])
        if law.q_kernel is None:
            return a_mat[np.ix_(keep, keep)]
        half = law.q_kernel.size // 2
        col = np.zeros(n)
        col[: min(half + 1, n)] = law.q_kernel[half : half + n]
        w = law.q_weight
        qa = w[:, None] * linalg.toeplitz(col) * w[None, :]
        m_full = np.vstack([qa[:nl] @ a_mat[:n], qa[:nl] @ a_mat[n:]])
        return m_full[:, keep]

    def blocks(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(M_x, M_y)`` of eq. (28), each shape (N, 2N): the rows of each axis."""
        m = self.dense()
        nl = self.n_learn
        return m[:nl], m[nl:]

    @cached_property
    def offset(self) -> np.ndarray:
        """``N = Q S L e_0`` of eq. (28), shape (2N,)."""
        x = self._apply_q(self._apply_sl(self.e0.T[:, :, None]))
        return x[:, : self.n_learn, 0].reshape(-1)

    # ------------------------------------------------------------------ figures of merit
    def max_singular_value(self, method: str = "lanczos", tol: float = 1e-10) -> float:
        """sigma_max(M), eq. (30): < 1 guarantees monotonic convergence in the 2-norm.

        Parameters
        ----------
        method : {"lanczos", "svds", "power"}
            ``"lanczos"``: ARPACK's Lanczos (``eigsh``) on M^T M, one product with M and
            one with M^T per step, run to convergence; ``"svds"``: ``scipy.sparse.linalg.
            svds`` (Lanczos bidiagonalisation, about 40 % more products here);
            ``"power"``: power iteration (``primlib.plant.max_singular_value``), which
            crawls when the top singular values cluster, as they do near 1 for a learning
            matrix. Lanczos needs no gap.
        tol : float
            Relative tolerance.
        """
        return _sigma_max(self.operator, method, tol)

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

    def spectral_radius(self, powers: tuple[int, ...] = (1, 4, 16, 64)) -> tuple[float, bool]:
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
            best = min(best, _sigma_max(mk, tol=1e-8) ** (1.0 / k))
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
                raise PrimlibError(
                    f"asymptotic: GMRES did not converge for 2N = {size} (I - M is too "
                    "ill-conditioned) and the dense fallback needs 2N <= 6000"
                )
            x = np.linalg.solve(np.eye(size) - self.dense(), rhs)  # eq. (31)
        u = self._pad(x.reshape(2, self.n_learn, 1))
        e = self.e0 - self._apply_g(u)[:, :, 0].T  # eq. (32)
        return u[:, :, 0].T, e


def _sigma_max(op: LinearOperator, method: str = "lanczos", tol: float = 1e-10) -> float:
    size = op.shape[1]
    if method not in ("lanczos", "svds") or min(op.shape) <= 2:
        return max_singular_value(op, method=method, tol=tol)
    v0 = np.random.default_rng(0).standard_normal(size)
    try:
        if method == "svds":
            return float(svds(op, k=1, tol=tol, v0=v0, return_singular_vectors=False)[0])
        normal = LinearOperator(
            (size, size), matvec=lambda v: op.rmatvec(op.matvec(v)), dtype=float
        )  # M^T M
        lam = eigsh(normal, k=1, which="LA", tol=tol, v0=v0, return_eigenvectors=False)
        return float(np.sqrt(max(lam[0], 0.0)))
    except ArpackNoConvergence:
        # ARPACK gave up (clustered top singular values): primlib.plant's Lanczos never raises
        # and bounds its own error independently of the gap.
        return max_singular_value(op, method="lanczos", tol=tol)


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

    Raises
    ------
    InputError
        For a model that is not two-axis or a reference whose shape differs from the law's.

    Examples
    --------
    >>> from primlib.ilc import master_slave_law
    >>> law = master_slave_law(points, m2.dt, "pdccilc", q_cutoff=1.0)
    >>> lifted = lifted_master_slave(law, m2, points)
    >>> rho, exact = lifted.spectral_radius()
    >>> bool(rho < 1)                 # converges (asymptotically) on this stage
    True
    >>> u_inf, e_inf = lifted.asymptotic()
    >>> u_inf.shape, e_inf.shape
    ((401, 2), (401, 2))
    """
    r = np.asarray(reference, dtype=float)
    if model.dim != 2:
        raise InputError(f"model: expected a two-axis machine, got {model.dim} axes")
    if r.shape != (law.n, 2):
        raise InputError(f"reference: expected shape ({law.n}, 2) like the law's, got {r.shape}")
    h = model.impulse_response(law.n)
    e0 = r - model.reference_response(r)  # eq. (24) with u = 0
    return LiftedMasterSlave(law=law, h=h, e0=e0)
