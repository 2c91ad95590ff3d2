"""Norm-optimal ILC step for long trials: (G^T G + w I) x = b without an n x n matrix.

G is the lifted (lower-triangular Toeplitz) matrix of a response g (n,), the model of one
axis shifted by its relative degree. The dense route factors G^T G + w I (n^3 / 3 flops,
8 n^2 bytes: 3.2 GB at n = 20,000). Here instead:

- the operator A = G^T G + w I is applied through the FFT (``toeplitz_operator``),
  O(n log n) per product;
- it is solved by preconditioned conjugate gradients. When g is the impulse response of a
  rational model, g = num / den (polynomials in q^-1, ``den[0] != 0``), the lifted algebra
  is exact: G = D^-1 N with N, D the banded lower-triangular Toeplitz matrices of num and den
  (truncated power series multiply exactly, and lower-triangular Toeplitz matrices
  commute), so

      G^T G + w I = D^-T (N^T N + w D^T D) D^-1,   A^-1 = D (N^T N + w D^T D)^-1 D^T,

  with N^T N + w D^T D symmetric positive definite and *banded* (bandwidth the model's
  order): a banded Cholesky, O(n p^2). That product is the preconditioner; in exact
  arithmetic it is A^-1 and CG stops after one step. In floating point the banded system
  can be worse conditioned than A (D of an integrating axis has sigma_min ~ 1 / n), so CG
  on the FFT operator polishes the result to the stated tolerance in a few steps. The
  preconditioner need not be exact, only symmetric positive definite (it always is):
  expanded closed-loop polynomials with poles near z = 1 carry rounding (their response
  can differ from the machine's, which simulates in second-order sections, by ~1e-6), and
  then CG takes a few more steps. Without polynomials (or when their response is off by
  more than 1 % of g's largest value) plain CG runs, which needs ~sqrt(cond A) steps.

Stopping rule: ||b - A x|| <= rtol ||b|| with

    rtol = min(1e-10, 2e-6 sqrt(w) / ||g||_1).

Why that is enough: the step error d = A^-1 r changes the next trial's error by G d, and
||G A^-1|| = max over singular values s of s / (s^2 + w) <= 1 / (2 sqrt w) while
||b|| = ||G^T e|| <= ||G|| ||e|| <= ||g||_1 ||e|| (Young), so

    ||G d|| <= rtol ||g||_1 / (2 sqrt w) ||e|| <= 1e-6 ||e||:

each solve perturbs the next error by at most a millionth of the current one, far below
what a trial removes, below any model error, and the iteration map w A^-1 (norm <= 1) does
not amplify earlier perturbations. On the XYZ stage at 20,000 samples ||g||_1 / sqrt w ~
7e4, so rtol ~ 3e-11; the preconditioned solves reach it in 1-2 steps. The same bound gives
the input error, ||d|| <= rtol ||b|| / w, which the tests comparing with the dense Cholesky
route use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, signal, sparse

from primlib.plant._lifted import toeplitz_operator

__all__ = ["NormalSolver", "CGInfo", "CG_RTOL", "ERROR_PERTURBATION"]

CG_RTOL = 1e-10  # ceiling of the relative residual
ERROR_PERTURBATION = 1e-6  # bound of ||G d|| / ||e|| per solve (module docstring)


def _banded_lower(c: np.ndarray, n: int):
    c = c[:n]
    return sparse.diags([np.full(n - k, c[k]) for k in range(c.size)], [-k for k in range(c.size)])


class NormalSolver:
    """Solves (G^T G + w I) x = b, G the lower-triangular Toeplitz matrix of g.

    Parameters
    ----------
    g : array, shape (n,)
        First column of G (``g[0] != 0``).
    w : float
        Weight, > 0.
    num, den : array, optional
        Polynomials in q^-1 with g ~ num / den (the preconditioner, see the module
        docstring); ignored if their response is off g by more than 1 % of its largest
        value.
    rtol : float, optional
        Relative residual at which CG stops; None: min(CG_RTOL, 2 ERROR_PERTURBATION
        sqrt(w) / ||g||_1) (module docstring).
    maxiter : int, optional
        Largest number of CG steps per solve (default: 50 with the preconditioner, then
        up to max(200, min(n, 5000)) more without it if it stalls; without it, the latter).

    Attributes
    ----------
    preconditioned : bool
    method : str
    """

    def __init__(self, g, w: float, num=None, den=None, rtol=None, maxiter=None):
        self.g = np.asarray(g, dtype=float)
        self.n = n = self.g.size
        self.w = float(w)
        if rtol is None:
            g1 = float(np.sum(np.abs(self.g)))
            rtol = min(CG_RTOL, 2 * ERROR_PERTURBATION * np.sqrt(self.w) / g1)
        self.rtol = float(rtol)
        self._op = toeplitz_operator(self.g)
        self._pre = None
        if num is not None and den is not None:
            self._pre = _banded_inverse(self.g, self.w, num, den)
        self.preconditioned = self._pre is not None
        if maxiter is None:
            maxiter = 50 if self.preconditioned else max(200, min(n, 5000))
        self.maxiter = int(maxiter)
        self.fallback_maxiter = max(200, min(n, 5000))
        self.method = (
            "CG on FFT Toeplitz operators, banded-Cholesky preconditioner"
            if self.preconditioned
            else "CG on FFT Toeplitz operators"
        )

    def matvec(self, x: np.ndarray) -> np.ndarray:
        """A x = G^T G x + w x."""
        return self._op.rmatvec(self._op.matvec(x)) + self.w * x

    def rhs(self, e: np.ndarray) -> np.ndarray:
        """G^T e."""
        return self._op.rmatvec(e)

    def solve(self, b: np.ndarray, x0=None) -> tuple[np.ndarray, CGInfo]:
        """x with ||b - A x|| <= rtol ||b|| (or after ``maxiter`` steps).

        Parameters
        ----------
        b : array, shape (n,)
        x0 : array, shape (n,), optional
            Warm start (e.g. the previous trial's step). It is first scaled by the
            alpha minimising the A-norm error along it, alpha = x0.b / x0.A x0, so a stale
            warm start is never worse than zero.

        Returns
        -------
        x : array, shape (n,)
        info : CGInfo
        """
        b = np.asarray(b, dtype=float)
        nb = float(np.linalg.norm(b))
        if nb == 0.0:
            return np.zeros(self.n), CGInfo(0, 0.0, True)
        x = np.zeros(self.n)
        r = b.copy()
        if x0 is not None:
            ax0 = self.matvec(x0)
            denom = float(x0 @ ax0)
            if denom > 0:
                alpha = float(x0 @ b) / denom
                x = alpha * np.asarray(x0, dtype=float)
                r = b - alpha * ax0
        goal = self.rtol * nb
        x, res, steps = self._cg(b, x, r, goal, self.maxiter, self._pre)
        if res > goal and self._pre is not None:
            # a poor preconditioner (see _banded_inverse) stalls: go on without it
            x, res, more = self._cg(b, x, b - self.matvec(x), goal, self.fallback_maxiter, None)
            steps += more
        return x, CGInfo(steps, res / nb, res <= goal)

    def _cg(self, b, x, r, goal, maxiter, pre):
        res = float(np.linalg.norm(r))
        z = r.copy() if pre is None else pre(r)
        p = z.copy()
        rz = float(r @ z)
        steps = 0
        while res > goal and steps < maxiter:
            ap = self.matvec(p)
            pap = float(p @ ap)
            if not pap > 0.0 or not rz > 0.0:  # breakdown (rounding): restart from here
                break
            step = rz / pap
            x += step * p
            steps += 1
            if steps % 10 == 0:  # replace the recurrence's residual by the true one
                r = b - self.matvec(x)
            else:
                r -= step * ap
            res = float(np.linalg.norm(r))
            z = r.copy() if pre is None else pre(r)
            rz_new = float(r @ z)
            p = z + (rz_new / rz) * p
            rz = rz_new
        return x, res, steps


@dataclass(frozen=True)
class CGInfo:
    """One conjugate-gradient solve: ``iterations``, final relative residual
    ``||b - A x|| / ||b||``, and whether it reached the tolerance."""

    iterations: int
    residual: float
    converged: bool


def _cancel_common_roots(num, den, tol: float = 1e-3):
    """Drop zero-pole pairs closer than ``tol`` (first coefficients kept).

    A PID loop's integrator puts a zero at z = 1 in u -> y while a slow closed-loop pole
    sits just inside it: N and D then nearly share a null direction and N^T N + w D^T D is
    numerically singular. Without the pair the model differs only at frequencies within
    ~|z - p| of the pair; as a preconditioner that costs CG a few steps.
    """
    if num.size < 2 or den.size < 2:
        return num, den
    zeros = list(np.roots(num))
    poles = list(np.roots(den))
    pairs = sorted((abs(z - p), i, j) for i, z in enumerate(zeros) for j, p in enumerate(poles))
    used_z, used_p = set(), set()
    for dist, i, j in pairs:
        if dist > tol:
            break
        if i not in used_z and j not in used_p:
            used_z.add(i)
            used_p.add(j)
    if not used_z:
        return num, den
    kz = [z for i, z in enumerate(zeros) if i not in used_z]
    kp = [p for j, p in enumerate(poles) if j not in used_p]
    new_num = num[0] * np.real(np.poly(kz)) if kz else num[:1].copy()
    new_den = den[0] * np.real(np.poly(kp)) if kp else den[:1].copy()
    return np.atleast_1d(new_num), np.atleast_1d(new_den)


def _banded_inverse(g, w, num, den):
    """x -> D (N^T N + w D^T D)^-1 D^T x, or None when num/den do not describe g."""
    n = g.size
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if den.size == 0 or den[0] == 0.0 or num.size == 0:
        return None
    imp = np.zeros(n)
    imp[0] = 1.0
    with np.errstate(over="ignore", invalid="ignore"):
        g_poly = signal.lfilter(num, den, imp)
    scale = float(np.max(np.abs(g)))
    if not np.all(np.isfinite(g_poly)) or np.max(np.abs(g_poly - g)) > 1e-2 * scale:
        return None
    num, den = _cancel_common_roots(num, den)
    N = _banded_lower(num, n)
    D = _banded_lower(den, n)
    B = (N.T @ N + w * (D.T @ D)).tocsr()
    p = max(num.size, den.size) - 1
    ab = np.zeros((p + 1, n))
    for k in range(min(p, n - 1) + 1):
        ab[p - k, k:] = B.diagonal(k)
    # num and den sharing a (near-)root at z = 1 (an integrator cancelled by a zero of the
    # loop) leave B numerically singular; a tiny diagonal shift keeps it positive definite
    # and only costs CG a few steps in those directions
    chol = None
    for shift in (0.0, 1e-12, 1e-9):
        shifted = ab.copy()
        shifted[p] += shift * float(np.max(ab[p]))
        try:
            chol = linalg.cholesky_banded(shifted, lower=False, check_finite=False)
            break
        except linalg.LinAlgError:
            continue
    if chol is None:
        return None
    D = D.tocsr()
    Dt = D.T.tocsr()

    def apply(x):
        return D @ linalg.cho_solve_banded((chol, False), Dt @ x, check_finite=False)

    return apply
