"""Sub-curve search: the best stored piece for one piece of the new path.

A *query* is the piece [a, b] (normalised time) of the new path; a *candidate* is a piece
[x0, x1] (fractional sample indices) of a stored primitive. Both are compared sampled at
uniform time — K points each, ``rmsd`` of eq. (1) in ``_kabsch`` — so a candidate of
duration (x1 − x0)·dt against a query of duration (b − a)·T has time scale
k = (x1 − x0)·dt / ((b − a)·T), within ``time_scale`` (default 0.25–4).

Three searchers propose *seeds* (candidates ranked by a grid RMSD); all three hand them to
the same continuous refinement (:func:`refine`) and the same dense confirmation, so they
differ only in how fast they find the seeds:

``GridSearch`` (the reference, exhaustive on a documented grid)
    Query sampled at K = ``grid_points`` (16) uniform-time points. Every primitive; every
    duration D = k·(query duration) for k on a geometric grid over ``time_scale`` with ratio
    at most ``scale_ratio`` (1.1, so 30 scales over 0.25–4); for each D the primitive is
    resampled at the stride h = D/(K − 1) and every start m·h (m = 0, 1, ...) is a
    candidate whose K points are K consecutive resampled points. The cross-covariances of
    the centred query with every window come from one product over a strided window view,
    the window second moments from cumulative sums, and the RMSD of all windows at once
    from ``rmsd_from_moments`` (QCP, no rotation formed).
``LoopSearch``
    The same candidates, one ``kabsch`` call each and no pruning: the plain per-candidate
    loop the benchmark times against and the tests compare with. (``GridSearch`` skips the
    exact score of windows whose radius-of-gyration bound already reaches their gate.)
``IndexSearch`` (the default, fast)
    A rigid motion and a change of time scale leave the arc-length shape of a piece
    unchanged, so the library is indexed once (:class:`ArcIndex`) by resampling every
    primitive at uniform arc length, a pyramid of steps Δ₀·2ʲ. A query of arc length ℓ is
    resampled at the spacing Δ that gives it 16–31 points; the candidates are the windows
    of that spacing starting at every point of the next finer level (dilated windows), so
    no duration grid is needed: a window's duration follows from its arc length (the
    time-scale dimension collapses), filtered to the time-scale range. Each window is scored
    by the Kabsch RMSD of its arc samples combined with ℓ times the RMS difference of the
    normalised time at the samples (the speed profile), and windows are scored best-first
    in order of provable lower bounds of that RMSD — a half-window bound on every window
    (radii of gyration of both halves and the rigid distance between their centroids) and
    the principal-value bound Σ(s_i(P) − s_i(Q))²/K (von Neumann's trace inequality) on
    the survivors, both from strided prefix sums of the coordinates and their products
    (:meth:`ArcIndex.sums`, no window gathered; the bounds are lowered by a proven
    round-off margin), exact float64 scores only for what passes — until no unscored
    window's bound is below the pool's threshold or the gate 3ε + Δ_b/2 on the shape RMSD
    (Δ_b the finer level's step; a stored copy starts within Δ_b/2 of a window). The pool
    holds the best 2·seeds windows and every other window within √2·gate of the best (at
    most ``pool_cap``): near-duplicate primitives that differ only in speed profile tie on
    the window grid, so the pool keeps all of them. The pool is re-scored at sub-step
    shifts of its windows' starts (a copy is then within Δ_b/8 of a shift); the best
    ``seeds`` distinct windows, and every other one within √2·(3ε + Δ_b/8) of the best,
    become the seeds, which the exact check decides between.

    The gate is a heuristic, not a theorem: a copy within ε in uniform time can have a
    longer arc than ε allows for when the path wiggles fast (tests/test_match_heuristics.py:
    a period of 3 samples at RMS 0.7ε breaks it; 4 samples does not). ``prune=False``
    (``search="scan"``) scores every window instead: the same seeds, which the benchmark
    checks on 1,000 primitives; it also checks the segmentation against ``GridSearch`` on
    100. (``GridSearch`` itself keeps only its best few seeds: on the near-duplicates it
    cuts more segments than the index search.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match._bank import BankArrays, cubic_at, linear_at
from primlib.match._kabsch import kabsch, rmsd_from_moments, rotation_for

__all__ = [
    "SearchOptions",
    "Candidate",
    "PathPiece",
    "GridSearch",
    "LoopSearch",
    "IndexSearch",
    "ArcIndex",
    "refine",
    "clamp",
    "piece_rmsd",
]


@dataclass(frozen=True)
class SearchOptions:
    """Knobs of the search, all documented in the module notes.

    Attributes
    ----------
    mode : {"full", "z", "none"}
        Rotation family.
    time_scale : (float, float)
        Allowed primitive duration / segment duration.
    grid_points : int
        K of the reference grid.
    scale_ratio : float
        Largest ratio between neighbouring time scales of the reference grid.
    seeds : int
        Seeds refined per query (distinct basins, best first).
    refine_points : int
        Uniform-time points used by the continuous refinement.
    """

    mode: str = "full"
    time_scale: tuple[float, float] = (0.25, 4.0)
    grid_points: int = 16
    scale_ratio: float = 1.1
    seeds: int = 3
    refine_points: int = 64


@dataclass(frozen=True)
class Candidate:
    """A piece [x0, x1] (fractional sample indices) of bank primitive ``prim`` (row index)."""

    prim: int
    x0: float
    x1: float
    score: float


@dataclass(frozen=True)
class PathPiece:
    """The new path as uniform-time samples; pieces are addressed by normalised time."""

    points: np.ndarray
    duration: float

    @property
    def n(self) -> int:
        return self.points.shape[0]

    def at(self, v: np.ndarray) -> np.ndarray:
        n = self.n
        return cubic_at(self.points, 0, n, np.asarray(v, dtype=float) * (n - 1))

    def confirm_points(self, a: float, b: float) -> int:
        """Points of the check: one per path sample in [a, b] (cuts lie on samples), ≥ 16."""
        return int(max(round((b - a) * (self.n - 1)) + 1, 16))


def _prim_at(bank: BankArrays, i: int, x: np.ndarray) -> np.ndarray:
    return cubic_at(bank.points, bank.offsets[i], bank.offsets[i + 1] - bank.offsets[i], x)


def piece_rmsd(
    bank: BankArrays, cand: Candidate, path: PathPiece, a: float, b: float, k: int, mode: str
):
    """Kabsch superposition of the candidate onto the path piece, both at k uniform times."""
    p = _prim_at(bank, cand.prim, np.linspace(cand.x0, cand.x1, k))
    q = path.at(np.linspace(a, b, k))
    return kabsch(p, q, mode=mode)


def _qp2(h: np.ndarray, g: np.ndarray, z: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Minimise ½δᵀHδ − gᵀδ subject to A(z + δ) ≤ b, for 2 unknowns (H positive definite).

    Convex, so the optimum is the unconstrained minimiser, the minimiser on one constraint
    line, or a vertex of two: try them all and keep the best feasible one.
    """
    slack = b - a @ z
    tol = 1e-9 * (1.0 + np.abs(b))
    free = np.linalg.solve(h, g)
    if np.all(a @ free <= slack + tol):
        return free  # the usual case: no constraint active
    cands = [free]
    for i in range(len(b)):
        ai = a[i]
        # on the line ai·δ = slack_i: δ = δ_p + t·n, n ⟂ ai
        nrm = ai @ ai
        dp = ai * slack[i] / nrm
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


