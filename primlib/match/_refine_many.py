"""The refinement of :mod:`._refine` for several seeds at once (one probe's seeds), in
lockstep: every evaluation gathers and superposes all the seeds still running, and
linearises those whose step was accepted and that go on, in one set of array operations, so
a failing probe costs one refinement's Python overhead instead of one per seed. Each seed
follows exactly the steps :func:`._refine.refine` takes for it alone (same damping, budget
and stopping rules, including giving up on a seed that will not end below ``give_up``);
only round-off differs. With ``first``, every seed stops as soon as one is below
``target`` (a probe only needs one match).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from primlib.match._interp import CurveTable, cubic_rows
from primlib.match._kabsch import _rotation_2d
from primlib.match._options import Candidate, PathPiece, SearchOptions
from primlib.match._refine import (
    _AMAT,
    _BUDGET,
    _GAIN,
    _MOVED,
    clamp_many,
    hopeless,
    slack_tolerance,
)

if TYPE_CHECKING:
    from primlib.match._bank import BankIndex

__all__ = ["refine_many"]


_EYE2, _EYE3 = np.eye(2), np.eye(3)
# running rows up to which a step and its update are taken in Python floats (the same IEEE
# operations as the arrays'; 0: always the arrays, as the tests compare)
_FLOAT_ROWS = 1


class _Residuals:
    """:class:`._refine._Residual` for m seeds: cost (m,), residual (m, d, k), dp/dx and R.

    Pieces are laid out (m, d, k), each coordinate a contiguous run of the k points: what a
    point's weights multiply then broadcasts along it (:func:`._interp.cubic_rows`, or
    :meth:`._interp.CurveTable.rows` when given the table)."""

    def __init__(self, table: CurveTable | None, bank: BankIndex, prim: np.ndarray,
                 q: np.ndarray, rotation: str):  # fmt: skip
        self.table, self.bank, self.prim, self.rotation = table, bank, prim, rotation
        self.start = bank.offsets[prim][:, None]
        self.last = bank.offsets[prim + 1][:, None] - self.start - 1
        self.base = None if table is None else table.bases(prim)
        self.qc = q - q.mean(axis=0)
        self.qt = np.ascontiguousarray(self.qc.T)  # (d, k)
        self.s = np.linspace(0.0, 1.0, q.shape[0])
        self.w = np.stack([1.0 - self.s, self.s], axis=1)  # ∂x/∂(x0, x1) at each point
        self.ww = (self.w[:, :, None] * self.w[:, None, :]).reshape(-1, 4)

    def rotations(self, h: np.ndarray) -> np.ndarray:
        m, d, _ = h.shape
        if self.rotation == "full":
            u, _, vt = np.linalg.svd(h)
            uvt = u @ vt
            # det(U Vᵀ) = ±1 (orthogonal): LU's sign is never in doubt, and one call costs less
            # than cofactors' 17 (5 against 14 µs at 2 seeds)
            proper = np.linalg.det(uvt) > 0
            if proper.all():  # the usual case: R = V Uᵀ = (U Vᵀ)ᵀ, the same sums
                return uvt.transpose(0, 2, 1)
            v = vt.transpose(0, 2, 1).copy()
            v[:, :, -1] *= np.where(proper, 1.0, -1.0)[:, None]
            return v @ u.transpose(0, 2, 1)
        r = np.tile(np.eye(d), (m, 1, 1))
        if self.rotation == "z":
            r[:, :2, :2] = _rotation_2d(h[:, 0, 0] + h[:, 1, 1], h[:, 0, 1] - h[:, 1, 0])
        return r

    def __call__(self, rows: np.ndarray, z: np.ndarray):
        """Cost (m,), residual (m, d, k), and the derivative along the curve and the
        rotation (:meth:`turned` makes R·dp of them: only accepted steps need it)."""
        x = z[:, :1] + (z[:, 1:] - z[:, :1]) * self.s
        if self.table is None:
            p, dp = cubic_rows(self.bank.points, self.start[rows], self.last[rows], x)
        else:  # the same numbers from the coefficients formed once
            p, dp = self.table.rows_from(self.base[rows], self.last[rows], x)
        pc = p - p.sum(axis=2, keepdims=True) / p.shape[2]  # the mean, without its wrapper
        if self.rotation == "none":  # R = I: no product, and no rotation kept
            r, res = np.empty((pc.shape[0], 0, 0)), self.qt - pc
        else:
            r = self.rotations(pc @ self.qc)
            res = self.qt - r @ pc
        return np.einsum("mak,mak->m", res, res), res, dp, r

    def turned(self, dp: np.ndarray, r: np.ndarray) -> np.ndarray:
        """R·dp_j for each row: the derivative of the rotated curve (R held fixed)."""
        return dp if self.rotation == "none" else r @ dp

    def normal_equations(self, res: np.ndarray, dpr: np.ndarray):
        """:meth:`._refine._Residual.normal_equations` for m seeds, from moments: the
        Jacobian's columns are w_c(s_j)·R dp_j, centred; Jᵀr needs no centring (Σ r = 0),
        nor does the rotation coupling B = Σ u × J (Σ u = 0)."""
        m, d, k = res.shape
        mom = dpr @ self.w  # Σ_j w_c(j) R dp_j, (m, d, 2)
        jtj = (np.einsum("mak,mak->mk", dpr, dpr) @ self.ww).reshape(m, 2, 2)
        jtj -= mom.transpose(0, 2, 1) @ mom / k
        g = np.einsum("mak,mak->mk", dpr, res) @ self.w
        red = jtj + 1e-9 * jtj * _EYE2
        if self.rotation == "none":
            return red, g
        u = self.qt - res  # the rotated, centred primitive
        if d == 3 and self.rotation == "full":
            u0, u1, u2 = u[:, 0], u[:, 1], u[:, 2]
            d0, d1, d2 = dpr[:, 0], dpr[:, 1], dpr[:, 2]
            cr = np.empty_like(u)  # u × R dp, written in place (no stack)
            np.multiply(u1, d2, out=cr[:, 0])
            cr[:, 0] -= u2 * d1
            np.multiply(u2, d0, out=cr[:, 1])
            cr[:, 1] -= u0 * d2
            np.multiply(u0, d1, out=cr[:, 2])
            cr[:, 2] -= u1 * d0
            b = (cr @ self.w).transpose(0, 2, 1)  # Σ_j w_c(j) u_j × R dp_j, (m, 2, 3)
            uu = u @ u.transpose(0, 2, 1)
            tr = (uu[:, 0, 0] + uu[:, 1, 1] + uu[:, 2, 2])[:, None, None]
            inertia = (1.0 + 2e-12) * tr * _EYE3 - uu  # + 1e-12 of its trace: never singular
            return red - b @ np.linalg.solve(inertia, b.transpose(0, 2, 1)), g
        b = (u[:, 0] * dpr[:, 1] - u[:, 1] * dpr[:, 0]) @ self.w  # (m, 2)
        inertia = np.einsum("mak,mak->m", u[:, :2], u[:, :2])
        return red - b[:, :, None] * b[:, None, :] / np.maximum(inertia, 1e-300)[:, None, None], g


def refine_many(bank: BankIndex, cands: list[Candidate], path: PathPiece, a: float, b: float,
                opts: SearchOptions, target: float = 0.0, give_up: float = np.inf,
                first: bool = False, points: int | None = None, rtol: float = _GAIN,
                samples: np.ndarray | None = None, table: CurveTable | None = None):  # fmt: skip
    """:func:`._refine.refine` of every candidate, in lockstep (module notes); with
    ``first``, all stop as soon as one is below ``target``; a seed whose step gained less
    than ``rtol`` of its cost has converged. ``samples``: the path at the ``points``
    uniform times of [a, b] when the caller has them (``path.at(np.linspace(a, b, k))``);
    ``table``: the bank's :class:`._interp.CurveTable`, kept across calls by the caller
    (the same numbers as without it, sooner).

    Returns the refined candidates and their Kabsch RMSD at the ``points`` uniform times
    (default ``opts.refine_points``) the refinement ran on, what :func:`._refine.piece_rmsd`
    gives there (inf for a primitive too short for the time-scale range: left as it came).
    """
    dur = (b - a) * path.duration
    out, rmsd = list(cands), np.full(len(cands), np.inf)
    if not cands:
        return out, rmsd
    prim = np.array([c.prim for c in cands])
    z = np.array([[c.x0, c.x1] for c in cands])
    z, lo, hi = clamp_many(bank, prim, z, dur / bank.dt, opts)
    rows = np.flatnonzero(hi >= lo)
    if rows.size == 0:
        return out, rmsd
    if rows.size < len(cands):
        prim, z, lo, hi = prim[rows], z[rows], lo[rows], hi[rows]
    last = bank.offsets[prim + 1] - bank.offsets[prim] - 1.0
    cvec = np.stack([np.zeros(rows.size), last, -lo, hi], axis=1)
    k = opts.refine_points if points is None else points
    q = path.at(np.linspace(a, b, k)) if samples is None else samples
    resid = _Residuals(table, bank, prim, q, opts.rotation)
    zf, cost = _lockstep(resid, z, cvec, target * target * k, give_up * give_up * k, first,
                         rtol)  # fmt: skip
    for j, i in enumerate(rows):
        out[i] = Candidate(cands[i].prim, float(zf[j, 0]), float(zf[j, 1]), cands[i].score)
    rmsd[rows] = np.sqrt(np.maximum(cost, 0.0) / k)
    return out, rmsd


def _one_step(jtj: np.ndarray, g: np.ndarray, lam: np.ndarray, z: np.ndarray,
              cvec: np.ndarray, tol: np.ndarray) -> np.ndarray | None:  # fmt: skip
    """:func:`_steps` of a single row in Python floats when its free step is feasible (the
    same operations on the same numbers: IEEE arithmetic is numpy's), else None (the box
    QP is then :func:`_steps`'): one refinement in two runs a single seed, and the dozens
    of numpy calls on 1-element arrays cost more than the step's arithmetic."""
    (j00, j01), (j10, j11) = jtj[0].tolist()
    g0, g1 = g[0].tolist()
    z0, z1 = z[0].tolist()
    c0, c1, c2, c3 = cvec[0].tolist()
    t0, t1, t2, t3 = tol[0].tolist()
    ell = lam[0].item() + 1e-12
    x0, x1 = ell * (j00 + 1e-12), ell * (j11 + 1e-12)
    h00, h01, h10, h11 = j00 + x0 * 1.0, j01 + x0 * 0.0, j10 + x1 * 0.0, j11 + x1 * 1.0
    det = h00 * h11 - h01 * h10
    if not det > 0:
        return None
    f0 = (h11 * g0 - h01 * g1) / det
    f1 = (h00 * g1 - h10 * g0) / det
    if (-f0 <= (c0 - -z0) + t0 and f1 <= (c1 - z1) + t1 and f0 - f1 <= (c2 - (z0 - z1)) + t2
            and f1 - f0 <= (c3 - (z1 - z0)) + t3):  # fmt: skip
        return np.array([[f0, f1]])
    return None


def _free_step(h: np.ndarray, g: np.ndarray, det: np.ndarray) -> np.ndarray:
    """The unconstrained minimisers of m 2x2 quadratics, h^-1 g by Cramer's rule; rows with
    ``det <= 0`` are divided by 1 instead (meaningless: the callers reject those rows)."""
    out = np.empty_like(g)
    np.multiply(h[:, 1, 1], g[:, 0], out=out[:, 0])
    out[:, 0] -= h[:, 0, 1] * g[:, 1]
    np.multiply(h[:, 0, 0], g[:, 1], out=out[:, 1])
    out[:, 1] -= h[:, 1, 0] * g[:, 0]
    out /= np.where(det > 0, det, 1.0)[:, None]
    return out


def _times_a(z: np.ndarray) -> np.ndarray:
    """z @ _AMAT.T for rows z = (x0, x1): (−x0, x1, x0 − x1, x1 − x0), exactly the product's
    numbers (each a sum of ±1 and 0 multiples: one rounding), without a matrix product."""
    out = np.empty((z.shape[0], 4))
    np.negative(z[:, 0], out=out[:, 0])
    out[:, 1] = z[:, 1]
    np.subtract(z[:, 0], z[:, 1], out=out[:, 2])
    np.subtract(z[:, 1], z[:, 0], out=out[:, 3])
    return out


def _steps(jtj, g, lam, z, cvec, tol=None):
    """Damped Gauss–Newton steps under A z ≤ c: the free 2×2 solution where feasible, the
    box QP of :func:`._refine.solve_box_qp2` elsewhere (in closed form for a fixed
    duration). ``tol``: :func:`._refine.slack_tolerance` of ``cvec``, if the caller keeps it."""
    dg = np.diagonal(jtj, axis1=1, axis2=2)
    h = jtj + ((lam + 1e-12)[:, None] * (dg + 1e-12))[:, :, None] * _EYE2
    det = h[:, 0, 0] * h[:, 1, 1] - h[:, 0, 1] * h[:, 1, 0]
    free = _free_step(h, g, det)
    slack = cvec - _times_a(z)
    tol = slack_tolerance(cvec) if tol is None else tol
    ok = (_times_a(free) <= slack + tol).all(axis=1) & (det > 0)
    if ok.all():
        return free  # the usual case: every free step is feasible
    bad = np.flatnonzero(~ok)
    # a fixed duration (time scale range of one value): the feasible set is the segment
    # x1 − x0 = lo, so the QP is one-dimensional along (1, 1), its minimiser clipped
    line = np.abs(cvec[bad, 2] + cvec[bad, 3]) <= 1e-12 * (1.0 + np.abs(cvec[bad, 3]))
    if np.any(line):
        on = bad[line]
        nhn = h[on].sum(axis=(1, 2))
        t = np.where(nhn > 0, g[on].sum(axis=1) / np.where(nhn > 0, nhn, 1.0), 0.0)
        t = np.clip(t, -z[on, 0], cvec[on, 1] - z[on, 1])
        free[on] = t[:, None]
        bad = bad[~line]
    if bad.size:
        free[bad] = _box_qp_many(h[bad], g[bad], slack[bad], tol[bad])
    return free


def _qp_layout():
    """The constraint lines' normals and the vertices' inverse matrices (constants of
    ``_AMAT``), and the candidates' order of :func:`._refine.solve_box_qp2` in the stack
    [zero, free, lines 0-3, vertices]."""
    normals = np.stack([[-a[1], a[0]] for a in _AMAT])
    pairs, inverses, order = [], [], [0, 1]
    for i in range(len(_AMAT)):
        order.append(2 + i)
        for j in range(i + 1, len(_AMAT)):
            pair = _AMAT[[i, j]]
            if abs(np.linalg.det(pair)) > 1e-12:
                order.append(2 + len(_AMAT) + len(pairs))
                pairs.append((i, j))
                inverses.append(np.linalg.inv(pair))
    return normals, np.array(pairs), np.stack(inverses), np.array(order)


_NORMALS, _PAIRS, _INVERSES, _ORDER = _qp_layout()


def _box_qp_many(h: np.ndarray, g: np.ndarray, slack: np.ndarray, tol: np.ndarray):
    """:func:`._refine.solve_box_qp2` for m problems: the same candidates (the free
    minimiser, each constraint line's minimiser, each vertex of two constraints) in the same
    order, the first best feasible one kept (zero if none improves)."""
    m = h.shape[0]
    det = h[:, 0, 0] * h[:, 1, 1] - h[:, 0, 1] * h[:, 1, 0]
    free = _free_step(h, g, det)
    # on line l (a_l·δ = slack_l): δ = δ_p + t·n_l, t minimising the quadratic along it
    dp = _AMAT[None] * (slack / np.einsum("la,la->l", _AMAT, _AMAT))[:, :, None]
    den = np.einsum("la,mab,lb->ml", _NORMALS, h, _NORMALS)
    num = np.einsum("mlb,lb->ml", g[:, None, :] - np.einsum("mab,mlb->mla", h, dp), _NORMALS)
    t = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    lines = dp + t[:, :, None] * _NORMALS[None]
    rhs = np.stack([slack[:, _PAIRS[:, 0]], slack[:, _PAIRS[:, 1]]], axis=2)
    verts = np.einsum("pab,mpb->mpa", _INVERSES, rhs)
    c = np.concatenate([np.zeros((m, 1, 2)), free[:, None], lines, verts], axis=1)[:, _ORDER]
    f = 0.5 * np.einsum("mna,mab,mnb->mn", c, h, c) - np.einsum("mna,ma->mn", c, g)
    feasible = np.all(c @ _AMAT.T <= (slack + tol)[:, None, :], axis=2)
    f = np.where(feasible, f, np.inf)
    f[:, 0] = 0.0
    return c[np.arange(m), np.argmin(f, axis=1)]


def _lockstep(resid: _Residuals, z: np.ndarray, cvec: np.ndarray, stop: float, give_up: float,
              first: bool, rtol: float = _GAIN) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """:func:`._refine._gauss_newton` for every row of z at once: the final z and costs.

    The state is kept for the running rows only (:class:`_Running`), so a step costs no
    gathers of every row's state, and the accepted and rejected rows are updated together
    (``np.where``: the same numbers as updating each set apart). While one row runs (a
    single seed, half the refinements of a segmentation), its step and update are taken in
    Python floats (:func:`_one_step`, :meth:`_Running.advance_one`): the same IEEE
    operations, without some eighty numpy calls on 1-element arrays per step."""
    m = z.shape[0]
    cost, res, dp, r = resid(np.arange(m), z)
    out_z, out_cost = z, cost
    if first and np.any(cost < stop):
        return out_z, out_cost
    st = _Running.of(z, cost, cvec, cost >= stop)
    if st is None:
        return out_z, out_cost
    keep = st.rows if st.rows.size < m else slice(None)
    st.jtj, st.g = resid.normal_equations(res[keep], resid.turned(dp[keep], r[keep]))
    limits = (rtol, stop, give_up)
    while True:
        one = st.rows.size <= _FLOAT_ROWS  # one seed running: its step and update in floats
        step = _one_step(st.jtj, st.g, st.lam, st.z, st.cvec, st.tol) if one else None
        if step is None:
            step = _steps(st.jtj, st.g, st.lam, st.z, st.cvec, st.tol)
        still = np.any(step != 0.0, axis=1)
        if not still.all():
            step = st.drop(still, out_z, out_cost, step)
            if st.rows.size == 0:
                break
        nz = st.z + step
        ncost, nres, ndp, nr = resid(st.rows, nz)
        on, ends, hit = (st.advance_one if one else st.advance)(step, nz, ncost, limits, first)
        if np.any(on) and not hit:
            if np.all(on):
                st.jtj, st.g = resid.normal_equations(nres, resid.turned(ndp, nr))
            else:
                st.jtj[on], st.g[on] = resid.normal_equations(
                    nres[on], resid.turned(ndp[on], nr[on])
                )
        if hit or np.all(ends):
            st.drop(np.zeros(st.rows.size, bool), out_z, out_cost)
            break
        if np.any(ends):
            st.drop(~ends, out_z, out_cost)
    return out_z, out_cost


class _Running:
    """The state of :func:`_lockstep`'s running rows: their row numbers, z, cost, damping,
    budget, last two gains, constraints and normal equations; :meth:`drop` writes the
    stopped rows' z and cost out and keeps the others."""

    __slots__ = ("rows", "z", "cost", "lam", "budget", "gain", "previous", "cvec", "tol", "jtj",
                 "g")  # fmt: skip

    @classmethod
    def of(cls, z, cost, cvec, run) -> _Running | None:
        rows = np.flatnonzero(run)
        if rows.size == 0:
            return None
        st = cls()
        st.rows = rows
        every = rows.size == run.size
        st.z, st.cost = (z.copy(), cost.copy()) if every else (z[rows], cost[rows])
        st.cvec = cvec if every else cvec[rows]
        st.tol = slack_tolerance(st.cvec)  # kept for _steps
        st.lam, st.budget = np.zeros(rows.size), np.full(rows.size, _BUDGET)
        st.gain, st.previous = np.zeros(rows.size), np.zeros(rows.size)
        return st

    def advance(self, step, nz, ncost, limits, first):
        """:func:`_lockstep`'s update after a step of the running rows (z ``nz`` at cost
        ``ncost``): the rows whose step was accepted and that go on, those that end, and
        whether one hit the target (with ``first``)."""
        rtol, stop, give_up = limits
        self.budget -= 1
        better = ncost < self.cost
        moved = np.abs(step).sum(axis=1)
        gain = np.where(better, self.cost - ncost, self.gain)
        previous = np.where(better, self.gain, self.previous)
        self.z = np.where(better[:, None], nz, self.z)
        cost = np.where(better, ncost, self.cost)
        self.lam = np.where(better, np.where(self.lam > 1e-6, self.lam / 10.0, 0.0),
                            np.maximum(self.lam * 10.0, 1e-4))  # fmt: skip
        done = (moved < _MOVED) | (gain < rtol * cost) | (cost < stop)
        done |= hopeless(cost, gain, previous, give_up)
        ends = np.where(better, done, self.lam > 1e8) | (self.budget <= 0)
        self.cost, self.gain, self.previous = cost, gain, previous
        hit = first and bool(np.any(ncost[better] < stop))
        return better & ~ends, ends, hit

    def advance_one(self, step, nz, ncost, limits, first) -> tuple[bool, bool, bool]:
        """:func:`_lockstep`'s update after a step of its one running row, in Python floats
        (the same comparisons and IEEE operations as its arrays'): whether the step was
        accepted and the row goes on, whether it ends, and whether it hit the target."""
        rtol, stop, give_up = limits
        c_new, c_old = ncost.item(), self.cost.item()
        lam, gain, previous = self.lam.item(), self.gain.item(), self.previous.item()
        self.budget -= 1
        s0, s1 = step[0].tolist()
        if not c_new < c_old:  # rejected: more damping
            lam = max(lam * 10.0, 1e-4)
            self.lam = np.array([lam])
            return False, lam > 1e8 or self.budget.item() <= 0, False
        gain, previous = c_old - c_new, gain
        self.z, self.cost = nz, ncost
        self.gain, self.previous = np.array([gain]), np.array([previous])
        self.lam = np.array([lam / 10.0 if lam > 1e-6 else 0.0])
        done = abs(s0) + abs(s1) < _MOVED or gain < rtol * c_new or c_new < stop
        done = done or _hopeless_one(c_new, gain, previous, give_up)
        ends = done or self.budget.item() <= 0
        return not ends, ends, first and c_new < stop

    def drop(self, keep, out_z, out_cost, *more):
        """Write the rows not in ``keep`` out; keep the others (and ``more``'s rows)."""
        gone = ~keep
        out_z[self.rows[gone]] = self.z[gone]
        out_cost[self.rows[gone]] = self.cost[gone]
        for name in self.__slots__:
            setattr(self, name, getattr(self, name)[keep])
        return more[0][keep] if more else None


def _hopeless_one(cost: float, gain: float, previous: float, give_up: float) -> bool:
    """:func:`._refine.hopeless` of one row in Python floats (the same operations)."""
    rho = gain / (previous if previous > 0 else np.inf)
    tail = 10.0 * gain * rho / (1.0 - rho if rho < 1.0 else 1.0)
    return cost > 1.21 * give_up and rho < 1.0 and previous > 0 and cost - tail > give_up
