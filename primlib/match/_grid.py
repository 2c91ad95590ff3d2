"""The time-uniform grid search: seeds for pieces too short in arc length to index, and for
every piece when the time scale is fixed on a small bank (one scale: the grid is then
cheaper than the index; on a large one it is not: ``_segment.seeder_for``).

Query sampled at K = ``grid_points`` (16) uniform-time points. Every primitive; every
duration D = k·(query duration) for k on a geometric grid over ``time_scale`` with ratio at
most ``scale_ratio`` (1.1, so 30 scales over 0.25–4); for each D the primitive is resampled
at the stride h = D/(K − 1) and every start m·h (m = 0, 1, ...) is a candidate whose K points
are K consecutive resampled points. A candidate is one below its gate (eps plus the cell
slack, :meth:`GridSearch._slack`); of each scale the ``8·seeds`` best by (RMSD, primitive,
start) enter the pool, and greedy suppression keeps the ``seeds`` best distinct ones.

Most windows are never resampled. For K points w_i (chord c_w = w_K − w_1) against the
query's q_i (chord c_q), any motion's residuals e_i = R w_i + t − q_i give
K ρ² ≥ |e_1|² + |e_K|² ≥ |e_K − e_1|²/2 = |R c_w − c_q|²/2, so

    ρ ≥ g(c_w)/√(2K),   g(c) = min_R |R c − c_q|

(|c − c_q|, ||c| − |c_q|| or, about z, hypot(|c_xy| − |c_q,xy|, c_z − c_q,z)); g is
1-Lipschitz and the interpolant P is Λ-Lipschitz with Λ the largest of |d_i| +
max(|d_{i−1} − d_i|, |d_{i+1} − d_i|)/2 over the intervals crossed (d_i the stored steps),
so over s consecutive windows between two anchor windows (values v_j, v_{j+1})
g(c_w) ≥ (v_j + v_{j+1})/2 − Λ·s·h (:mod:`._grid_bound`, with the proofs). The anchors are P
at every s-th grid point (s divides K − 1: an anchor window's end is an anchor too; s·h up
to a third of D, and s = 1 on a scale of few windows, whose anchors are then every window's
points and its bound the window's own). A
stretch whose bound is beyond its gate, or beyond the scale's ``8·seeds``-th best RMSD found
so far (stretches taken smallest bound first), cannot enter the pool: it is dropped, with a
margin for round-off (:func:`._grid_bound.beyond`). The windows of the others are resampled
in two passes: first the points where they start and end, whose own endpoint bound drops
more (about two thirds of them at a piece's edge on 1,000 primitives); then the points
between, for the stretches that keep a window. The radius-of-gyration bound
(:func:`primlib.match._bounds.gyration_bound`), taken from running sums along each stretch
with a margin for their round-off (:func:`._grid_bound.window_energies`), drops more before
any window's points are gathered; the rest are centred each on its own mean, bounded so
again, and scored by ``rmsd_from_moments`` (no rotation formed). The seeds are those of
scoring every window so (``benchmarks/_reference_search.every_window_seeds``).

Two more prunings leave the seeds as they are. On a scale of many windows the starts are cut
in blocks, each with one bound on the chords of the windows starting in it
(:mod:`._grid_blocks`): a few blocks whose chords are nearest the query's are searched first,
and the others only where their bound is not beyond the limit that leaves, none resampled
before. And the scales are searched under a cap taken from the pool so far
(:meth:`GridSearch.seeds`): a window scoring above the ``seeds``-th candidate the suppression
keeps is not among the picks unless a later candidate suppresses earlier ones, which is
checked, and then the scales are searched again without caps. A piece at rest (a path that
stops: a piece the index cannot place) against 1,000 primitives scored ~80,000 windows and
took 1.4 s; with both ~300 and 0.13-0.17 s (``benchmarks/bench_match_novel.py --rests``).

One pruning changes which windows are candidates at all: a window whose whole cell reads
stored rows too little curved to follow the piece's sharpest turn within eps at the path's
samples (a stop or a start at once, a sharp corner) is left out of its scale
(:mod:`._curvature`, ``out`` of each scale). It cannot be a match, but it could have been a
seed above eps; the every-window reference takes the same windows.

The index search falls back on it for (nearly) stationary or very short pieces; the tests
and benchmarks also run it on whole paths as the exhaustive reference.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import Any, ClassVar

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import maximum_filter1d

from primlib.match._bank import BankIndex
from primlib.match._bounds import gyration_bound
from primlib.match._curvature import Curvature, critical, lag_turns, minus
from primlib.match._grid_blocks import Scale as _Scale
from primlib.match._grid_blocks import StartBlocks, runs, without
from primlib.match._grid_bound import (
    Best,
    anchor_values,
    beyond,
    endpoint_gap,
    gyration_below,
    speed_bounds,
    stretch_bounds,
    stretch_length,
    window_energies,
)
from primlib.match._kabsch import rmsd_from_moments
from primlib.match._options import Candidate, PathPiece, SearchOptions, SearchStats
from primlib.match._pool import suppress

__all__ = ["GridSearch", "scale_grid"]

_HEAD = 64  # blocks searched first on a scale, to set its limit (GridSearch._scale_seeds)
_TABLE = 8  # a resampling of more than 1/_TABLE of the bank's samples builds the table


def scale_grid(lo: float, hi: float, ratio: float) -> np.ndarray:
    """Geometric grid over [lo, hi] with neighbouring ratio at most ``ratio``."""
    n = 1 + max(1, math.ceil(math.log(hi / lo) / math.log(ratio) - 1e-9)) if hi > lo else 1
    return np.geomspace(lo, hi, n) if n > 1 else np.array([lo])


def _coefficient_table(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Every interval's first sample p1 and Catmull-Rom coefficients (c1, c2, c3) with the
    neighbours :func:`._interp.cubic_at` takes (clamped at the curve's ends), coefficient by
    coefficient, one row per stored sample (row j: the interval j -> j + 1 of its curve;
    a curve's last row is no interval and is never read): shape (4, N, d).

    The neighbours are the rows either side (slices, not gathers), then each curve's end
    rows clamped; the coefficients are :func:`._interp.coefficients`' operations in their
    order, written in place: the same numbers to the last bit as gathering the neighbours
    of every interval (a third of the time: 1.4 s on 1,000 primitives of 2,000 samples,
    once per segmentation), and each coefficient contiguous for :meth:`GridSearch._resample`.
    """
    n, d = points.shape
    tab = np.empty((4, n, d))
    if n < 2:
        tab[:] = points
        return tab
    p0, p2, p3 = np.empty_like(points), np.empty_like(points), np.empty_like(points)
    p0[1:], p0[0] = points[:-1], points[0]
    p2[:-1], p2[-1] = points[1:], points[-1]
    p3[:-2], p3[-2:] = points[2:], points[-1]
    heads, ends = offsets[:-1], offsets[1:]
    long = ends - heads >= 2
    p0[heads[long]] = points[heads[long]]  # a curve's first interval: p0 = p1
    p3[ends[long] - 2] = points[ends[long] - 1]  # its last: p3 = p2
    tab[0] = points
    np.subtract(p2, p0, out=tab[1])  # c1 = p2 − p0
    c2 = tab[2]  # c2 = 2 p0 − 5 p1 + 4 p2 − p3, left to right
    np.multiply(p0, 2.0, out=c2)
    c2 -= 5.0 * points
    c2 += 4.0 * p2
    c2 -= p3
    c3 = tab[3]  # c3 = 3 (p1 − p2) + p3 − p0, left to right
    np.subtract(points, p2, out=c3)
    c3 *= 3.0
    c3 += p3
    c3 -= p0
    return tab


