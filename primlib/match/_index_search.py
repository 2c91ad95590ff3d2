"""The index search: seeds for one piece of the path from the arc-length index.

A *query* is the piece [a, b] (normalised time) of the new path; a *candidate* is a piece
[x0, x1] (fractional sample indices) of a stored primitive. A candidate of duration
(x1 − x0)·dt against a query of duration (b − a)·T has time scale
k = (x1 − x0)·dt / ((b − a)·T), within ``time_scale``.

A rigid motion and a change of time scale leave the arc-length shape of a piece unchanged, so
the library is indexed once (:class:`~primlib.match._arc_index.ArcIndex`) by resampling every
primitive at uniform arc length, a pyramid of steps Δ₀·2ʲ. A query of arc length ℓ is
resampled at the spacing Δ that gives it 16–31 points; the candidates are the windows of that
spacing starting at every point of the next finer level (dilated windows), so no duration
grid is needed: a window's duration follows from its arc length, filtered to the time-scale
range. Each window is scored by the Kabsch RMSD of its arc samples combined with ℓ times the
RMS difference of the normalised time at the samples (the speed profile), and windows are
scored best-first in order of provable lower bounds of that score (:mod:`._bounds`: a bound
on the speed term from prefix sums of the sample index on every window, the half-window
bound on the shape RMSD on what passes, the principal-value bound on the survivors (not for
``rotation="none"``, whose per-axis half-window bound leaves it nothing to drop); a sample
of the windows fills the pool first so that its threshold prunes from the start; where the
shape bound would be taken on most windows, the cone of :mod:`._cone` first drops whole
blocks of windows from the bounds at every 8th window: a window's RMSD moves by at most
the spacing of its points from one window to the next), exact float64 scores only for
what passes (for ``rotation="none"`` on levels of many windows, only the windows ball
queries of :mod:`._ball` find near the query) — until no unscored window's bound is below the
pool's threshold (:mod:`._pool`) or the gate 3ε + Δ_b/2 on the shape RMSD (Δ_b the finer
level's step; a stored copy starts within Δ_b/2 of a window). The pool is re-scored at sub-step
shifts of its windows' starts (a copy is then within Δ_b/8 of a shift); the best ``seeds``
distinct windows, and every other one within √2·(3ε + Δ_b/8) of the best, become the seeds,
which the exact check (:mod:`._segment`) decides between.

The index searches the path smoothed within a bound tied to its noise and eps
(:mod:`._smooth`: white noise lengthens a path's arc far beyond what eps allows for, and
the index would look at windows of the wrong length); the exact check stays on the samples.
A stored piece within eps of the raw piece is within eps + δ of the smoothed one (δ the
piece's RMS deviation from its samples, ≤ eps), so the gate and the tie width above are
applied with eps + δ in place of eps. Noisy stored primitives are smoothed the same way in
the index (:mod:`._arc_index`), and each window's gate widens by 3 times its own RMS
deviation. On paths and primitives with no noise to speak of δ = 0 and nothing changes.

The gate is a heuristic, not a theorem: a copy within ε in uniform time can have a longer arc
than ε allows for when the path wiggles fast; the smoothing takes out wiggles the noise
estimate sees (tests/test_match_heuristics.py: periods of 2.5-4 samples at RMS 0.6-0.7ε),
not slower ones of the same size. Nor does it hold where the piece's arc is short against eps
(< ``LOOSE_ARC`` eps): a match within eps can then run over a stored arc a third
shorter (real drawings, stored at rest while the piece moves 4 eps). There, on banks of up to
``GRID_BANK`` samples and pieces of more than ``K_MAX`` samples, the time-uniform grid's seeds
are added to the index's, tried when none of the index's matches (measured: LASA,
``bench_match_real.py``). The exhaustive references (every window scored; the time-uniform
grid) live in ``benchmarks/_reference_search.py`` and the tests compare them with this search;
``benchmarks/bench_match_noisy.py`` on noisy queries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from primlib.match import _ball, _cone
from primlib.match._arc_index import ArcIndex, ArcQuery
from primlib.match._bank import BankIndex
from primlib.match._bounds import (
    QueryMoments,
    half_bound_margin,
    half_window_bound,
    half_window_bound_fixed,
    principal_bound,
    principal_bound_points,
    products_for,
    speed_bound,
    speed_screen,
)
from primlib.match._cone import not_in as _not_in
from primlib.match._drain import drain_sorted
from primlib.match._ends import offer_overrun, score_points
from primlib.match._gates import Gates as _Gates
from primlib.match._gates import rough_skip, scale_ok
from primlib.match._grid import GridSearch
from primlib.match._options import Candidate, PathPiece, SearchOptions, SearchStats, SeedMemo
from primlib.match._pool import CandidatePool, reshift
from primlib.match._rescan import rescan
from primlib.match._rough import K_MAX
from primlib.match._smooth import Smoothed, piece_view, smooth_path, smooth_to, wiggly

__all__ = ["IndexSearch", "ArcQuery"]

LOOSE_ARC = 30.0  # arc / eps below which a piece takes the grid's seeds too (notes)
GRID_BANK = 1 << 15  # bank samples up to which the grid is cheap: loose pieces, fixed scales
_SORTED_FROM = 4  # chunks of windows left from which the drain sorts their bounds (._drain)


@dataclass
class IndexSearch:
    """Seeds from the arc-length index with provable lower-bound pruning (module notes)."""

    bank: BankIndex
    opts: SearchOptions
    target_points: int = 16
    phase_bits: int = 1
    pool: int = 2
    pool_cap: int = 48
    chunk: int = 8192
    first_batch: int = 512
    sample: int = 32
    gather_fraction: float = 0.25
    cone: tuple[int, ...] = _cone.SIZES  # block sizes of the cone rejection; (): none
    cone_min: int = _cone.MIN_WINDOWS  # fewer windows a query: no cone
    stats: SearchStats = field(default_factory=SearchStats)
    name: ClassVar[str] = "index"
    ball: ClassVar[bool] = True  # rotation none: ball queries (:mod:`._ball`) where they pay

    def __post_init__(self) -> None:
        self._grid = GridSearch(self.bank, self.opts, self.stats)
        self._smoothed: list = [None, None, None, None]
        # the last query's seeds: a segmentation asks again for the piece whose probe
        # matched at once (``best``)
        self._last: SeedMemo | None = None

    def smoothed(self, path: PathPiece, eps: float, wide: bool = False) -> Smoothed:
        """The path as the index sees it (:mod:`._smooth`), kept for the path and eps of
        the last call (one segmentation asks for the same path many times); ``wide``: the
        copy within eps, for wiggly pieces."""
        hit = self._smoothed
        if hit[0] is not path or hit[1] != eps:
            hit[:] = [path, eps, smooth_path(path, eps), None]
        if wide and hit[3] is None:
            hit[3] = smooth_to(path, eps)
        return hit[3] if wide else hit[2]

    def _index_for(self, ell: float) -> ArcIndex:
        """The index, or a finer one for pieces short in arc length (~16 arc samples)."""
        idx = self.bank.arc_index()
        need = (self.target_points - 1) * idx.step0 / max(ell, 1e-300)
        if need <= 1.0:
            return idx
        return self.bank.fine_arc_index(math.ceil(math.log2(need)))

    def arc_query(
        self, path: PathPiece, a: float, b: float, eps: float | None = None
    ) -> ArcQuery | None:
        """The piece [a, b] at uniform arc length; None when it is too short to index.

        With ``eps``, on the path smoothed within a bound tied to its noise and eps
        (:mod:`._smooth`); ``smoothing`` is then the piece's RMS deviation from the samples.
        """
        smoothing = 0.0
        if eps is not None:
            sm = self.smoothed(path, eps)
            if wiggly(sm.path.points, a, b):
                sm = self.smoothed(path, eps, wide=True)
            path, a, b, smoothing = piece_view(sm, path, a, b, eps)
        n_dense = max(64, int(round((b - a) * (path.n - 1))) * 2 + 1)
        dense = path.at(np.linspace(a, b, n_dense))
        chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        ell = float(chord[-1])
        if ell < 3.0 * self.bank.finest_step():
            return None  # too short for any index: none is built for it
        idx = self._index_for(ell)
        if ell < 3.0 * idx.step0:
            return None
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
        per_axis = self.opts.rotation == "z"
        sq = (qc * qc).sum(axis=0) if per_axis else float((qc * qc).sum())
        dq = (b - a) * path.duration / self.bank.dt
        return ArcQuery(
            idx, jb, lv, dil, step, ell, u, qc, sq, QueryMoments.of(qc), dq, per_axis, smoothing
        )

    def first_bound(self, aq: ArcQuery, ws: np.ndarray | tuple[int, int] | None = None,
                    stride: int = 1) -> np.ndarray:  # fmt: skip
        """Half-window lower bound of the shape RMSD of every window, or of windows ``ws``
        (an index array, or a range (c0, c1): sliced, not gathered; every ``stride``-th of
        it) (:mod:`._bounds`), the per-axis form when the rotation family is restricted."""
        rotation = self.opts.rotation
        psum, pmax, radius = aq.index.sums(aq.jb, aq.dil, products=products_for(rotation))
        d = aq.qc.shape[1]
        margin = half_bound_margin(aq.k, d, pmax, radius)
        if isinstance(ws, tuple):  # window m of the range reads the columns from c0 on
            psum, ws, n = psum[:, ws[0] :], None, -(-(ws[1] - ws[0]) // stride)
        else:
            n = aq.n_windows if ws is None else ws.size
        if rotation == "full":
            return half_window_bound(psum, n, aq.dil, aq.moments, margin, ws, stride)
        # per-axis energies: each carries up to the total's error bound
        return half_window_bound_fixed(
            psum, n, aq.dil, aq.moments, margin * math.sqrt(d), rotation, ws, stride
        )

    def second_bound(self, aq: ArcQuery, ws: np.ndarray) -> np.ndarray:
        """Principal-value lower bound of the shape RMSD of windows ``ws``: from the prefix
        sums of the products where the restricted families' per-axis bound has them built
        anyway (two columns a window), else from the windows' points (few windows get this
        far; the rotation-invariant search builds no products)."""
        if self.opts.rotation != "full":
            psum, pmax, radius = aq.index.sums(aq.jb, aq.dil)
            return principal_bound(psum, ws, aq.dil, aq.moments, pmax, radius)
        radius = aq.index.sums(aq.jb, aq.dil, products=False)[2]
        return principal_bound_points(aq.level.pts, ws, aq.dil, aq.moments, radius)

    def speed_bound(self, aq: ArcQuery, ws: np.ndarray | tuple[int, int],
                    parts: int = 4) -> np.ndarray:  # fmt: skip
        """Lower bound of the speed-profile term ℓ·RMS(τ_w − τ_q) of the score
        (:func:`._ends.combine`, :func:`._bounds.speed_bound`) of windows ``ws`` (an index array,
        or a range (c0, c1))."""
        csum = aq.index.x_sums(aq.jb, aq.dil)
        return speed_bound(csum, aq.level.x, ws, aq.dil, aq.tau, aq.ell, parts, aq.groups(parts))

    def speed_screen(self, aq: ArcQuery, block: tuple[int, int] | np.ndarray,
                     tau: float) -> np.ndarray:  # fmt: skip
        """Mask of the windows in ``block`` (a range, or an index array) whose speed bound
        with 2 groups is below ``tau`` (:func:`._bounds.speed_screen`)."""
        csum = aq.index.x_sums(aq.jb, aq.dil)
        return speed_screen(csum, aq.level.x, block, aq.dil, aq.tau, aq.ell, tau,
                            groups=aq.groups(2))  # fmt: skip

    def in_range(self, aq: ArcQuery, ws: np.ndarray | tuple[int, int],
                 screen: bool = False) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Mask of windows ``ws`` (an index array, or a range (c0, c1)) whose time scale is
        in range, and their end sample index.

        A window's duration follows from its arc length (10 % slack: the refinement enforces
        the range exactly). The end lies ell / step level points on, in the same primitive
        unless near its end (then found from the arc; with ``screen``, such windows are
        kept instead, and their end left approximate).
        """
        lv, ts = aq.level, self.opts.time_scale
        last = lv.pts.shape[0] - 2
        r = aq.ell / lv.step
        off = int(math.floor(r))
        frac = r - off
        if isinstance(ws, tuple) and ws[1] - 1 + off <= last:
            c0, c1 = ws  # slices: the screen's blocks
            x0 = lv.x[c0:c1]
            xa, xb = lv.x[c0 + off : c1 + off], lv.x[c0 + off + 1 : c1 + off + 1]
            prim = lv.prim[c0:c1]
            inside = lv.prim[c0 + off + 1 : c1 + off + 1] == prim
        else:
            if isinstance(ws, tuple):
                ws = np.arange(*ws)
            i0 = ws + off
            over = np.maximum(i0 - last, 0)  # past the level's last point: extrapolated
            i0 -= over
            frac = frac + over
            x0, xa, xb = lv.x[ws], lv.x[i0], lv.x[i0 + 1]
            prim = lv.prim[ws]
            inside = lv.prim[i0 + 1] == prim
        x_end = xa + frac * (xb - xa)
        if screen:
            # the screen: a window whose end crosses its primitive's last level point (a few
            # per block) stays, for the exact test of the batch that scores it
            return scale_ok(aq, (x_end - x0) / aq.duration, prim, ws, ts) | ~inside, x_end
        fix = ~inside
        if np.any(fix):
            at = np.flatnonzero(fix)
            start = at + ws[0] if isinstance(ws, tuple) else ws[at]
            x_end[at] = aq.index.arc_to_sample(lv.garc[start] + aq.ell, lv.prim[start])
        return scale_ok(aq, (x_end - x0) / aq.duration, prim, ws, ts), x_end

    def score(self, aq: ArcQuery, ws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact (combined score, shape RMSD) of the windows starting at ``ws``, float64
        (:func:`._ends.score_points` of the gathered windows, (m, d, k))."""
        pts_w, x_w = aq.index.window_views(aq.jb, aq.span, aq.dil)
        return score_points(aq, pts_w[ws], x_w[ws], self.opts.rotation)  # pts_w[ws]: a copy

    def score_shifted(self, aq: ArcQuery, start: np.ndarray,
                      need: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Combined scores of the windows starting at fractional level positions
        (:meth:`._arc_index.ArcQuery.at_starts`) and their start sample index; +inf where
        one has less than ``need`` of arc left in its primitive."""
        pts, xw, ok = aq.at_starts(start, need)
        r = score_points(aq, pts.transpose(0, 2, 1), xw, self.opts.rotation)[0]
        return np.where(ok, r, np.inf), xw[:, 0]

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Best distinct arc-window candidates below the gate 3·(eps + δ) + Δ/2, best first
        (δ: the smoothing's deviation, module notes), then :meth:`more_seeds`.

        A stored copy of the query starts within Δ/2 of arc length of some window start,
        which moves each arc sample by at most Δ/2 in space and in ℓ·τ: its window scores
        below √2·Δ/2 plus the copy's own deviation (a few eps at most for a match within
        eps).
        """
        return self.first_seeds(path, a, b, eps) + self.more_seeds(path, a, b, eps)

    def first_seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """The index's seeds (the grid's for a piece it cannot place); the same query twice
        in a row (path object, a, b, eps) from the first."""
        if self._last is not None and self._last.holds(path, a, b, eps):
            return list(self._last.first)
        aq = self.arc_query(path, a, b, eps)  # None: (nearly) stationary or very short
        if aq is None:
            out, loose = self._grid.seeds(path, a, b, eps), False
        else:
            out, loose = self._indexed(aq, path, a, b, eps), self._loose(aq, path, a, b, eps)
        self._last = SeedMemo(path, a, b, eps, tuple(out), loose)
        return out

    def more_seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Seeds to try where :meth:`first_seeds` gave no match: the grid's of a loose piece
        (module notes; the index's often have lower RMSDs than the grid's lattice finds)."""
        self.first_seeds(path, a, b, eps)  # the same query: from its memo
        last = self._last
        if last.more is None:
            last.more = tuple(self._grid.seeds(path, a, b, eps)) if last.loose else ()
        return list(last.more)

    def _indexed(self, aq: ArcQuery, path: PathPiece, a: float, b: float,
                 eps: float) -> list[Candidate]:  # fmt: skip
        """:meth:`seeds` from the index."""
        if aq.n_windows <= 0:
            return []
        self.stats.queries += 1
        skip = rough_skip(self.bank, self.opts.time_scale, aq, path, a, b, eps)
        gates = _Gates.of(aq, eps, *skip)
        pool = self._best_first(aq, gates)
        if pool.keys.size == 0:
            return []
        extra = 0.0 if gates.stored is None else float(gates.deviation(pool.keys).max())
        seeds = reshift(self, aq, pool, eps + aq.smoothing + extra, gates.need)
        # the best few placed on uniform time (:mod:`._rescan`); the rest are near ties
        top = 2 * self.opts.seeds
        return rescan(self.bank, seeds[:top], path, a, b, self.opts) + seeds[top:]

    def _loose(self, aq: ArcQuery, path: PathPiece, a: float, b: float, eps: float) -> bool:
        """Whether the piece takes the grid's seeds too, though the index can place it."""
        if self.bank.points.shape[0] > GRID_BANK or aq.ell >= LOOSE_ARC * eps:
            return False
        return path.confirm_points(a, b) > K_MAX

    def _best_first(self, aq: ArcQuery, gates: _Gates) -> CandidatePool:
        """Score windows best-first in order of lower bounds until none left can enter the
        pool: the pool is then exactly the best distinct windows of scoring every window.

        A sample of the windows (every ``sample``-th, time scale in range) ranked by the
        speed bound fills the pool, so its threshold falls before any window is bounded;
        one pass over every window with the time-scale test (:meth:`in_range`, which any
        window scored must pass) and a cheap speed bound (2 groups) against it; on what
        passes, the tighter speed bound and the half-window shape bound (for ``"none"`` the
        shape bound first, :func:`._cone.shape_first` or after the screen
        :meth:`_shape_then_speed`: it sifts far more), and in increasing
        order of the two combined (ℓ·τ and shape add in quadrature in the score) the
        principal-value bound and exact scores, until the next bound reaches the pool's
        threshold (:meth:`_drain`). A window is left out only when its time scale is out of
        range, its shape bound reaches its gate or its combined bound the pool's
        :attr:`~._pool.CandidatePool.combined`.
        """
        g = gates.top
        pool = CandidatePool(self.pool * self.opts.seeds, self.pool_cap, g, math.sqrt(2.0) * g)
        offer_overrun(self, aq, gates, pool)
        if aq.n_windows <= self.chunk:
            self._few(aq, gates, pool)
            return pool
        if _ball.search(self, aq, gates, pool):  # rotation none: the windows near the query
            return pool
        head = np.arange(0, aq.n_windows, self.sample)
        sampled = head.size
        head = head[gates.valid(head)]
        head = head[self.in_range(aq, head)[0]]
        share = head.size / sampled  # of the windows, those valid and in time-scale range
        lbs = self.speed_bound(aq, head)  # per window: the picked ones' bounds are theirs
        if head.size > self.first_batch:
            pick = np.sort(np.argpartition(lbs, self.first_batch - 1)[: self.first_batch])
            head, lbs = head[pick], lbs[pick]  # head is increasing: so is head[pick]
        self._batch(aq, pool, head, lbs, None, gates.at(head))
        known = math.isfinite(pool.combined)
        if known and self.opts.rotation == "none" and share > self.gather_fraction:
            # the shape bound sifts: it first (unless the time-scale test sifts more: a slow
            # piece, most windows far too short in time, then takes the screen below)
            rest, lbs, lbc = _cone.shape_first(self, aq, gates, pool.combined, head)
        elif known:
            rest = self._screen(aq, gates, pool.combined, share)
            rest = rest[_not_in(rest, head, aq.n_windows)]
            if rest.size == 0:
                return pool
            if self.opts.rotation == "none":
                rest, lbs, lbc = self._shape_then_speed(aq, gates, pool.combined, rest)
            else:
                lbs = self.speed_bound(aq, rest)
                keep = (lbs < pool.combined) & _cone.alive(self, aq, gates, rest, self.cone)
                rest, lbs = rest[keep], lbs[keep]
                lb1 = self._shape_bound(aq, rest)
                lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
                keep = (lb1 < gates.at(rest)) & (lbc < pool.combined)
                rest, lbs, lbc = rest[keep], lbs[keep], lbc[keep]
        else:
            # fewer than the pool's best few below the gate yet: the speed bound prunes
            # nothing (a window below the gate enters whatever its speed profile); the
            # drain bounds the rest once the pool has a threshold. The combined bound is
            # the shape bound alone (hypot(x, 0) = x)
            rest, lb1 = self._below_gate(aq, gates, head, share)
            lbc, lbs = np.maximum(lb1, 0.0), np.full(rest.size, -1.0)
        self.stats.bounded += head.size + rest.size
        self._drain(aq, gates, pool, rest, lbs, lbc, known)
        return pool

    def _shape_then_speed(self, aq: ArcQuery, gates: _Gates, tau: float,
                          rest: np.ndarray) -> tuple[np.ndarray, ...]:  # fmt: skip
        """The windows ``rest`` (through the screen) whose shape bound is below their gate
        and ``tau``, and then whose speed and combined bounds are: those bounds. The same
        windows as the speed bound first (hypot(a, b) ≥ a), in the order that reads least
        under ``"none"``, whose per-axis shape bound sifts far more (:func:`._cone.shape_first`)."""
        rest = rest[_cone.alive(self, aq, gates, rest, self.cone)]
        lb1 = self._shape_bound(aq, rest)
        keep = (lb1 < gates.at(rest)) & (lb1 < tau)
        rest, lb1 = rest[keep], lb1[keep]
        lbs = self.speed_bound(aq, rest)
        lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
        keep = lbc < tau  # hypot(a, b) >= b: the speed bound is below tau too
        return rest[keep], lbs[keep], lbc[keep]

    def _shape_bound(self, aq: ArcQuery, rest: np.ndarray) -> np.ndarray:
        """:meth:`first_bound` of windows ``rest``: taken on every window and picked where
        they are more than ``gather_fraction`` of them (contiguous: cheaper than gathering)."""
        if rest.size > self.gather_fraction * aq.n_windows:
            return self.first_bound(aq)[rest]
        return self.first_bound(aq, rest)

    def _few(self, aq: ArcQuery, gates: _Gates, pool: CandidatePool) -> None:
        """Few windows (≤ ``chunk``): every valid one bounded at once (from slices when most
        are valid: 88 against 305 ns a window) and drained best-first (:meth:`drain_bounded`):
        all in one batch scored twice as many exactly (1,650 windows a query against 770)."""
        ws = np.flatnonzero(gates.valid((0, aq.n_windows)))
        self.stats.windows += ws.size
        self.stats.bounded += ws.size
        cut = ws.size > self.gather_fraction * aq.n_windows
        lbs = self.speed_bound(aq, (0, aq.n_windows))[ws] if cut else self.speed_bound(aq, ws)
        lb1 = self.first_bound(aq)[ws] if cut else self.first_bound(aq, ws)
        self.drain_bounded(aq, gates, pool, ws, lbs, lb1)

    def drain_bounded(self, aq: ArcQuery, gates: _Gates, pool: CandidatePool, ws: np.ndarray,
                      lbs: np.ndarray, lb1: np.ndarray) -> None:  # fmt: skip
        """Drain (:meth:`_drain`) the windows ``ws`` whose shape bound ``lb1`` is below
        their gate, in order of the bound combined with their speed bound ``lbs``."""
        lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
        keep = lb1 < gates.at(ws)
        self._drain(aq, gates, pool, ws[keep], lbs[keep], lbc[keep], True)

    def _drain(self, aq: ArcQuery, gates: _Gates, pool: CandidatePool, rest: np.ndarray,
               lbs: np.ndarray, lbc: np.ndarray, known: bool) -> None:  # fmt: skip
        """Score windows ``rest`` in increasing order of their combined bounds ``lbc`` (the
        shape bound alone unless ``known``: ``lbs`` then holds their speed bounds), batch by
        batch, until every one left reaches the pool's threshold.

        Each batch is the smallest of what is left (a partial selection: most windows are
        never scored, and sorting them all cost more than scoring the few); the speed
        bounds are added to every window left as soon as the pool has a threshold (a pool
        filling late left a million windows ranked by their shape bound alone). Once they
        are, more than ``_SORTED_FROM`` chunks left are drained from their bounds sorted a
        front at a time (:func:`._drain.drain_sorted`): a drain that the threshold does not
        stop visits them all, and a selection per batch cost O(n) each.
        """
        size = self.first_batch
        while rest.size:
            if not known and math.isfinite(pool.combined):
                lbs = self.speed_bound(aq, rest)
                lbc = np.hypot(lbc, np.maximum(lbs, 0.0))
                known = True
            live = lbc < pool.combined
            if not live.all():
                rest, lbs, lbc = rest[live], lbs[live], lbc[live]
            if rest.size == 0:
                return
            if known and rest.size > _SORTED_FROM * self.chunk:  # the bounds sorted once
                return drain_sorted(self, aq, gates, pool, (rest, lbs, lbc), size)
            if rest.size > size:
                take = np.argpartition(lbc, size - 1)[:size]
                take.sort()
                left = np.ones(rest.size, dtype=bool)
                left[take] = False
            else:
                take, left = np.arange(rest.size), None
            ws = rest[take]
            self._batch(aq, pool, ws, lbs[take], lbc[take], gates.at(ws))
            if left is None:
                return
            rest, lbs, lbc = rest[left], lbs[left], lbc[left]
            size = min(2 * size, self.chunk)

    def _screen(self, aq: ArcQuery, gates: _Gates, tau: float,
                share: float = 0.0) -> np.ndarray:  # fmt: skip
        """Every valid window whose 2-group speed bound is below ``tau`` and whose time
        scale is in range (:meth:`in_range`, which every window scored must pass: on a
        short, nearly straight query it is the one test that sifts), by blocks of windows
        (cache-sized temporaries); counts the valid windows.

        The tests are taken in the order that reads least: where most windows are in
        time-scale range (a ``share`` of the sampled ones above ``gather_fraction``) the
        speed test first, on every window (it passes a few percent), and the time-scale
        test on those it passes, gathered; else the time-scale test first. Each window's
        outcome is the same either way, so the same windows come out.
        """
        out = []
        speed_first = math.isfinite(tau) and share > self.gather_fraction
        for c0, c1 in _blocks(aq.n_windows):
            ok = gates.valid((c0, c1))
            self.stats.windows += int(np.count_nonzero(ok))
            if speed_first:
                ok &= self.speed_screen(aq, (c0, c1), tau)
                if np.count_nonzero(ok) < self.gather_fraction * (c1 - c0):
                    ws = c0 + np.flatnonzero(ok)
                    out.append(ws[self.in_range(aq, ws, screen=True)[0]])
                    continue
            ok &= self.in_range(aq, (c0, c1), screen=True)[0]
            if not math.isfinite(tau) or speed_first:
                out.append(c0 + np.flatnonzero(ok))
            elif np.count_nonzero(ok) < self.gather_fraction * (c1 - c0):
                # few in range: the speed test on them alone, gathered (the same values)
                ws = c0 + np.flatnonzero(ok)
                out.append(ws[self.speed_screen(aq, ws, tau)])
            else:
                ok &= self.speed_screen(aq, (c0, c1), tau)
                out.append(c0 + np.flatnonzero(ok))
        return np.concatenate(out)

    def _below_gate(self, aq: ArcQuery, gates: _Gates, head: np.ndarray,
                    share: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Every valid window not in ``head`` whose time scale is in range and whose shape
        bound is below its gate, and those bounds. Most windows valid and in time-scale
        range (a ``share`` of the sample, :meth:`_best_first`), so that the bound would be
        taken on every window anyway: the bound first (:meth:`_screen_shape`); few (a
        short, nearly straight piece; pieces near the length of the primitives): the
        validity and time-scale tests first (:meth:`_screen`), the bound on what passes,
        gathered. The same windows either way."""
        if share > self.gather_fraction:
            rest, lb1 = self._screen_shape(aq, gates)
            keep = _not_in(rest, head, aq.n_windows)
        else:
            rest = self._screen(aq, gates, math.inf)
            rest = rest[_not_in(rest, head, aq.n_windows)]
            rest = rest[_cone.alive(self, aq, gates, rest, self.cone)]
            lb1 = self.first_bound(aq, rest)
            keep = lb1 < gates.at(rest)
        return rest[keep], lb1[keep]

    def _screen_shape(self, aq: ArcQuery, gates: _Gates) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_screen` with no threshold, the shape bound against the gate first
        (:func:`._cone.screen_shape`)."""
        return _cone.screen_shape(self, aq, gates, self.cone)

    def _batch(self, aq: ArcQuery, pool: CandidatePool, ws: np.ndarray, lbs: np.ndarray,
               lbc: np.ndarray | None, gates: np.ndarray) -> None:  # fmt: skip
        """Bound (the shape bounds combined with the speed bounds ``lbs``, negative where
        not computed yet; ``lbc`` the combined half-window bound when known), score and
        offer windows ``ws``."""
        if math.isfinite(pool.combined) and lbs.size and lbs.min() < 0:
            lbs = self.speed_bound(aq, ws)
            if lbc is not None:  # it held the shape bound alone
                lbc = np.hypot(lbc, np.maximum(lbs, 0.0))
                keep = lbc < pool.combined
                ws, lbs, gates = ws[keep], lbs[keep], gates[keep]
        if lbc is None:
            lb1 = self.first_bound(aq, ws)
            lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
            keep = (lb1 < gates) & (lbc < pool.combined)
            ws, lbs, gates = ws[keep], lbs[keep], gates[keep]
        # the time-scale filter first: cheap, and with a narrow range (a fixed time scale)
        # it leaves few windows for the principal-value bound
        ok_range, x_end = self.in_range(aq, ws)
        ws, x_end, lbs, gates = ws[ok_range], x_end[ok_range], lbs[ok_range], gates[ok_range]
        if ws.size == 0:  # nothing left to bound or score (each costs ~0.3 ms even so)
            return
        # the principal-value bound is rotation-invariant: after the per-axis bound of "none"
        # it dropped 24 of 183,000 windows (5 novel paths), at about the cost of scoring them
        if self.opts.rotation != "none":
            lb2 = self.second_bound(aq, ws)
            keep = (lb2 < gates) & (np.hypot(np.maximum(lb2, 0.0), np.maximum(lbs, 0.0))
                                    < pool.combined)  # fmt: skip
            ws, x_end, gates = ws[keep], x_end[keep], gates[keep]
            if ws.size == 0:
                return
        r, shape = self.score(aq, ws)
        self.stats.scored += ws.size
        ok = (shape < gates) & (r <= pool.combined)
        lv = aq.level
        pool.offer_arrays(r[ok], lv.prim[ws[ok]], lv.x[ws[ok]], x_end[ok], ws[ok])


def _blocks(n: int, size: int = 1 << 16):
    """The ranges (c0, c1) of n windows taken ``size`` at a time: 65,536 took 20 % less
    time than 16,384 (per-call overhead) or 262,144 (temporaries out of cache)."""
    return ((c0, min(c0 + size, n)) for c0 in range(0, n, size))