def refine(
    bank: BankArrays,
    cand: Candidate,
    path: PathPiece,
    a: float,
    b: float,
    opts: SearchOptions,
    target: float = 0.0,
) -> Candidate:
    """Continuous refinement of a seed's start and end, bounded to the time-scale range.

    Variable projection with damped Gauss–Newton: the residual r_j = q̃_j − R p̃(x0 + (x1 −
    x0) s_j) (s_j uniform in [0, 1], tildes = centred) is linearised in (x0, x1) with the
    Kabsch R of the current iterate held fixed — by the envelope theorem this is the
    gradient of the reduced cost min_R Σ|r_j|² — and the derivative of the stored curve
    comes from its cubic interpolant. Each step solves the linearised problem exactly under
    0 ≤ x0, x1 ≤ n − 1 and the time-scale range lo ≤ x1 − x0 ≤ hi (:func:`_qp2`), and is
    accepted only when the cost decreases (Levenberg damping otherwise). Stops at
    convergence (60 evaluations at most) or as soon as the RMSD at the refinement points
    is below ``target``.
    """
    off = int(bank.offsets[cand.prim])
    n_p = int(bank.offsets[cand.prim + 1]) - off
    dq = (b - a) * path.duration / bank.dt
    lo = max(opts.time_scale[0] * dq, 1e-6)
    hi = min(opts.time_scale[1] * dq, n_p - 1.0)
    if hi < lo:
        return cand
    k = opts.refine_points
    q = path.at(np.linspace(a, b, k))
    qc = q - q.mean(axis=0)
    s = np.linspace(0.0, 1.0, k)
    # A z <= c for z = (x0, x1)
    amat = np.array([[-1.0, 0.0], [0.0, 1.0], [1.0, -1.0], [-1.0, 1.0]])
    cvec = np.array([0.0, n_p - 1.0, -lo, hi])
    own = bank.points[off : off + n_p]
    full = opts.mode == "full"
    fix = np.ones(qc.shape[1])

    def evaluate(z: np.ndarray):
        p, dp = cubic_at(own, 0, n_p, z[0] + (z[1] - z[0]) * s, derivative=True)
        pc = p - p.mean(axis=0)
        h = pc.T @ qc
        if full:
            # any optimal rotation gives the same residual, so no canonical choice needed
            u, _, vt = np.linalg.svd(h)
            fix[-1] = 1.0 if np.linalg.det(u @ vt) > 0 else -1.0
            r = (vt.T * fix) @ u.T
        else:
            r = rotation_for(h, opts.mode)
        res = qc - pc @ r.T
        return float(np.sum(res * res)), res, dp @ r.T

    c0 = clamp(bank, cand, (b - a) * path.duration, opts)
    z = np.array([c0.x0, c0.x1])
    cost, res, dpr = evaluate(z)
    stop = target * target * k
    lam = 0.0
    budget = 60  # evaluations
    while budget > 0 and cost >= stop:
        j1 = dpr * s[:, None]  # ∂(R p_j)/∂x1
        j0 = dpr - j1  # ∂(R p_j)/∂x0
        jac = np.stack([(j0 - j0.mean(axis=0)).ravel(), (j1 - j1.mean(axis=0)).ravel()], 1)
        jtj = jac.T @ jac
        g = jac.T @ res.ravel()
        improved = False
        while budget > 0:
            h = jtj + (lam + 1e-12) * np.diag(np.diag(jtj) + 1e-12)
            step = _qp2(h, g, z, amat, cvec)
            if not np.any(step):
                break
            nz = z + step
            ncost, nres, ndpr = evaluate(nz)
            budget -= 1
            if ncost < cost:
                moved = float(np.abs(step).sum())
                gain = cost - ncost
                z, cost, res, dpr = nz, ncost, nres, ndpr
                lam = lam / 10.0 if lam > 1e-6 else 0.0
                improved = True
                break
            lam = max(lam * 10.0, 1e-4)
            if lam > 1e8:
                break
        if not improved or moved < 1e-6 or gain < 1e-12 * cost:
            break
    return Candidate(cand.prim, float(z[0]), float(z[1]), cand.score)