def _coefficients_at(points: np.ndarray, rows: np.ndarray, i: np.ndarray,
                     count: np.ndarray) -> tuple[np.ndarray, ...]:  # fmt: skip
    """The rows ``rows`` of :func:`_coefficient_table` (the interval i of a curve of
    ``count`` samples each), formed from the neighbours gathered: p1 and c1, c2, c3 by the
    same operations in the same order, so the same numbers to the last bit."""
    p1 = points[rows]
    p2 = points[rows + 1]
    p0 = points[np.where(i > 0, rows - 1, rows)]  # a curve's first interval: p0 = p1
    p3 = points[np.where(i < count - 2, rows + 2, rows + 1)]  # its last: p3 = p2
    c1 = p2 - p0
    c2 = p0 * 2.0
    c2 -= 5.0 * p1
    c2 += 4.0 * p2
    c2 -= p3
    c3 = p1 - p2
    c3 *= 3.0
    c3 += p3
    c3 -= p0
    return p1, c1, c2, c3


@dataclass(frozen=True)
class _Query:
    """The query's K centred points, their second moments (per axis for ``"z"``), its
    radius of gyration, chord (the endpoint bound's c_q, :mod:`._grid_bound`) and largest
    coordinate magnitude."""

    qc: np.ndarray
    sq: np.ndarray | float
    rg: float
    chord: np.ndarray
    extent: float

    @classmethod
    def of(cls, q: np.ndarray, rotation: str) -> _Query:
        qc = q - q.mean(axis=0)
        sq = (qc * qc).sum(axis=0) if rotation == "z" else float((qc * qc).sum())
        rg = math.sqrt(float(np.sum(sq)) / q.shape[0])
        return cls(qc, sq, rg, q[-1] - q[0], float(np.abs(q).max()))


