"""Continuous refinement of a candidate's start and end (damped Gauss–Newton, variable
projection), and the exact RMSD of a candidate against a piece of the path."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from primlib.match._interp import cubic_at
from primlib.match._kabsch import KabschResult, kabsch, rotation_for
from primlib.match._options import Candidate, PathPiece, SearchOptions

if TYPE_CHECKING:
    from primlib.match._bank import BankIndex

__all__ = [
    "refine",
    "clamp",
    "clamp_many",
    "piece_rmsd",
    "duration_range",
    "solve_box_qp2",
    "rotation_coupling",
    "hopeless",
    "slack_tolerance",
]

# A z <= c for z = (x0, x1): x0 >= 0, x1 <= n − 1, x1 − x0 >= lo, x1 − x0 <= hi
_AMAT = np.array([[-1.0, 0.0], [0.0, 1.0], [1.0, -1.0], [-1.0, 1.0]])
_BUDGET = 60  # evaluations per refinement
# converged: a step moved less than this (samples) or gained less than this of the cost
_MOVED = 1e-4
_GAIN = 1e-8


def slack_tolerance(c: np.ndarray) -> np.ndarray:
    """How far past the constraints ``A z <= c`` a step may land and count as feasible:
    1e-9 (1 + |c|), for the one-seed and the many-seed solvers alike."""
    return 1e-9 * (1.0 + np.abs(c))


def prim_at(bank: BankIndex, i: int, x: np.ndarray) -> np.ndarray:
    """Primitive row i at fractional sample indices x (cubic interpolation)."""
    return cubic_at(bank.points, bank.offsets[i], bank.offsets[i + 1] - bank.offsets[i], x)


def piece_rmsd(
    bank: BankIndex, cand: Candidate, path: PathPiece, a: float, b: float, k: int, rotation: str
) -> KabschResult:
    """Kabsch superposition of the candidate onto the path piece, both at k uniform times."""
    p = prim_at(bank, cand.prim, np.linspace(cand.x0, cand.x1, k))
    q = path.at(np.linspace(a, b, k))
    return kabsch(p, q, rotation=rotation)


def duration_range(
    n_p: int | np.ndarray, dq: float, opts: SearchOptions
) -> tuple[float, float | np.ndarray]:
    """Allowed candidate duration (in samples) for a query of ``dq`` samples' duration in a
    primitive of ``n_p`` samples (an int, or an array of them: the upper end per entry):
    the time-scale range, clipped to the primitive."""
    return max(opts.time_scale[0] * dq, 1e-6), np.minimum(opts.time_scale[1] * dq, n_p - 1.0)


def clamp(bank: BankIndex, cand: Candidate, duration: float, opts: SearchOptions) -> Candidate:
    """The candidate with its duration clipped to the time-scale range (for a query lasting
    ``duration`` s) and its start moved so it stays inside the primitive (one row of
    :func:`clamp_many`)."""
    z, _, _ = clamp_many(bank, np.array([cand.prim]), np.array([[cand.x0, cand.x1]]),
                         duration / bank.dt, opts)  # fmt: skip
    return Candidate(cand.prim, float(z[0, 0]), float(z[0, 1]), cand.score)


def clamp_many(bank: BankIndex, prim: np.ndarray, z: np.ndarray, steps: float,
               opts: SearchOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`duration_range` and :func:`clamp` of m candidates at once.

    Parameters
    ----------
    bank : BankIndex
        The primitives.
    prim : array of int, shape (m,)
        Each candidate's primitive row.
    z : array, shape (m, 2)
        Each candidate's (x0, x1), fractional sample indices.
    steps : float
        The query's duration in sample steps of the bank's dt.
    opts : SearchOptions
        Its time-scale range.

    Returns
    -------
    z : array, shape (m, 2)
        The clamped (x0, x1): duration clipped to [lo, hi], start moved inside the primitive.
    lo, hi : arrays, shape (m,)
        The allowed duration range; a row with ``hi < lo`` is a primitive too short for the
        time-scale range (its z is then clipped to hi: no candidate of it is allowed).
    """
    n_p = bank.offsets[prim + 1] - bank.offsets[prim]
    low, hi = duration_range(n_p, steps, opts)
    lo = np.broadcast_to(low, hi.shape)
    span = np.minimum(np.maximum(z[:, 1] - z[:, 0], lo), hi)
    x0 = np.minimum(np.maximum(z[:, 0], 0.0), n_p - 1.0 - span)
    return np.stack([x0, x0 + span], axis=1), lo, hi