def clamp(bank: BankArrays, cand: Candidate, duration: float, opts: SearchOptions) -> Candidate:
    """The candidate with its duration clipped to the time-scale range (for a query lasting
    ``duration`` s) and its start moved so it stays inside the primitive."""
    n_p = int(bank.offsets[cand.prim + 1] - bank.offsets[cand.prim])
    dq = duration / bank.dt
    lo = max(opts.time_scale[0] * dq, 1e-6)
    hi = min(opts.time_scale[1] * dq, n_p - 1.0)
    dur = min(max(cand.x1 - cand.x0, lo), hi)
    x0 = min(max(cand.x0, 0.0), n_p - 1.0 - dur)
    return Candidate(cand.prim, x0, x0 + dur, cand.score)


def _sym_eigvals(a: np.ndarray) -> np.ndarray:
    """Eigenvalues, descending, of symmetric (m, d, d) matrices, d in {2, 3}, in closed form
    (the trigonometric solution of the characteristic cubic for d = 3)."""
    if a.shape[-1] == 2:
        mid = 0.5 * (a[:, 0, 0] + a[:, 1, 1])
        rad = np.hypot(0.5 * (a[:, 0, 0] - a[:, 1, 1]), a[:, 0, 1])
        return np.stack([mid + rad, mid - rad], axis=1)
    q = (a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2]) / 3.0
    p1 = a[:, 0, 1] ** 2 + a[:, 0, 2] ** 2 + a[:, 1, 2] ** 2
    p2 = (a[:, 0, 0] - q) ** 2 + (a[:, 1, 1] - q) ** 2 + (a[:, 2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    safe = np.where(p > 0, p, 1.0)
    b = (a - q[:, None, None] * np.eye(3)) / safe[:, None, None]
    det = (
        b[:, 0, 0] * (b[:, 1, 1] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 1])
        - b[:, 0, 1] * (b[:, 1, 0] * b[:, 2, 2] - b[:, 1, 2] * b[:, 2, 0])
        + b[:, 0, 2] * (b[:, 1, 0] * b[:, 2, 1] - b[:, 1, 1] * b[:, 2, 0])
    )
    phi = np.arccos(np.clip(det / 2.0, -1.0, 1.0)) / 3.0
    l1 = q + 2.0 * p * np.cos(phi)
    l3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 * q - l1 - l3
    return np.stack([l1, l2, l3], axis=1)


def _scale_grid(lo: float, hi: float, ratio: float) -> np.ndarray:
    n = 1 + max(1, math.ceil(math.log(hi / lo) / math.log(ratio) - 1e-9)) if hi > lo else 1
    return np.geomspace(lo, hi, n) if n > 1 else np.array([lo])


def _suppress(cands: list[Candidate], m: int) -> list[Candidate]:
    """Greedy non-maximum suppression: one seed per basin (overlap > half the shorter)."""
    out: list[Candidate] = []
    for c in sorted(cands, key=lambda c: c.score):
        same = False
        for o in out:
            if o.prim == c.prim:
                ov = min(o.x1, c.x1) - max(o.x0, c.x0)
                if ov > 0.5 * min(o.x1 - o.x0, c.x1 - c.x0):
                    same = True
                    break
        if not same:
            out.append(c)
            if len(out) == m:
                break
    return out


def _window_moments(cs: np.ndarray, cs2: np.ndarray, starts: np.ndarray, k: int, per_axis: bool):
    """Σ|p − p̄|² of the windows [m, m + k) from cumulative sums (per axis if asked)."""
    sx = cs[starts + k] - cs[starts]
    sxx = cs2[starts + k] - cs2[starts]
    sp = sxx - sx * sx / k
    return sp if per_axis else sp.sum(axis=1)


def _cumsums(x: np.ndarray):
    cs = np.zeros((x.shape[0] + 1, x.shape[1]))
    np.cumsum(x, axis=0, out=cs[1:])
    cs2 = np.zeros_like(cs)
    np.cumsum(x * x, axis=0, out=cs2[1:])
    return cs, cs2


@dataclass
class _Stats:
    windows: int = 0  # candidates considered
    bounded: int = 0  # candidates past the cheap first bound (index search)
    scored: int = 0  # candidates scored exactly
    queries: int = 0


@dataclass
class GridSearch:
    """Exhaustive search on the documented (start, time scale) grid, vectorised."""

    bank: BankArrays
    opts: SearchOptions
    stats: _Stats = field(default_factory=_Stats)
    _vmax: np.ndarray | None = None

    def _query(self, path: PathPiece, a: float, b: float):
        k = self.opts.grid_points
        q = path.at(np.linspace(a, b, k))
        qc = q - q.mean(axis=0)
        return q, qc

    def _windows(self, path: PathPiece, a: float, b: float):
        """Yield, per time scale, the resampled bank and its valid windows."""
        bank, k = self.bank, self.opts.grid_points
        dq = (b - a) * path.duration / bank.dt
        counts = bank.counts
        for scale in _scale_grid(*self.opts.time_scale, self.opts.scale_ratio):
            dur = scale * dq
            h = dur / (k - 1)
            ok = np.flatnonzero(counts - 1 >= dur - 1e-9)
            if ok.size == 0 or h <= 0:
                continue
            n_start = np.floor((counts[ok] - 1 - dur) / h + 1e-9).astype(np.int64) + 1
            n_res = n_start + k - 1
            base = np.concatenate([[0], np.cumsum(n_res)])
            prim = np.repeat(ok, n_res)
            local = np.arange(base[-1]) - np.repeat(base[:-1], n_res)
            res = cubic_at(bank.points, bank.offsets[prim], counts[prim], local * h)
            first = np.concatenate([[0], np.cumsum(n_start)])
            s_local = np.arange(first[-1]) - np.repeat(first[:-1], n_start)
            starts = np.repeat(base[:-1], n_start) + s_local
            s_prim = np.repeat(ok, n_start)
            yield res, starts, s_prim, s_local * h, dur

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Best distinct grid candidates that a continuous move within their cell could
        bring below eps (Lipschitz gate, see :meth:`_slack`), best first."""
        k, mode = self.opts.grid_points, self.opts.mode
        q, qc = self._query(path, a, b)
        sq = (qc * qc).sum(axis=0) if mode == "z" else float((qc * qc).sum())
        pool: list[Candidate] = []
        self.stats.queries += 1
        for res, starts, s_prim, x0, dur in self._windows(path, a, b):
            gate = eps + self._slack(s_prim, dur, k)
            rmsd = self._score(res, starts, q, qc, sq, k, mode, gate)
            self.stats.windows += starts.size
            ok = np.flatnonzero(rmsd < gate)
            top = ok[np.argsort(rmsd[ok])[: 8 * self.opts.seeds]]
            pool += [
                Candidate(int(s_prim[t]), float(x0[t]), float(x0[t] + dur), float(rmsd[t]))
                for t in top
            ]
        return _suppress(pool, self.opts.seeds)

    def _slack(self, prim: np.ndarray, dur: float, k: int) -> np.ndarray:
        """Bound on how much the RMSD can drop inside a grid cell.

        Moving the start by up to h/2 and the duration to a neighbouring scale (factor
        √ratio) moves each of the K points by at most h/2 + D(√ratio − 1) samples, i.e. by
        at most that times the largest step between samples (×1.25 for the cubic
        interpolation's overshoot); the RMSD against a fixed query is 1-Lipschitz in the
        RMS point displacement.
        """
        if self._vmax is None:
            step = np.linalg.norm(np.diff(self.bank.points, axis=0), axis=1)
            step[self.bank.offsets[1:-1] - 1] = 0.0
            self._vmax = np.maximum.reduceat(np.append(step, 0.0), self.bank.offsets[:-1])
        cell = dur / (k - 1) / 2.0 + dur * (math.sqrt(self.opts.scale_ratio) - 1.0)
        return 1.25 * self._vmax[prim] * cell

    def _score(self, res, starts, q, qc, sq, k, mode, gate) -> np.ndarray:
        """RMSD of every window that can pass ``gate``; +inf for the others, which the
        radius-of-gyration bound |g(P) − g(Q)| ≤ rmsd proves to be at or above it."""
        # centre per window via cumulative sums; the cross term needs no centring (Σ q̃ = 0)
        res_c = res - res.mean(axis=0)
        cs, cs2 = _cumsums(res_c)
        per_axis = mode == "z"
        sp = _window_moments(cs, cs2, starts, k, per_axis=per_axis)
        tot = sp.sum(axis=1) if per_axis else sp
        g_q = math.sqrt(float(np.sum(sq)) / k)
        live = np.flatnonzero(np.abs(np.sqrt(np.maximum(tot, 0.0) / k) - g_q) < gate)
        out = np.full(starts.size, np.inf)
        self.stats.scored += live.size
        if live.size:
            win = sliding_window_view(res_c, k, axis=0)[starts[live]]  # (m, d, k)
            s = np.einsum("mak,kb->mab", win, qc, optimize=True)
            sp_l = sp[live]
            out[live] = rmsd_from_moments(s, sp_l, np.broadcast_to(sq, sp_l.shape), k, mode)
        return out


@dataclass
class LoopSearch(GridSearch):
    """The same grid as :class:`GridSearch`, one Kabsch call per candidate (reference)."""

    def _score(self, res, starts, q, qc, sq, k, mode, gate) -> np.ndarray:
        self.stats.scored += starts.size
        return np.array([kabsch(res[m : m + k], q, mode=mode).rmsd for m in starts])


@dataclass(frozen=True)
class _Level:
    step: float
    pts: np.ndarray  # (M, d) centred per primitive
    prim: np.ndarray  # (M,)
    x: np.ndarray  # (M,) fractional sample index in the primitive
    garc: np.ndarray  # (M,) global arc coordinate (primitive arcs laid end to end)
    left: np.ndarray  # (M,) arc length from this point to the primitive's end


@dataclass(frozen=True)
class ArcIndex:
    """The library resampled at uniform arc length, a pyramid of steps ``step0 · 2ʲ``.

    Built once per bank (:meth:`build`); rigid motions and time scaling leave every
    primitive's arc-length shape unchanged, so one index serves every query.
    """

    step0: float
    levels: tuple[_Level, ...]
    x_all: np.ndarray  # sample index of every stored sample, for arc -> time
    garc_all: np.ndarray  # global arc coordinate of every stored sample
    cache: dict = field(default_factory=dict, compare=False, repr=False)

    def arc_to_sample(self, g: np.ndarray) -> np.ndarray:
        """Fractional sample index at global arc coordinates g (linear between samples)."""
        i = np.clip(np.searchsorted(self.garc_all, g) - 1, 0, self.garc_all.size - 2)
        g0, g1 = self.garc_all[i], self.garc_all[i + 1]
        f = np.clip((g - g0) / np.where(g1 > g0, g1 - g0, 1.0), 0.0, 1.0)
        return self.x_all[i] + f * (self.x_all[i + 1] - self.x_all[i])

    def sums(self, jb: int, dil: int) -> tuple[np.ndarray, np.ndarray, float]:
        """Strided prefix sums of level jb for the windows {m + i·dil, i < n}, m = 0, 1, ...

        Rows: the d coordinates, |p|², then the products p_a·p_b (a ≤ b), so the sums, the
        centroid, the radius of gyration and the scatter matrix of any window come from two
        columns: Σ_{i<n} f(p_{m+i·dil}) = P[:, m + n·dil] − P[:, m] (P[:, m] sums the
        earlier points of m's phase m mod dil). Built once per (level, dilation).

        Round-off: P is a running sum, P_{j+dil} = fl(P_j + f_j), so the difference of two
        entries n steps apart carries only the n roundings between them:
        |error| ≤ (n + 2)·u·max|P| (u = 2⁻⁵³), which ``seeds`` adds to its bounds.

        Returns
        -------
        P : array, shape (c, L)
            c = d + 1 + d(d + 1)/2 rows, L = (⌈M/dil⌉ + 1)·dil columns.
        pmax : array, shape (c,)
            max |P| per row.
        radius : float
            max |p| over the level's points.
        """
        key = ("s", jb, dil)
        hit = self.cache.get(key)
        if hit is not None:
            return hit
        pts = self.levels[jb].pts
        m, d = pts.shape
        rows = -(-m // dil)
        pairs = [(a, b) for a in range(d) for b in range(a, d)]
        buf = np.zeros((d + 1 + len(pairs), rows + 1, dil))
        flat = buf.reshape(buf.shape[0], -1)
        flat[:d, dil : dil + m] = pts.T
        for i, (a, b) in enumerate(pairs):
            np.multiply(pts[:, a], pts[:, b], out=flat[d + 1 + i, dil : dil + m])
        diag = [d + 1 + i for i, (a, b) in enumerate(pairs) if a == b]
        np.sum(flat[diag, dil : dil + m], axis=0, out=flat[d, dil : dil + m])
        radius = math.sqrt(float(flat[d].max()))
        np.cumsum(buf, axis=1, out=buf)
        out = (flat, np.maximum(flat.max(axis=1), -flat.min(axis=1)), radius)
        self.cache[key] = out
        return out

    @classmethod
    def build(cls, bank: BankArrays, points_per_sample: float = 0.25) -> ArcIndex:
        # one pass per step over the flat buffer (offsets mark the primitives), no loop over
        # primitives; each level is taken from the one below it (half the points)
        pts = bank.points
        counts = bank.counts
        k = bank.k
        seg = np.empty(pts.shape[0] - 1)
        for c0 in range(0, seg.size, 1 << 16):  # chunks: no (N, d) temporary
            c1 = min(c0 + (1 << 16), seg.size)
            dif = pts[c0 + 1 : c1 + 1] - pts[c0:c1]
            np.sqrt(np.einsum("ij,ij->i", dif, dif), out=seg[c0:c1])
        # no arc across primitive boundaries
        seg[bank.offsets[1:-1] - 1] = 0.0
        cum = np.empty(pts.shape[0])
        cum[0] = 0.0
        np.cumsum(seg, out=cum[1:])
        del seg
        starts_arc = cum[bank.offsets[:-1]]
        length = cum[bank.offsets[1:] - 1] - starts_arc
        total = float(length.sum())
        step0 = max(total / max(points_per_sample * pts.shape[0], 1.0), 1e-300)
        if total <= 0:
            step0 = 1.0
        n_lv0 = np.floor(length / step0 + 1e-9).astype(np.int64) + 1
        prim = np.repeat(np.arange(k), n_lv0)
        base = np.concatenate([[0], np.cumsum(n_lv0)])
        local = np.arange(base[-1]) - base[:-1][prim]
        arc_local = local * step0
        # arc -> sample index per primitive: one interp on a globally monotone arc axis
        gap = np.arange(k) * (step0 * 4.0)  # separates primitives on the global axis
        g_samples = np.repeat(gap, counts)
        g_samples += cum
        g_samples += np.arange(g_samples.size) * (1e-12 * max(step0, 1.0))
        sample_idx = np.arange(pts.shape[0], dtype=float)
        sample_idx -= np.repeat(bank.offsets[:-1].astype(float), counts)
        garc = arc_local + (starts_arc + gap)[prim]
        x = np.interp(garc, g_samples, sample_idx)
        np.minimum(x, (counts - 1.0)[prim], out=x)
        p = linear_at(pts, bank.offsets[prim], counts[prim], x)
        cent = np.add.reduceat(p, base[:-1], axis=0) / n_lv0[:, None]
        p -= cent[prim]
        left = length[prim] - arc_local
        levels = []
        lv = 0
        longest = float(length.max())
        while True:
            levels.append(_Level(step0 * (1 << lv), p, prim, x, garc, left))
            if p.shape[0] <= 2 * k or (1 << lv) * step0 * 16 > longest:
                break
            sel = np.flatnonzero((local & 1) == 0)
            p, prim, x, garc, left = p[sel], prim[sel], x[sel], garc[sel], left[sel]
            local = local[sel] >> 1
            lv += 1
        return cls(step0, tuple(levels), sample_idx, g_samples)


@dataclass
class IndexSearch:
    """Seeds from the arc-length index with provable lower-bound pruning (see module notes)."""

    bank: BankArrays
    opts: SearchOptions
    index: ArcIndex | None = None
    target_points: int = 16
    phase_bits: int = 1
    pool: int = 2
    pool_cap: int = 48
    chunk: int = 8192
    prune: bool = True
    stats: _Stats = field(default_factory=_Stats)

    def __post_init__(self) -> None:
        if self.index is None:
            self.index = ArcIndex.build(self.bank)
        self._grid = GridSearch(self.bank, self.opts, self.stats)
        self._fine: dict[int, ArcIndex] = {}

    def _index_for(self, ell: float) -> ArcIndex:
        """The index, or a finer one (built once, on demand) for pieces short in arc length.

        Finer by 2ʲ so the piece gets ~16 arc samples, capped at 4 million indexed points.
        """
        idx = self.index
        need = (self.target_points - 1) * idx.step0 / max(ell, 1e-300)
        if need <= 1.0:
            return idx
        n0 = idx.levels[0].pts.shape[0]
        j = min(math.ceil(math.log2(need)), int(math.log2(max(4e6 / max(n0, 1), 1.0))))
        if j <= 0:
            return idx
        if j not in self._fine:
            pps = n0 / max(self.bank.points.shape[0], 1)
            self._fine[j] = ArcIndex.build(self.bank, points_per_sample=pps * 2**j)
        return self._fine[j]

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Best distinct arc-window candidates below the gate 3·eps + Δ, best first.

        The score is the Kabsch RMSD of the arc samples combined (root sum of squares) with
        ℓ times the RMS difference of the normalised time at the arc samples (the speed
        profile). A stored copy of the query starts within Δ/2 of arc length of some window
        start, which moves each arc sample by at most Δ/2 in space and in ℓ·τ: its window
        scores below √2·Δ/2 plus the copy's own deviation (a few eps at most for a match
        within eps).
        """
        n_dense = max(64, int(round((b - a) * (path.n - 1))) * 2 + 1)
        dense = path.at(np.linspace(a, b, n_dense))
        chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        ell = float(chord[-1])
        idx = self._index_for(ell)
        if ell < 3.0 * idx.step0:
            # a (nearly) stationary or very short piece: arc length cannot place it
            return self._grid.seeds(path, a, b, eps)
        # spacing Δ_j gives target..2·target arc samples; window starts on the finer level
        # j − phase_bits (windows then take every dil-th point), so a stored copy starts
        # within Δ_j / (2·dil) of some window
        top = len(idx.levels) - 1
        j = int(np.clip(np.floor(np.log2(ell / (idx.step0 * (self.target_points - 1)))), 0, top))
        jb = max(j - self.phase_bits, 0)
        lv = idx.levels[jb]
        dil = 1 << (j - jb)
        step = lv.step * dil
        k = int(np.floor(ell / step + 1e-9)) + 1
        s = np.arange(k) * step
        t_dense = np.linspace(0.0, 1.0, n_dense)
        u = np.interp(s, chord + np.arange(n_dense) * 1e-15 * max(ell, 1.0), t_dense)
        q = path.at(a + (b - a) * u)
        qc = q - q.mean(axis=0)
        mode = self.opts.mode
        per_axis = mode == "z"
        sq = (qc * qc).sum(axis=0) if per_axis else float((qc * qc).sum())
        g_q = math.sqrt(float(np.sum(sq)) / k)
        # candidate windows: in one primitive, long enough, time scale in range
        span = (k - 1) * dil + 1
        m_all = lv.pts.shape[0] - span + 1
        if m_all <= 0:
            return []
        m = self.opts.seeds
        # a stored copy starts within half a base step of some window start, which moves
        # every arc sample by at most that: its window's shape RMSD is below the gate
        gate = 3.0 * eps + 0.5 * lv.step * (1.0 + 1e-6)
        # bound 1, every window, from cumulative sums: split P and Q into halves (k1, k2
        # points). Under the optimal motion the error energy K·rmsd² splits into each half's
        # centroid error (k_h δ_h²) and its centred part (≥ k_h (g_h(P) − g_h(Q))², the
        # radius-of-gyration bound, Cauchy–Schwarz on eq. (2)); the distance D between the
        # half centroids is rigid, so δ1 + δ2 ≥ |D(P) − D(Q)| and min k1δ1² + k2δ2² =
        # k1k2/K·ΔD². Hence rmsd² ≥ (k1k2/K·ΔD² + Σ_h k_h Δg_h²)/K.
        k1 = k // 2
        k2 = k - k1
        d = qc.shape[1]
        psum, pmax, radius = idx.sums(jb, dil)
        u_ = 2.0**-53
        # round-off of window sums of n ≤ k terms (see ArcIndex.sums), propagated: centroid
        # coordinates, energies Σ|p − p̄|² (the subtraction |S|²/k included), and the
        # bound by the triangle inequality on its weighted norm
        err_c = (k + 2) * u_ * float(pmax[:d].max())
        err_e = (k + 2) * u_ * float(pmax[d]) + 2 * math.sqrt(d) * radius * err_c
        err_e += d * err_c * err_c + 8 * u_ * k * radius * radius
        err_d = math.sqrt(d) * err_c * (1.0 / k1 + 1.0 / k2)
        margin1 = math.sqrt((k1 * k2 / k * err_d * err_d + 2.0 * err_e) / k)
        qh1, qh2 = qc[:k1], qc[k1:]
        dq_ = float(np.linalg.norm(qh1.mean(axis=0) - qh2.mean(axis=0)))
        gq1 = math.sqrt(float(np.sum((qh1 - qh1.mean(axis=0)) ** 2)) / k1)
        gq2 = math.sqrt(float(np.sum((qh2 - qh2.mean(axis=0)) ** 2)) / k2)
        # the two halves' sums for every window: contiguous slices, no gathering, in
        # cache-sized blocks of windows (2-3x faster than whole-array passes)
        lb1 = np.empty(m_all)
        for c0 in range(0, m_all, 1 << 14):
            c1 = min(c0 + (1 << 14), m_all)
            p0 = psum[: d + 1, c0:c1]
            p1 = psum[: d + 1, c0 + k1 * dil : c1 + k1 * dil]
            s1 = p1 - p0
            s2 = psum[: d + 1, c0 + k * dil : c1 + k * dil] - p1
            dd = s1[:d] * (1.0 / k1) - s2[:d] * (1.0 / k2)  # c1 − c2
            dd = np.sqrt(np.einsum("ij,ij->j", dd, dd))
            dd -= dq_
            e1 = s1[d] - np.einsum("ij,ij->j", s1[:d], s1[:d]) * (1.0 / k1)
            e2 = s2[d] - np.einsum("ij,ij->j", s2[:d], s2[:d]) * (1.0 / k2)
            np.maximum(e1, 0.0, out=e1)
            np.maximum(e2, 0.0, out=e2)
            dg1 = np.sqrt(e1 * (1.0 / k1))
            dg1 -= gq1
            dg2 = np.sqrt(e2 * (1.0 / k2))
            dg2 -= gq2
            dd *= dd
            dd *= k1 * k2 / k / k
            dg1 *= dg1
            dg1 *= k1 / k
            dg2 *= dg2
            dg2 *= k2 / k
            dd += dg1
            dd += dg2
            out = np.sqrt(dd, out=lb1[c0:c1])
            out -= margin1 + 1e-12 * (g_q + out)
        if not self.prune:
            lb1 = np.zeros_like(lb1)  # the exhaustive scan: every window gets scored
        # chord lengths under-estimate arc length a little (more for the stored samples than
        # for the densely sampled query): let a piece reach a primitive's very end
        valid = lv.left[:m_all] >= ell - max(step, 0.02 * ell)
        self.stats.queries += 1
        self.stats.windows += int(np.count_nonzero(valid))
        w = np.flatnonzero(valid & (lb1 < gate * (1 + 1e-9)))
        self.stats.bounded += w.size
        if w.size == 0:
            return []
        scat_q = (qc.T @ qc)[None]
        sv_q = np.sqrt(np.maximum(_sym_eigvals(scat_q), 0.0))[0]
        pairs = [(i, j) for i in range(d) for j in range(i, d)]
        # closed-form eigenvalues: acos near ±1 and the rest cost at most 1e-7·trace
        err_q = math.sqrt(d * 1e-7 * float(np.trace(scat_q[0])) / k)
        err_pp = (k + 2) * u_ * float(pmax[d + 1 :].max())
        err_m = d * (err_pp + 2 * radius * err_c + err_c * err_c / k)  # ‖E‖_F of a scatter

        win_view = sliding_window_view(lv.pts, span, axis=0)[:, :, ::dil]

        def bound2(sel: np.ndarray):
            # the principal values of the windows' scatter matrices, from the prefix sums.
            # von Neumann: tr(R P̃ᵀQ̃) ≤ Σ s_i(P̃) s_i(Q̃) for any orthogonal R, so rmsd² ≥
            # Σ (s_i(P̃) − s_i(Q̃))² / K in every rotation mode. Round-off: Weyl moves each
            # eigenvalue by ≤ ‖E‖ (+ the closed form's 1e-7·trace), |√a − √b| ≤ √|a − b|
            ws = w[sel]
            s = psum[:, ws + k * dil] - psum[:, ws]  # (c, m)
            scat = np.empty((ws.size, d, d))
            for i, (a_, b_) in enumerate(pairs):
                v = s[d + 1 + i] - s[a_] * s[b_] * (1.0 / k)
                scat[:, a_, b_] = v
                scat[:, b_, a_] = v
            sv_p = np.sqrt(np.maximum(_sym_eigvals(scat), 0.0))
            tr = np.maximum(s[d] - np.einsum("ij,ij->j", s[:d], s[:d]) * (1.0 / k), 0.0)
            lb = np.sqrt(np.sum((sv_p - sv_q) ** 2, axis=1) / k)
            lb -= np.sqrt(d * (err_m + 1e-7 * tr) / k) + err_q + 1e-12 * (g_q + lb)
            if not self.prune:
                lb = np.zeros_like(lb)
            return lb

        dq = (b - a) * path.duration / self.bank.dt
        lo, hi = self.opts.time_scale

        def in_range(sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            # the window's duration follows from its arc length; keep the time scales in
            # range (10 % slack: the refinement enforces the range exactly). The end lies
            # ell / step level points on, in the same primitive unless near its end.
            ws = w[sel]
            e = ws + ell / lv.step
            i0 = np.minimum(np.floor(e).astype(np.int64), lv.pts.shape[0] - 2)
            f = e - i0
            inside = lv.prim[np.minimum(i0 + 1, lv.pts.shape[0] - 1)] == lv.prim[ws]
            x_end = lv.x[i0] + f * (lv.x[i0 + 1] - lv.x[i0])
            if not np.all(inside):
                x_end[~inside] = idx.arc_to_sample(lv.garc[ws[~inside]] + ell)
            scale = (x_end - lv.x[ws]) / dq
            ok = (scale >= lo / 1.1) & (scale <= hi * 1.1)
            return sel[ok], x_end[ok]

        # the speed profile: normalised time at each arc sample, query and windows
        tau_q = (u - u[0]) / max(u[-1] - u[0], 1e-300)
        x_view = sliding_window_view(lv.x, span)[:, ::dil]

        def combine(shape: np.ndarray, xw: np.ndarray) -> np.ndarray:
            # a normalised-time error δτ at an arc sample moves the uniform-time sample by
            # about ℓ·δτ along the curve: add it so pieces of the same shape traversed with
            # another speed profile rank below the right one (never below the shape RMSD,
            # so the lower bounds still hold)
            dur = xw[:, -1] - xw[:, 0]
            still = dur <= 1e-9  # a stationary stretch: no speed profile to compare
            tau_w = (xw - xw[:, :1]) / np.where(still, 1.0, dur)[:, None]
            tau_w[still] = tau_q
            return np.hypot(shape, ell * np.sqrt(np.mean((tau_w - tau_q) ** 2, axis=1)))

        def score(sel: np.ndarray):
            # the exact scores in float64 from the gathered windows (m, d, k): one matrix
            # product for all cross-covariances (Σ q̃ = 0: no window centring)
            win = win_view[w[sel]]
            pc = win - win.mean(axis=2, keepdims=True)
            sp = np.einsum("mak,mak->ma", pc, pc)
            if not per_axis:
                sp = sp.sum(axis=1)
            s_ = (win.reshape(-1, k) @ qc).reshape(sel.size, qc.shape[1], qc.shape[1])
            sq_ = np.broadcast_to(sq, (sel.size, 3)) if per_axis else sq
            shape = rmsd_from_moments(s_, sp, sq_, k, mode)
            return combine(shape, x_view[w[sel]]), shape

        def score_shifted(start: np.ndarray) -> np.ndarray:
            # windows starting at fractional base-level positions (linear interpolation
            # between the arc samples); +inf where a window leaves its primitive
            pos = start[:, None] + np.arange(k) * dil
            i0 = np.clip(np.floor(pos).astype(np.int64), 0, lv.pts.shape[0] - 2)
            f = np.clip(pos - i0, 0.0, 1.0)
            ok = (start >= 0) & (lv.prim[i0[:, 0]] == lv.prim[i0[:, -1] + 1])
            pts = lv.pts[i0] * (1.0 - f[..., None]) + lv.pts[i0 + 1] * f[..., None]
            pc = pts - pts.mean(axis=1, keepdims=True)
            s_ = np.einsum("mka,kb->mab", pc, qc)
            sp_ = (pc * pc).sum(axis=1) if per_axis else (pc * pc).sum(axis=(1, 2))
            sq_ = np.broadcast_to(sq, (start.size, 3)) if per_axis else sq
            xw = lv.x[i0] * (1.0 - f) + lv.x[i0 + 1] * f
            r = combine(rmsd_from_moments(s_, sp_, sq_, k, mode), xw)
            return np.where(ok, r, np.inf), xw[:, 0]

        # best first: windows in increasing order of bound 1, bound 2 on each chunk, exact
        # scores for what passes, until the next bound reaches the pool's worst score (or
        # the gate): the pool is then exactly the best n_pool distinct windows of scoring
        # every window
        n_pool = self.pool * m
        cand = np.arange(w.size)[np.argsort(lb1[w], kind="stable")]
        lbw = lb1[w]
        pool: list[Candidate] = []
        where: dict[tuple[int, float], int] = {}
        tau = gate
        pos = 0
        while pos < cand.size and lbw[cand[pos]] < tau:
            todo = cand[pos : pos + self.chunk]
            todo = todo[lbw[todo] < tau]
            pos += self.chunk
            todo = todo[bound2(todo) < tau]
            todo, x_end = in_range(todo)
            r, shape = score(todo)
            self.stats.scored += todo.size
            ok = np.flatnonzero(shape < gate)
            order = ok[np.argsort(r[ok])[: self.pool_cap]]
            for t in order:
                c = Candidate(int(lv.prim[w[todo[t]]]), float(lv.x[w[todo[t]]]), float(x_end[t]),
                              float(r[t]))  # fmt: skip
                where[(c.prim, c.x0)] = int(w[todo[t]])
                pool.append(c)
            # the best n_pool windows, and every other window within √2·gate of the best
            # (a stored copy scores below √2·gate, so near-duplicates differing only in
            # speed profile tie on the window grid; the sub-step re-scoring below parts
            # them), at most pool_cap: no window at or above tau can enter
            pool = _suppress(pool, self.pool_cap)
            tie = pool[0].score + math.sqrt(2.0) * gate if pool else math.inf
            pool = [c for i, c in enumerate(pool) if i < n_pool or c.score < tie]
            tau = gate
            if len(pool) >= n_pool:
                tau = min(tau, max(pool[n_pool - 1].score, tie))
            if len(pool) == self.pool_cap:
                tau = min(tau, pool[-1].score)
        if not pool:
            return []
        # the window grid puts a stored copy up to half a base step from a window start:
        # re-score the pool at sub-step shifts and keep each window's best
        shifts = np.linspace(-0.5, 0.5, 5)
        base = np.array([where[(c.prim, c.x0)] for c in pool], dtype=float)
        starts = (base[:, None] + shifts).ravel()
        r, x0 = score_shifted(starts)
        r, x0 = r.reshape(len(pool), -1), x0.reshape(len(pool), -1)
        best = np.argmin(r, axis=1)
        rows = np.arange(len(pool))
        g0 = lv.garc[base.astype(np.int64)] + shifts[best] * lv.step
        x_end = idx.arc_to_sample(g0 + ell)
        kept = _suppress(
            [
                Candidate(c.prim, float(x0[i, best[i]]), float(x_end[i]), float(r[i, best[i]]))
                for i, c in zip(rows, pool, strict=True)
                if np.isfinite(r[i, best[i]])
            ],
            self.pool_cap,
        )
        # after the re-scoring a stored copy starts within an eighth of a base step of a
        # shift: it scores below √2·(3·eps + Δ_b/8). Every window within that of the best
        # may be it (near-duplicates differing only in speed profile): all become seeds
        # (at least m), and the exact check decides
        tie = kept[0].score + math.sqrt(2.0) * (3.0 * eps + 0.125 * lv.step) if kept else 0.0
        return [c for i, c in enumerate(kept) if i < m or c.score < tie]