@dataclass(frozen=True)
class _Stretches:
    """One scale's stretches of s consecutive windows (primitive by primitive): primitive,
    first window, windows in it (``count``), the lower bound on ρ of its windows, a gate at
    or above theirs; the anchors (P at every s-th grid point) and, per stretch, the anchor
    row of its first window."""

    s: int
    prim: np.ndarray
    first: np.ndarray
    count: np.ndarray
    bound: np.ndarray
    gate: np.ndarray
    anchors: np.ndarray
    rows: np.ndarray


@dataclass
class GridSearch:
    """Exhaustive search on the documented (start, time scale) grid, vectorised; windows
    that a lower bound proves out are never resampled (:mod:`._grid_bound`)."""

    bank: BankIndex
    opts: SearchOptions
    stats: SearchStats = field(default_factory=SearchStats)
    name: ClassVar[str] = "grid"
    span: ClassVar[float] = 0.34
    chunk: ClassVar[int] = 1 << 14  # stretches scored at once, at most
    few: ClassVar[int] = 1 << 16  # windows of a scale below which s = 1 (each its own)

    @property
    def _kept(self) -> dict:
        """The bank's tables (``BankIndex.grid_tables``, made here on first use): every
        search on the same index shares them, so a segmentation after the first pays for
        none (on 1,000 primitives of 2,000 samples the coefficients are 192 MB, made in
        ~0.7 s, the blocks ~50 MB a width)."""
        return self.bank.grid_tables

    def _once(self, key: str, make: Callable[[], Any]) -> Any:
        """The bank's table ``key`` (:attr:`_kept`), made by ``make`` at the first ask."""
        kept = self._kept
        if key not in kept:
            kept[key] = make()
        return kept[key]

    def _scales(self, path: PathPiece, a: float, b: float,
                eps: float | None = None) -> Iterator[_Scale]:  # fmt: skip
        """Per time scale, the primitives that hold its duration and their windows (starts
        m·h, m < n_start); with ``eps``, ``out`` the windows the piece's turns rule out
        (:mod:`._curvature`)."""
        bank, k = self.bank, self.opts.grid_points
        dq = (b - a) * path.duration / bank.dt
        counts = bank.counts
        lo, hi = self.opts.time_scale
        spread = math.sqrt(self.opts.scale_ratio) - 1.0 if hi > lo else 0.0
        kc = path.confirm_points(a, b)
        turns = None if eps is None else lag_turns(path.at(np.linspace(a, b, kc)))
        for scale in scale_grid(lo, hi, self.opts.scale_ratio):
            dur = scale * dq
            h = dur / (k - 1)
            ok = np.flatnonzero(counts - 1 >= dur - 1e-9)
            if ok.size == 0 or h <= 0:
                continue
            n_start = np.floor((counts[ok] - 1 - dur) / h + 1e-9).astype(np.int64) + 1
            cell = dur / (k - 1) / 2.0 + dur * spread
            sc = _Scale(ok, n_start, dur, h, cell)
            span = dur * (1.0 + spread)  # the longest window of the scale's cells
            crit = -1.0 if turns is None else critical(turns, span / max(kc - 1, 1), kc, eps)
            if crit >= 0.0:
                curv = self._once(
                    "curvature", lambda: Curvature(bank.points, bank.offsets, self._magnitude())
                )
                sc = replace(sc, out=curv.out(sc, crit, span))
            yield sc

    def _resample(self, prim: np.ndarray, x: np.ndarray) -> np.ndarray:
        """:func:`._interp.cubic_at` of primitives ``prim`` at sample indices ``x``, from a
        table of every interval's Catmull-Rom coefficients (:func:`_coefficient_table`,
        built on the first call, kept): no neighbour gathers and no coefficient arithmetic
        per point, the same numbers to the last bit. Until a resampling of more than
        1/``_TABLE`` of the bank's samples asks for the table, the coefficients of the
        intervals read are formed from their neighbours (:func:`_coefficients_at`, the same
        operations): searches that blocks and caps confine read a few thousand points."""
        count = self.bank.counts[prim]
        x = np.clip(x, 0.0, count - 1)
        i = np.minimum(np.floor(x).astype(np.int64), count - 2)
        f = (x - i)[:, None]
        rows = self.bank.offsets[prim] + i
        table = self._kept.get("table")
        if table is None and x.size * _TABLE <= self.bank.points.shape[0]:
            p1, c1, c2, c3 = _coefficients_at(self.bank.points, rows, i, count)
            rows = np.arange(rows.size)
        else:
            p1, c1, c2, c3 = self._once(
                "table", lambda: _coefficient_table(self.bank.points, self.bank.offsets)
            )
        # p1 + 0.5 f (c1 + f (c2 + f c3)), its operations in their order, in place, each
        # coefficient gathered contiguous (mode "clip": no buffer; rows are in range)
        val = np.take(c3, rows, axis=0, mode="clip")
        val *= f
        val += np.take(c2, rows, axis=0, mode="clip")
        val *= f
        val += np.take(c1, rows, axis=0, mode="clip")
        val *= 0.5 * f
        val += np.take(p1, rows, axis=0, mode="clip")
        return val

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Best distinct grid candidates that a continuous move within their cell could
        bring below eps (Lipschitz gate, see :meth:`_slack`), best first: of each time
        scale the ``8·seeds`` best windows below their gates (:meth:`_scale_seeds`), then
        greedy suppression (:func:`._pool.suppress`).

        The scales are searched in order under a cap: once the suppression of the pool so
        far keeps ``seeds`` candidates, no window scoring above the last of them (the cap)
        is scored on the scales after (:meth:`_scale_seeds` drops whole blocks of starts by it).
        A window above every cap taken (``low``) comes after the suppression's picks in
        its order, so where the picks end at or below ``low`` they are those of the search
        without caps: the pool's windows at or below ``low`` are the same (each scale's
        ``8·seeds`` best below it are all kept), in the same order. Where they do not (a
        later candidate suppressed earlier picks), the search is run again without caps.
        """
        k = self.opts.grid_points
        q = path.at(np.linspace(a, b, k))
        query = _Query.of(q, self.opts.rotation)
        self.stats.queries += 1
        kept, low = self._pooled(path, a, b, eps, query, capped=True)
        if low < math.inf and (len(kept) < self.opts.seeds or kept[-1].score > low):
            windows = self.stats.windows  # the grid's windows, counted once
            kept, _ = self._pooled(path, a, b, eps, query, capped=False)
            self.stats.windows = windows
        return kept

    def _pooled(self, path: PathPiece, a: float, b: float, eps: float, query: _Query,
                capped: bool) -> tuple[list[Candidate], float]:  # fmt: skip
        """:meth:`seeds` (under caps, or not) and the lowest cap taken (inf: none)."""
        pool: list[Candidate] = []
        slack = self._round_off(query)
        cap = low = math.inf
        for sc in self._scales(path, a, b, eps):
            self.stats.windows += int(sc.n_start.sum())
            best = self._scale_seeds(sc, query, eps, slack, cap)
            pool += [
                Candidate(int(p), float(x), float(x + sc.dur), float(r))
                for r, p, x in zip(best.rmsd, best.prim, best.x0, strict=True)
            ]
            if capped and best.rmsd.size:
                kept = suppress(pool, self.opts.seeds)
                if len(kept) == self.opts.seeds:
                    cap = kept[-1].score
                    low = min(low, cap)
        return suppress(pool, self.opts.seeds), low

    def _scale_seeds(self, sc: _Scale, query: _Query, eps: float, slack: float,
                     cap: float = math.inf) -> Best:  # fmt: skip
        """The scale's best windows below their gates and ``cap``.

        On a scale of many windows, by blocks of their starts (:mod:`._grid_blocks`): first
        ``_HEAD`` blocks, those of the smallest bounds among the blocks ``cap`` leaves (none
        left: nothing is searched), or with no cap those whose chords are nearest the
        query's (:meth:`._grid_blocks.StartBlocks.head`: most of the best windows of a piece
        at rest are in the stillest blocks); then the other blocks whose bound is not beyond
        the limit that leaves (the ``top``-th best RMSD, or ``cap``), none resampled before.
        Each part (or the whole scale) is searched by :meth:`_best_first`."""
        best = Best(8 * self.opts.seeds)
        starts = self._start_blocks(sc)
        if starts is None:
            self._best_first(sc, query, eps, slack, cap, best, sc)
            return best
        width = starts.width(sc.dur)
        if cap < math.inf:  # the blocks the cap leaves, the 64 of the smallest bounds first
            live, bound = self._block_bounds(starts, sc, query, cap, slack)
            if live.size <= _HEAD:
                self._best_first(runs(live, width, self.bank.offsets, sc), query, eps, slack,
                                 cap, best, sc)  # fmt: skip
                return best
            first = np.sort(live[np.argpartition(bound, _HEAD - 1)[:_HEAD]])
        else:
            first = starts.head(sc.dur, query.chord, self.opts.rotation, _HEAD)
        head = runs(first, width, self.bank.offsets, sc)
        self._best_first(head, query, eps, slack, cap, best, sc)
        limit = min(best.limit(), cap)
        if cap < math.inf:
            live = live[~beyond(bound, limit, query.rg, slack)]
        else:
            live, _ = self._block_bounds(starts, sc, query, limit, slack)
        live = live[~np.isin(live, first)]
        if live.size > starts.count(width) // 4:  # blocks prove little: all but the head
            rest = without(sc, head)
        else:
            rest = runs(live, width, self.bank.offsets, sc)
        self._best_first(rest, query, eps, slack, cap, best, sc)
        return best

    def _best_first(self, sc: _Scale | None, query: _Query, eps: float, slack: float,
                    cap: float, best: Best, whole: _Scale) -> None:  # fmt: skip
        """Offer ``best`` the windows of ``sc`` (None: none; those of ``whole.out`` left out)
        below their gates and ``cap``: stretches of windows best-first by their lower bound
        (:meth:`_stretches`) until the next one's bound passes the ``top``-th best RMSD found
        (:class:`._grid_bound.Best`), ``cap`` or its stretch's gate."""
        sc = minus(sc, whole.out, whole)
        if sc is None:
            return
        st = self._stretches(sc, query, eps)
        left = np.flatnonzero(~beyond(st.bound, st.gate, query.rg, slack))
        size = 64 if st.s > 1 else 256  # few windows: most in the first batch
        while left.size:
            left = left[~beyond(st.bound[left], min(best.limit(), cap), query.rg, slack)]
            if left.size > size:  # the smallest bounds first: the limit falls fastest
                at = np.argpartition(st.bound[left], size - 1)[:size]
                part, left = left[at], np.delete(left, at)
            else:
                part, left = left, left[:0]
            if part.size:
                self._score_part(sc, query, eps, st, part, best, slack, cap)
            size = min(4 * size, self.chunk) if st.s > 1 else left.size  # few: the rest at once

    def _start_blocks(self, sc: _Scale) -> StartBlocks | None:
        """The blocks of starts (:class:`._grid_blocks.StartBlocks`, made at the first ask)
        for a scale of more than ``few`` windows lasting 7 samples or more; None elsewhere
        (the scale is searched whole)."""
        if StartBlocks.width(sc.dur) is None or int(sc.n_start.sum()) <= self.few:
            return None
        return self._once(
            "starts", lambda: StartBlocks(self.bank.points, self.bank.offsets, self._blocks(1))
        )

    def _block_bounds(self, starts: StartBlocks, sc: _Scale, query: _Query, limit: float,
                      slack: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """:meth:`._grid_blocks.StartBlocks.bounds` for the scale and query."""
        return starts.bounds(sc.dur, query.chord, self.opts.rotation, self.opts.grid_points,
                             limit, query.rg, slack)  # fmt: skip

    def _score_part(self, sc: _Scale, query: _Query, eps: float, st: _Stretches,
                    part: np.ndarray, best: Best, slack: float, cap: float) -> None:  # fmt: skip
        """:meth:`_score` the windows of the stretches ``part`` (none above ``cap``) not
        beyond the limit by their own endpoint bound (s = 1: the stretch bound was it)."""
        limit = np.minimum(st.gate[part], min(best.limit(), cap))
        if st.s == 1:  # the anchors are every grid point
            windows = (st.anchors, st.rows[part], st.prim[part], st.first[part], limit)
        else:
            windows = self._stretch_windows(sc, query, st, part, limit, slack)
        if windows is not None:
            self._score(sc, query, eps, windows, best, slack)

    def _stretch_windows(self, sc: _Scale, query: _Query, st: _Stretches, part: np.ndarray,
                         limit: np.ndarray, slack: float) -> tuple | None:  # fmt: skip
        """The windows of the stretches ``part`` (s > 1; ``limit`` per stretch) that neither
        their own endpoint bound nor :func:`._grid_bound.gyration_below` puts beyond it: the
        resampled points (M, d), the row of each window's first point (its K points are the
        next K rows), its primitive, index m and limit; None for none. P is resampled where
        the windows start and end first (2s rows of a stretch's s + K − 1), the rows between
        only for the stretches that keep a window (about a third of them, at a piece's
        edge on 1,000 primitives): the same points, row by row."""
        k, s, h = self.opts.grid_points, st.s, sc.h
        first, prim, d = st.first[part], st.prim[part], self.bank.points.shape[1]
        t = np.arange(s)
        ends = np.concatenate([t, t + k - 1])
        pts = self._resample(np.repeat(prim, 2 * s), ((first[:, None] + ends) * h).ravel())
        pts = pts.reshape(part.size, 2 * s, d)
        chord = (pts[:, s:] - pts[:, :s]).reshape(-1, d)
        gap = endpoint_gap(chord, query.chord, self.opts.rotation).reshape(part.size, s)
        keep = (t < st.count[part][:, None]) & ~beyond(
            gap / math.sqrt(2.0 * k), limit[:, None], query.rg, slack)  # fmt: skip
        b = np.flatnonzero(keep.any(axis=1))
        if b.size == 0:
            return None
        mid = np.arange(s, k - 1)
        inner = self._resample(np.repeat(prim[b], mid.size), ((first[b, None] + mid) * h).ravel())
        rows = np.concatenate([pts[b, :s], inner.reshape(b.size, mid.size, d), pts[b, s:]], axis=1)
        energy, err = window_energies(rows, k, self._magnitude())
        gyr = gyration_below(energy, err, float(np.sum(query.sq)), k)
        bb, tt = np.nonzero(keep[b] & ~beyond(gyr, limit[b, None], query.rg, 0.0))
        return (
            rows.reshape(-1, d),
            bb * rows.shape[1] + tt,
            prim[b][bb],
            first[b][bb] + tt,
            limit[b][bb],
        )

    def _magnitude(self) -> float:
        """The bank's largest coordinate magnitude (kept)."""
        pts = self.bank.points
        return self._once("extent", lambda: float(max(pts.max(), -pts.min())) if pts.size else 0.0)

    def _round_off(self, query: _Query) -> float:
        """Absolute round-off of the endpoint bound in ρ: the chords' points carry ~u of
        the coordinates' magnitude each (256 u, generously), over √(2K)."""
        big = self._magnitude() + query.extent
        return 256.0 * np.finfo(float).eps * big / math.sqrt(2.0 * self.opts.grid_points)

    def _stretches(self, sc: _Scale, query: _Query, eps: float) -> _Stretches:
        """Stretches of s consecutive windows of each primitive (s = :func:`stretch_length`,
        1 on a scale of few windows): the lower bound on ρ of their windows and a gate at
        or above theirs. P is resampled at every s-th grid point only
        (:func:`anchor_values`)."""
        k, h = self.opts.grid_points, sc.h
        few = int(sc.n_start.sum()) <= self.few
        s = 1 if few else stretch_length(k, h, self.span * sc.dur)
        lag = (k - 1) // s
        n_stretch = -(-sc.n_start // s)
        n_anchor = n_stretch + 1 + lag
        base = np.concatenate([[0], np.cumsum(n_anchor)])
        local = np.arange(base[-1]) - np.repeat(base[:-1], n_anchor)
        m0 = sc.first()
        at = (np.repeat(m0, n_anchor) + local * s) * h  # every s-th grid point of each run
        anchors = self._resample(np.repeat(sc.prim, n_anchor), at)
        values = anchor_values(anchors, n_anchor, lag, query.chord, self.opts.rotation)
        prim = np.repeat(sc.prim, n_stretch)
        first = np.arange(n_stretch.sum()) - np.repeat(np.cumsum(n_stretch) - n_stretch, n_stretch)
        rows = first + np.repeat(base[:-1], n_stretch)  # s = 1: a window's first anchor
        first = first * s + np.repeat(m0, n_stretch)  # window index m in its primitive
        # the largest speed bound over the intervals the stretch's starts and ends cross,
        # and every gate's local speed bounds (of its starts [a, a + ⌈s·h⌉])
        at = self.bank.offsets[prim] + np.floor(first * h).astype(np.int64)
        top = self._stretch_speeds(sc, at, math.ceil(s * h))
        lb = stretch_bounds(values, n_stretch, top * (s * h), s)
        gate = eps + top * sc.cell  # at or above every window's (:meth:`_slack`)
        count = np.minimum(np.repeat(m0 + sc.n_start, n_stretch) - first, s)
        return _Stretches(s, prim, first, count, lb / math.sqrt(2.0 * k), gate, anchors, rows)

    def _slack(self, prim: np.ndarray, x0: np.ndarray, sc: _Scale) -> np.ndarray:
        """Bound on how much the RMSD can drop inside a grid cell.

        Moving the start by up to h/2 and the duration to a neighbouring scale (factor
        √ratio) moves each of the K points by at most c = h/2 + D(√ratio − 1) samples along
        the stored curve, i.e. by at most c times the interpolant's largest speed over the
        intervals it crosses: |P'| ≤ |d_i| + max(|d_{i−1} − d_i|, |d_{i+1} − d_i|)/2 on the
        interval i (:func:`._grid_bound.speed_bounds`, proven there; up to 1.5 times the
        largest step, at f = 1/2 between alternating steps, where the 1.25 times the largest
        step this took before fell short); the RMSD against a fixed query is 1-Lipschitz in
        the RMS point displacement. The largest speed is taken over the window's own
        stretch, [x0 − c, x0 + D + c] (:meth:`_local_speeds`), not the whole primitive: a slow
        piece of a fast primitive got the fast parts' slack, which let nearly every window
        past the radius-of-gyration bound (a 34-sample piece too short in arc length to
        index, on 1,000 primitives: 32.8 M of 37 M windows scored, 42 s). A fixed time scale
        (one duration) has no neighbouring scale: only the start moves.
        """
        at = self.bank.offsets[prim] + np.floor(x0).astype(np.int64)
        return self._local_speeds(sc, at) * sc.cell

    def _local_speeds(self, sc: _Scale, at: np.ndarray) -> np.ndarray:
        """Per stored sample j in ``at``, the largest speed bound of its primitive's
        intervals (:func:`._grid_bound.speed_bounds`) over [j − ⌈c⌉ − 1, j + ⌈D⌉ + ⌈c⌉ + 2]
        (c = ``cell``): every interval a grid point of a window starting in [j, j + 1)
        crosses, moved within its cell (a sample to spare either side; 0 past a primitive's
        ends and the bank's). Gathered: only the windows scored need it."""
        padded = self._padded_speeds()
        span = at[..., None] - sc.back + np.arange(1, sc.size + 1)
        return np.take(padded, span, mode="clip").max(axis=-1)

    def _stretch_speeds(self, sc: _Scale, at: np.ndarray, extra: int) -> np.ndarray:
        """At or above :meth:`_local_speeds` of every j in [a, a + extra] for each a in
        ``at``: the largest speed bound over [a − back, a − back + size + extra), taken on
        maxima of blocks of B of them (B a power of 2 near 1/8 of that: one filter over N/B
        block maxima, kept per B)."""
        reach = sc.size + extra
        width = 1 << max(0, (reach // 8).bit_length() - 1)
        blocks = self._blocks(width)
        nb = (reach - 1) // width + 2  # blocks that any `reach` consecutive intervals touch
        row = np.clip((at - sc.back) // width, 0, blocks.size - 1)
        if row.size * nb < blocks.size:  # few: the nb blocks of each, gathered (0 past the end)
            span = row[:, None] + np.arange(nb)
            return np.where(span < blocks.size, blocks[np.minimum(span, blocks.size - 1)],
                            0.0).max(axis=1)  # fmt: skip
        wide = maximum_filter1d(blocks, size=nb, origin=-(nb // 2), mode="constant")
        return wide[row]

    def _blocks(self, width: int) -> np.ndarray:
        """Maxima of the speed bounds over blocks [i·width, (i + 1)·width), width a power of 2
        (each from the one of half its width), kept."""
        block_max = self._once("block_max", dict)
        if width not in block_max:
            if width == 1:
                block_max[1] = speed_bounds(self.bank.points, self.bank.offsets)
            else:
                half = self._blocks(width // 2)
                pairs = np.zeros(half.size + half.size % 2)
                pairs[: half.size] = half
                block_max[width] = pairs.reshape(-1, 2).max(axis=1)
        return block_max[width]

    def _padded_speeds(self) -> np.ndarray:
        """The speed bounds of :meth:`_blocks` (width 1) with a 0 either side (gathers
        clipped to them read 0)."""
        return self._once("speeds", lambda: np.concatenate([[0.0], self._blocks(1), [0.0]]))

    def _score(self, sc: _Scale, query: _Query, eps: float, part: tuple, best: Best,
               slack: float) -> None:  # fmt: skip
        """Of the windows ``part`` (resampled points (M, d), each window's first row, its
        primitive, index m and a limit at or above its gate, its own endpoint bound not
        beyond it), drop those whose radius-of-gyration bound
        (:func:`primlib.match._bounds.gyration_bound`) is beyond the limit, score the others
        (``rmsd_from_moments``, each window centred on its own mean) and offer those below
        their gates to ``best``."""
        res, rows, prim, m, limit = part
        k, rotation = self.opts.grid_points, self.opts.rotation
        win = sliding_window_view(res, k, axis=0)[rows]  # (m, d, k)
        win = win - win.mean(axis=2, keepdims=True)
        sp = np.einsum("mdk,mdk->md" if rotation == "z" else "mdk,mdk->m", win, win)
        tot = sp.sum(axis=1) if rotation == "z" else sp
        gyr = gyration_bound(tot, float(np.sum(query.sq)), k)
        live = np.flatnonzero(~beyond(gyr, limit, query.rg, 0.0))
        self.stats.scored += live.size
        if live.size == 0:
            return
        win, prim, x0 = win[live], prim[live], m[live] * sc.h
        sp = sp[live]
        s_q = win @ query.qc  # one (m·d, k) by (k, d) product
        rmsd = rmsd_from_moments(s_q, sp, np.broadcast_to(query.sq, sp.shape), k, rotation)
        ok = np.flatnonzero(rmsd < eps + self._slack(prim, x0, sc))
        best.add(rmsd[ok], prim[ok], x0[ok])