def solve_box_qp2(h: np.ndarray, g: np.ndarray, z: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Minimise ½δᵀHδ − gᵀδ subject to A(z + δ) ≤ b, for 2 unknowns (H positive definite).

    Convex, so the optimum is the unconstrained minimiser, the minimiser on one constraint
    line, or a vertex of two: try them all and keep the best feasible one.
    """
    slack = b - a @ z
    tol = slack_tolerance(b)
    free = np.linalg.solve(h, g)
    if np.all(a @ free <= slack + tol):
        return free  # the usual case: no constraint active
    cands = [free]
    for i in range(len(b)):
        ai = a[i]
        # on the line ai·δ = slack_i: δ = δ_p + t·n, n ⟂ ai
        dp = ai * slack[i] / (ai @ ai)
        nv = np.array([-ai[1], ai[0]])
        den = nv @ h @ nv
        t = (nv @ (g - h @ dp)) / den if den > 0 else 0.0
        cands.append(dp + t * nv)
        for j in range(i + 1, len(b)):
            m = np.array([a[i], a[j]])
            if abs(np.linalg.det(m)) > 1e-12:
                cands.append(np.linalg.solve(m, [slack[i], slack[j]]))
    best, best_f = np.zeros(2), 0.0
    for d in cands:
        if np.all(a @ d <= slack + tol):
            f = 0.5 * d @ h @ d - g @ d
            if f < best_f:
                best, best_f = d, f
    return best


class _Residual:
    """The centred residual q̃_j − R p̃(x0 + (x1 − x0) s_j) under the Kabsch R of (x0, x1),
    with the derivative of R p along the curve (R held fixed: the envelope theorem)."""

    def __init__(self, own: np.ndarray, q: np.ndarray, rotation: str) -> None:
        self.own = own
        self.qc = q - q.mean(axis=0)
        self.s = np.linspace(0.0, 1.0, q.shape[0])
        self.rotation = rotation
        self.fix = np.ones(q.shape[1])

    def __call__(self, z: np.ndarray):
        n_p = self.own.shape[0]
        x = z[0] + (z[1] - z[0]) * self.s
        p, dp = cubic_at(self.own, 0, n_p, x, derivative=True)
        pc = p - p.mean(axis=0)
        h = pc.T @ self.qc
        if self.rotation == "full":
            # any optimal rotation gives the same residual, so no canonical choice needed
            u, _, vt = np.linalg.svd(h)
            self.fix[-1] = 1.0 if np.linalg.det(u @ vt) > 0 else -1.0
            r = (vt.T * self.fix) @ u.T
        else:
            r = rotation_for(h, self.rotation)
        res = self.qc - pc @ r.T
        return float(np.sum(res * res)), res, dp @ r.T

    def normal_equations(self, res: np.ndarray, dpr: np.ndarray):
        """JᵀJ (rotation eliminated: :func:`rotation_coupling`) and Jᵀr of the linearised
        residual in (x0, x1)."""
        j1 = dpr * self.s[:, None]  # ∂(R p_j)/∂x1
        j0 = dpr - j1  # ∂(R p_j)/∂x0
        jac = np.stack([j0 - j0.mean(axis=0), j1 - j1.mean(axis=0)], axis=2)  # (k, d, 2)
        jtj = np.einsum("kac,kae->ce", jac, jac)
        red = jtj - rotation_coupling((self.qc - res)[None], jac[None], self.rotation)[0]
        return red + 1e-9 * np.diag(np.diag(jtj)), np.einsum("kac,ka->c", jac, res)


def rotation_coupling(u: np.ndarray, jac: np.ndarray, rotation: str) -> np.ndarray:
    """B I⁻¹ Bᵀ, shape (m, 2, 2): what a small rotation of the rotated, centred primitive
    u (m, k, d) takes back from JᵀJ of the Jacobian columns ``jac`` (m, k, d, 2).

    The residual linearised in (δz, ω) is r − J δz − ω × u_j. Eliminating ω (its gradient
    is zero at the Kabsch optimum) leaves the Schur complement JᵀJ − B I⁻¹ Bᵀ as the
    Gauss–Newton matrix of the reduced cost min_R Σ|r_j|², with B_c = Σ_j u_j × J_c,j and
    I = Σ_j (|u_j|² 1 − u_j u_jᵀ) (u's inertia). Holding R fixed instead (JᵀJ alone)
    over-estimates the curvature wherever a rotation can absorb part of a shift along the
    curve, and Gauss–Newton then crawls (tens of short steps where a few do). Zero for
    ``rotation="none"``; one angle about the plane's normal in 2-D and for ``"z"``.
    """
    m = u.shape[0]
    if rotation == "none":
        return np.zeros((m, 2, 2))
    cov = np.einsum("mka,mkbc->mcab", u, jac)  # Σ_j u_j J_c,jᵀ, (m, 2, d, d)
    if u.shape[2] == 3 and rotation == "full":
        # (u × v)_a = ε_abc u_b v_c: the antisymmetric part of Σ u vᵀ
        b = np.stack([cov[..., 1, 2] - cov[..., 2, 1], cov[..., 2, 0] - cov[..., 0, 2],
                      cov[..., 0, 1] - cov[..., 1, 0]], axis=2)  # fmt: skip
        uu = np.einsum("mka,mkb->mab", u, u)
        inertia = np.trace(uu, axis1=1, axis2=2)[:, None, None] * np.eye(3) - uu
        inertia += 1e-12 * np.trace(inertia, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        return b @ np.linalg.solve(inertia, b.transpose(0, 2, 1))
    b = cov[..., 0, 1] - cov[..., 1, 0]  # (m, 2): the angle about the plane's normal
    inertia = np.einsum("mka,mka->m", u[..., :2], u[..., :2])
    return b[:, :, None] * b[:, None, :] / np.maximum(inertia, 1e-300)[:, None, None]


def hopeless(cost, gain, previous, give_up: float):
    """True where Gauss–Newton, converging linearly at the ratio ρ = gain / previous of its
    last two accepted decreases, would still end above ``give_up`` with ten times the
    geometric tail gain·ρ/(1 − ρ) taken off; never within 1.21·give_up (RMSD 1.1 ε).

    A heuristic, not a bound (on novel paths no seed so abandoned ever ended within it).
    """
    rho = gain / np.where(previous > 0, previous, np.inf)
    tail = 10.0 * gain * rho / np.where(rho < 1.0, 1.0 - rho, 1.0)
    return (cost > 1.21 * give_up) & (rho < 1.0) & (previous > 0) & (cost - tail > give_up)


def refine(
    bank: BankIndex,
    cand: Candidate,
    path: PathPiece,
    a: float,
    b: float,
    opts: SearchOptions,
    target: float = 0.0,
    give_up: float = np.inf,
) -> Candidate:
    """Continuous refinement of a seed's start and end, bounded to the time-scale range.

    Variable projection with damped Gauss–Newton: the residual r_j = q̃_j − R p̃(x0 + (x1 −
    x0) s_j) (s_j uniform in [0, 1], tildes = centred) is linearised in (x0, x1) with the
    Kabsch R of the current iterate held fixed — by the envelope theorem this is the
    gradient of the reduced cost min_R Σ|r_j|² — and the derivative of the stored curve
    comes from its cubic interpolant. Each step solves the linearised problem exactly under
    0 ≤ x0, x1 ≤ n − 1 and the time-scale range lo ≤ x1 − x0 ≤ hi (:func:`solve_box_qp2`),
    and is accepted only when the cost decreases (Levenberg damping otherwise). Stops at
    convergence (60 evaluations at most), as soon as the RMSD at the refinement points
    is below ``target``, or when its cost decrease says it will not end below ``give_up``
    (:func:`hopeless`).
    """
    off = int(bank.offsets[cand.prim])
    n_p = int(bank.offsets[cand.prim + 1]) - off
    lo, hi = duration_range(n_p, (b - a) * path.duration / bank.dt, opts)
    if hi < lo:
        return cand
    k = opts.refine_points
    resid = _Residual(bank.points[off : off + n_p], path.at(np.linspace(a, b, k)), opts.rotation)
    c0 = clamp(bank, cand, (b - a) * path.duration, opts)
    z = _gauss_newton(resid, np.array([c0.x0, c0.x1]), np.array([0.0, n_p - 1.0, -lo, hi]),
                      target * target * k, give_up * give_up * k)  # fmt: skip
    return Candidate(cand.prim, float(z[0]), float(z[1]), cand.score)


def _gauss_newton(resid: _Residual, z: np.ndarray, cvec: np.ndarray, stop: float,
                  give_up: float) -> np.ndarray:  # fmt: skip
    """Damped Gauss–Newton on (x0, x1) under A z ≤ c until the cost is below ``stop``."""
    cost, res, dpr = resid(z)
    lam, gain = 0.0, 0.0
    budget = _BUDGET
    while budget > 0 and cost >= stop:
        jtj, g = resid.normal_equations(res, dpr)
        improved = False
        while budget > 0:
            h = jtj + (lam + 1e-12) * np.diag(np.diag(jtj) + 1e-12)
            step = solve_box_qp2(h, g, z, _AMAT, cvec)
            if not np.any(step):
                break
            nz = z + step
            ncost, nres, ndpr = resid(nz)
            budget -= 1
            if ncost < cost:
                moved = float(np.abs(step).sum())
                previous, gain = gain, cost - ncost
                z, cost, res, dpr = nz, ncost, nres, ndpr
                lam = lam / 10.0 if lam > 1e-6 else 0.0
                improved = True
                break
            lam = max(lam * 10.0, 1e-4)
            if lam > 1e8:
                break
        if not improved or moved < _MOVED or gain < _GAIN * cost:
            break
        if hopeless(cost, gain, previous, give_up):
            break
    return z
