"""The arc-length index: every primitive resampled at uniform arc length, a pyramid of steps.

A rigid motion and a change of time scale leave the arc-length shape of a piece unchanged,
so one index serves every query of every rotation family and time scale
(:mod:`primlib.match._index_search` searches it). Arc length is measured on the primitives
smoothed like a query (:func:`primlib.match._smooth.smooth_bank`: noisy stored samples would
lengthen it as a noisy query's do); each index point carries the squared deviation of the
smoothed primitive from its samples there, so a window knows its RMS deviation
(:meth:`ArcIndex.window_deviation`). Clean primitives are not smoothed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match._bounds import (
    QueryMoments,
    product_pairs,
    speed_groups,
    strided_cumsum,
    strided_prefix_sums,
)
from primlib.match._reject import row_groups
from primlib.match._smooth import smooth_bank

if TYPE_CHECKING:
    from primlib.match._bank import BankIndex

__all__ = ["ArcIndex", "Level", "ArcSamples", "ArcQuery"]


@dataclass(frozen=True)
class Level:
    """One level of an :class:`ArcIndex`: M points, each primitive's at arc ``0, step,
    2·step, ...`` from its start (``step = step0 · 2^shift``).

    The global arc coordinate of each point (:attr:`garc`) and the arc left to its
    primitive's end (:attr:`left`) are not held (16 bytes a point, beside the 36 of a 3-D
    point's coordinates, primitive and sample index): both are a per-primitive constant
    plus or minus ``(n · 2^shift) · step0`` for the point's number n within its
    primitive, computed on access with the very operations that formed them (the same
    values, bit for bit); :meth:`fits` tells which points have a given arc left from
    per-primitive counts.
    """

    step: float
    pts: np.ndarray  # (M, d) centred per primitive
    prim: np.ndarray  # (M,) int32
    x: np.ndarray  # (M,) fractional sample index in the primitive
    start: np.ndarray  # (k,) each primitive's first point
    first: np.ndarray  # (k,) global arc coordinate of each primitive's first point
    length: np.ndarray  # (k,) each primitive's arc length
    step0: float  # the step of level 0
    shift: int = 0  # this level's number: its point n is level 0's point n · 2^shift
    dev2: np.ndarray | None = None  # (M,) squared deviation of the smoothed samples; None: 0

    @property
    def garc(self) -> _PerPoint:
        """Global arc coordinate of each point (primitive arcs laid end to end), shape
        (M,), computed for the points asked (``level.garc[ws]``)."""
        return _PerPoint(self, True)

    @property
    def left(self) -> _PerPoint:
        """Arc length from each point to its primitive's end, shape (M,), computed for the
        points asked (``level.left[ws]``)."""
        return _PerPoint(self, False)

    def arc_from_start(self, n: np.ndarray) -> np.ndarray:
        """Arc from a primitive's start to its point number n, as the build formed it:
        ``(n · 2^shift) · step0`` (an exact integer times step0, one rounding)."""
        return (np.asarray(n, dtype=np.int64) << self.shift) * self.step0

    @property
    def counts(self) -> np.ndarray:
        """Points of each primitive, shape (k,)."""
        return np.diff(np.append(self.start, self.prim.size))

    def fits(self, need: float) -> np.ndarray:
        """Whether each point has at least ``need`` of arc left, shape (M,) bool: exactly
        ``left >= need`` (:meth:`first_of`: the first :meth:`fit_counts` of each)."""
        return self.first_of(self.fit_counts(need))

    def first_of(self, c: np.ndarray) -> np.ndarray:
        """Mask (M,) of the first c_p points of each primitive p."""
        runs = np.column_stack([c, self.counts - c]).ravel()
        return np.repeat(np.tile(np.array([True, False]), c.size), runs)

    def fit_counts(self, need: float) -> np.ndarray:
        """Points of each primitive with at least ``need`` of arc left, shape (k,). The arc
        left falls along a primitive (each rounding is monotone), so they are its first c_p:
        c_p estimated from the step, then moved one point at a time while the formula of
        :attr:`left` says otherwise (off by a rounding, at most a point or two)."""
        counts = self.counts
        with np.errstate(invalid="ignore", over="ignore"):
            est = np.floor((self.length - need) / (self.step0 * (1 << self.shift))) + 1.0
        c = np.clip(np.nan_to_num(est, nan=0.0), 0, counts).astype(np.int64)
        while True:  # one more fits: up; the last counted does not: down
            up = np.flatnonzero(c < counts)
            up = up[self.length[up] - self.arc_from_start(c[up]) >= need]
            down = np.flatnonzero(c > 0)
            down = down[self.length[down] - self.arc_from_start(c[down] - 1) < need]
            if up.size == 0 and down.size == 0:
                break
            c[up] += 1
            c[down] -= 1
        return c


class _PerPoint:
    """:attr:`Level.garc` or :attr:`Level.left`: indexed like an array of every point (a
    slice, indices or a mask), computed for the points asked; ``np.asarray`` gives all."""

    __slots__ = ("level", "garc")

    def __init__(self, level: Level, garc: bool) -> None:
        self.level, self.garc = level, garc

    @property
    def shape(self) -> tuple[int]:
        return self.level.prim.shape

    def __len__(self) -> int:
        return self.level.prim.size

    def __getitem__(self, key) -> np.ndarray:
        lv = self.level
        if isinstance(key, slice):
            idx = np.arange(lv.prim.size)[key]
        else:
            idx = np.asarray(key)
            if idx.dtype == bool:
                idx = np.flatnonzero(idx)
        p = lv.prim[idx]
        arc = lv.arc_from_start(idx - lv.start[p])
        # garc: first + arc (IEEE addition commutes); left: length − arc
        return lv.first[p] + arc if self.garc else lv.length[p] - arc

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = self[:]
        return out if dtype is None else out.astype(dtype)


@dataclass(frozen=True)
class ArcIndex:
    """The library resampled at uniform arc length, a pyramid of steps ``step0 · 2ʲ``.

    Built once per bank (:meth:`build`); rigid motions and time scaling leave every
    primitive's arc-length shape unchanged, so one index serves every query.
    """

    step0: float
    levels: tuple[Level, ...]
    x_all: np.ndarray  # sample index of every stored sample, for arc -> time
    garc_all: np.ndarray  # global arc coordinate of every stored sample
    smoothed: bool = False  # whether any primitive was smoothed (levels carry dev2)
    cache: dict = field(default_factory=dict, compare=False, repr=False)
    end_arc: np.ndarray | None = None  # (k,) global arc coordinate of each last sample

    def arc_to_sample(self, g: np.ndarray, prim: np.ndarray | None = None) -> np.ndarray:
        """Fractional sample index at global arc coordinates g (linear between samples);
        with ``prim``, g is first clamped to the end of that primitive (past it the axis
        crosses the gap to the next primitive, whose sample indices start again at 0)."""
        if prim is not None and self.end_arc is not None:
            g = np.minimum(g, self.end_arc[prim])
        i = np.clip(np.searchsorted(self.garc_all, g) - 1, 0, self.garc_all.size - 2)
        g0, g1 = self.garc_all[i], self.garc_all[i + 1]
        f = np.clip((g - g0) / np.where(g1 > g0, g1 - g0, 1.0), 0.0, 1.0)
        return self.x_all[i] + f * (self.x_all[i + 1] - self.x_all[i])

    def sums(self, jb: int, dil: int,
             products: bool | str = True) -> tuple[np.ndarray, np.ndarray, float]:  # fmt: skip
        """Strided prefix sums of level jb for the windows {m + i·dil, i < n}, m = 0, 1, ...

        Rows: the d coordinates, |p|², then (with ``products``) the products p_a·p_b
        (a ≤ b, the squares first), so the sums, the centroid, the radius of gyration and the
        scatter matrix of any window come from two columns:
        Σ_{i<n} f(p_{m+i·dil}) = P[:, m + n·dil] − P[:, m] (P[:, m] sums the earlier points
        of m's phase m mod dil). Built once per (level,
        dilation); without ``products`` (or with the squares alone, ``"squares"``) the first
        rows of sums with more rows when those were built (each row holds the same values
        whichever others are built), else those rows alone: the rotation-invariant bound
        needs the d + 1 rows (2.5x less to build and hold), the per-axis bound of
        ``rotation="none"`` the squares besides (2d + 1 rows of 10 in 3-D: rotation none's
        worst bundled path, seed 103, built 0.17 s of sums on the fine indexes of its short
        pieces, most of it for the cross products only the principal bound reads).

        Round-off: P is a running sum, P_{j+dil} = fl(P_j + f_j), so the difference of two
        entries n steps apart carries only the n roundings between them:
        |error| ≤ (n + 2)·u·max|P| (u = 2⁻⁵³), which ``seeds`` adds to its bounds.

        Returns
        -------
        P : array, shape (c, L)
            c = d + 1 + d(d + 1)/2 rows (d + 1 without ``products``, 2d + 1 with the squares
            alone), L = (⌈M/dil⌉ + 1)·dil columns.
        pmax : array, shape (c,)
            max |P| per row.
        radius : float
            max |p| over the level's points.
        """
        d = self.levels[jb].pts.shape[1]
        rows = d + 1 + len(product_pairs(d, products))
        for have in (True, "squares", False):  # the most rows first: sliced, or exact
            hit = self.cache.get(("s", jb, dil, have))
            if hit is not None and hit[0].shape[0] >= rows:
                if hit[0].shape[0] == rows:
                    return hit
                return hit[0][:rows], hit[1][:rows], hit[2]
        hit = self.cache[("s", jb, dil, products)] = strided_prefix_sums(
            self.levels[jb].pts, dil, products
        )
        return hit

    def x_sums(self, jb: int, dil: int) -> tuple[np.ndarray, float, float]:
        """:func:`~primlib.match._bounds.strided_cumsum` of level jb's sample indices at
        stride dil (the speed-profile bound's input), built once per (level, dilation)."""
        key = ("x", jb, dil)
        hit = self.cache.get(key)
        if hit is None:
            hit = self.cache[key] = strided_cumsum(self.levels[jb].x, dil)
        return hit

    def window_views(self, jb: int, span: int, dil: int) -> tuple[np.ndarray, np.ndarray]:
        """Views (no copy) of level jb's windows of ``span`` points taking every ``dil``-th:
        the points (M', d, K) and the sample indices (M', K); formed once per (level, span,
        dilation) -- making a view costs ~40 µs, as much as scoring a few windows."""
        key = ("w", jb, span, dil)
        hit = self.cache.get(key)
        if hit is None:
            lv = self.levels[jb]
            hit = self.cache[key] = (
                sliding_window_view(lv.pts, span, axis=0)[:, :, ::dil],
                sliding_window_view(lv.x, span)[:, ::dil],
            )
        return hit

    def window_deviation(self, jb: int, n_windows: int, span: int) -> np.ndarray | None:
        """RMS deviation of the smoothed primitive from its samples over the ``span`` level
        points of each window m < n_windows of level jb; None when nothing was smoothed."""
        lv = self.levels[jb]
        if not self.smoothed or lv.dev2 is None:
            return None
        key = ("d", jb)
        cum = self.cache.get(key)
        if cum is None:
            cum = self.cache[key] = np.concatenate([[0.0], np.cumsum(lv.dev2)])
        return np.sqrt(np.maximum(cum[span : span + n_windows] - cum[:n_windows], 0.0) / span)

    @property
    def n_points(self) -> int:
        """Points over all levels (the index's size)."""
        return sum(lv.pts.shape[0] for lv in self.levels)

    @classmethod
    def build(cls, bank: BankIndex, points_per_sample: float = 0.25,
              max_levels: int | None = None) -> ArcIndex:  # fmt: skip
        """Index ``bank`` at ``points_per_sample`` level-0 points per stored sample, at most
        ``max_levels`` levels (default: up to the longest primitive's 16 steps)."""
        # one pass per step over the flat buffer (offsets mark the primitives), no loop over
        # primitives; each level is taken from the one below it (half the points)
        sm = bank.arc_samples()
        pts = sm.points
        smoothed = sm.smoothed
        k = bank.k
        starts_arc, length = sm.starts, sm.length
        total = float(length.sum())
        step0 = max(total / max(points_per_sample * pts.shape[0], 1.0), 1e-300)
        if total <= 0:
            step0 = 1.0
        n_lv0 = np.floor(length / step0 + 1e-9).astype(np.int64) + 1
        # per-primitive values spread to the points by np.repeat (2-3x cheaper than
        # gathering them by ``prim``: a fine index has millions of points)
        # int32 (an index holds at most a few million points): half the memory of int64 for
        # the primitive of every point at every level, and for the local counter
        prim = np.repeat(np.arange(k, dtype=np.int32), n_lv0)
        base = np.concatenate([[0], np.cumsum(n_lv0)])
        local = np.arange(base[-1], dtype=np.int32)
        local -= np.repeat(base[:-1].astype(np.int32), n_lv0)
        # arc -> sample index per primitive: one interp on a globally monotone arc axis, at
        # each point's global arc coordinate first + local·step0 (Level.garc: the same)
        g_samples, sample_idx, gap = sm.garc, sm.x, sm.gap
        first = starts_arc + gap
        g = local * step0
        g += np.repeat(first, n_lv0)
        # not past a primitive's last sample (the arc may overshoot its length by 1e-9)
        end_arc = g_samples[bank.offsets[1:] - 1]
        np.minimum(g, np.repeat(end_arc, n_lv0), out=g)
        x = np.interp(g, g_samples, sample_idx)
        del g
        # a primitive's first point lies a ramp (< 1e-6 of arc) before its first sample on
        # the axis: interpolated across the gap from the previous primitive, it came out at
        # ~1e-3 samples instead of 0
        x[base[:-1]] = 0.0
        p, dev2 = _at_samples(sm, bank.offsets, base, x, smoothed)
        levels = []
        lv = 0
        longest = float(length.max())
        counts = n_lv0
        while True:
            start = base[:-1] if lv == 0 else np.concatenate([[0], np.cumsum(counts)[:-1]])
            levels.append(Level(step0 * (1 << lv), p, prim, x, start, first, length, step0,
                                lv, dev2))  # fmt: skip
            if p.shape[0] <= 2 * k or (1 << lv) * step0 * 16 > longest:
                break
            if max_levels is not None and len(levels) >= max_levels:
                break
            # a mask and np.compress: 2.5x less time than the indices and a gather on the
            # (M, d) points, a little less on the rest
            sel = (local & 1) == 0
            p = np.compress(sel, p, axis=0)
            prim, x = np.compress(sel, prim), np.compress(sel, x)
            dev2 = None if dev2 is None else np.compress(sel, dev2)
            local = np.compress(sel, local)
            local >>= 1
            counts = (counts + 1) // 2
            lv += 1
        return cls(step0, tuple(levels), sample_idx, g_samples, smoothed, end_arc=end_arc)


def _at_samples(sm: ArcSamples, offsets: np.ndarray, base: np.ndarray, x: np.ndarray,
                smoothed: bool) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
    """The samples linear between samples at fractional sample indices ``x``, centred per
    primitive (the mean of its points subtracted), and the squared deviations linear
    between samples when ``smoothed``; primitive i's points are ``base[i]:base[i + 1]``.

    ``x`` is the one interpolation on the arc axis: the samples are linear in x between
    samples, so its integer part is the segment and its fraction the weight. Rows taken in
    increasing order (a sequential read): 3.5x less time than one ``np.interp`` per axis.
    Whole primitives of ~65,536 points at a time (:func:`._reject.row_groups`): the
    segment, weight, lower sample and mean of each group stay in cache, and the only
    arrays of every point formed are the results (each index point was formed with four
    such temporaries, 112 bytes a point, fresh memory a first call pays to fault in).
    """
    n_lv0 = np.diff(base)
    counts = np.diff(offsets)
    pts = sm.points
    p = np.empty((int(base[-1]), pts.shape[1]))
    dev2 = np.empty(p.shape[0]) if smoothed else None
    d2 = sm.deviation * sm.deviation if smoothed else None
    for g0, g1 in row_groups(base):
        r0, r1 = int(base[g0]), int(base[g1])
        n_g = n_lv0[g0:g1]
        seg = np.floor(x[r0:r1]).astype(np.int64)
        # the segment within its primitive: the last sample starts none, and only a
        # primitive's last point can lie on it (x >= 0 holds already)
        last = base[g0 + 1 : g1 + 1] - 1 - r0
        seg[last] = np.minimum(seg[last], counts[g0:g1] - 2)
        f = x[r0:r1] - seg
        seg += np.repeat(offsets[g0:g1], n_g)
        lo = np.take(pts, seg, axis=0)
        seg += 1
        # mode "clip" (every index is in range): the default "raise" buffers ``out``
        out = np.take(pts, seg, axis=0, out=p[r0:r1], mode="clip")
        out -= lo
        out *= f[:, None]
        out += lo
        cent = np.add.reduceat(out, base[g0:g1] - r0, axis=0) / n_g[:, None]
        out -= np.repeat(cent, n_g, axis=0)
        if dev2 is not None:
            lo2 = d2[seg - 1]
            dev2[r0:r1] = lo2 + f * (d2[seg] - lo2)
    return p, dev2


@dataclass(frozen=True)
class ArcSamples:
    """What every arc-length index of a bank is built from (:meth:`of`, once per bank).

    Attributes
    ----------
    points : array, shape (N, d)
        The samples, smoothed like a query (:func:`~primlib.match._smooth.smooth_bank`).
    deviation : array, shape (N,)
        Each one's distance from its stored sample (zeros where not smoothed).
    starts, length : array, shape (k,)
        Each primitive's first and total arc length on the global axis (primitives laid end
        to end, without the gaps).
    garc : array, shape (N,)
        Global arc coordinate of every sample: its primitive's arc plus ``gap`` (a gap of
        4 base steps between primitives, a 1e-12 ramp to keep it strictly increasing).
    x : array, shape (N,)
        Sample index of every sample within its primitive.
    gap : array, shape (k,)
        Offset of each primitive on the global axis.
    max_step : array, shape (k,), or None
        Largest distance between consecutive stored samples per primitive, when no
        primitive was smoothed (else None: the steps above are not the stored ones).
    smoothed : bool
        Whether any sample was moved (any ``deviation`` > 0; read only when
        :func:`~primlib.match._smooth.smooth_bank` returned a copy: the deviations of a
        clean bank are zeros never touched, 16 MB at 1,000 primitives of 2,000 samples).
    """

    points: np.ndarray
    deviation: np.ndarray
    starts: np.ndarray
    length: np.ndarray
    garc: np.ndarray
    x: np.ndarray
    gap: np.ndarray
    max_step: np.ndarray | None = None
    smoothed: bool = False

    @classmethod
    def of(cls, points: np.ndarray, offsets: np.ndarray, base_pps: float) -> ArcSamples:
        """From the usable primitives' samples laid end to end; ``base_pps``: points of the
        base index per sample (its step sets the gap)."""
        pts, dev = smooth_bank(points, offsets)
        n = pts.shape[0]
        counts = np.diff(offsets)
        groups = row_groups(offsets)
        # whole primitives ~65,536 samples at a time (temporaries in cache): each sample's
        # step from the previous one of its primitive (0 at a first sample), summed as
        # (x² + z²) + y², the order np.einsum("ij,ij->i") took before (bit-identical arcs)
        step_in = np.empty(n)
        for g0, g1 in groups:
            r0, r1 = int(offsets[g0]), int(offsets[g1])
            dif = pts[r0 + 1 : r1] - pts[r0 : r1 - 1]
            dif *= dif
            out = step_in[r0 + 1 : r1]
            if dif.shape[1] == 3:
                np.add(dif[:, 0], dif[:, 2], out=out)
                out += dif[:, 1]
            else:
                np.sum(dif, axis=1, out=out)
            np.sqrt(out, out=out)
        step_in[offsets[:-1]] = 0.0  # no arc across primitive boundaries
        cum = np.cumsum(step_in)
        # the largest stored step per primitive (the envelopes' margin), when these are the
        # stored samples themselves
        big = np.maximum.reduceat(step_in, offsets[:-1]) if pts is points else None
        starts = cum[offsets[:-1]]
        length = cum[offsets[1:] - 1] - starts
        total = float(length.sum())
        step = max(total / max(base_pps * n, 1.0), 1e-300) if total > 0 else 1.0
        gap = np.arange(counts.size) * (step * 4.0)  # separates primitives on the axis
        ramp = 1e-12 * max(step, 1.0)
        garc, x = cum, step_in  # their buffers, filled in place
        for g0, g1 in groups:
            r0, r1 = int(offsets[g0]), int(offsets[g1])
            i = np.arange(r0, r1, dtype=float)
            g = garc[r0:r1]
            g += np.repeat(gap[g0:g1], counts[g0:g1])
            g += i * ramp
            i -= np.repeat(offsets[g0:g1].astype(float), counts[g0:g1])
            x[r0:r1] = i
        smoothed = pts is not points and bool(np.any(dev > 0))
        return cls(pts, dev, starts, length, garc, x, gap, big, smoothed)


@dataclass(frozen=True)
class ArcQuery:
    """One query resampled at uniform arc length, and the index level it is searched on.

    ``k`` arc samples at spacing ``step`` (= ``level.step · dil``); windows start at every
    point of ``level`` and take every ``dil``-th point (``span`` points in all).
    """

    index: ArcIndex
    jb: int
    level: Level
    dil: int
    step: float
    ell: float
    u: np.ndarray  # (k,) normalised time of the arc samples within [0, 1]
    qc: np.ndarray  # (k, d) centred arc samples
    sq: np.ndarray | float  # Σ|q̃|², per axis for rotation "z"
    moments: QueryMoments
    duration: float  # query duration in stored samples
    per_axis: bool
    smoothing: float = 0.0  # RMS deviation of the smoothed piece from the path samples
    memo: dict = field(default_factory=dict, compare=False, repr=False)  # per-query constants

    @property
    def k(self) -> int:
        return self.qc.shape[0]

    @property
    def span(self) -> int:
        return (self.k - 1) * self.dil + 1

    @property
    def n_windows(self) -> int:
        return self.level.pts.shape[0] - self.span + 1

    @property
    def tau(self) -> np.ndarray:
        """Normalised time within the piece at each arc sample (the speed profile)."""
        hit = self.memo.get("tau")
        if hit is None:
            hit = self.memo["tau"] = (self.u - self.u[0]) / max(self.u[-1] - self.u[0], 1e-300)
        return hit

    def at_starts(self, start: np.ndarray,
                  need: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
        """The k points (m, k, d) and sample indices (m, k) of the windows starting at
        fractional level positions ``start`` (m,), linear between points, and whether each
        has ``need`` of arc left in its primitive (:attr:`._gates.Gates.need`).

        A window may run past its primitive's last point as far as the gates allow
        (:func:`._gates.overrun`): it then ends there, its points evenly spaced (the points
        past it are another primitive's)."""
        lv, k, top = self.level, self.k, self.level.pts.shape[0] - 1
        p0 = lv.prim[np.clip(np.floor(start).astype(np.int64), 0, top)]
        first = lv.start[p0]
        end = np.append(lv.start[1:], top + 1)[p0] - 1.0  # the primitive's last point
        left = lv.length[p0] - (start - first) * lv.step  # Gates.of's test, on arc
        ok = (start >= first) & (left >= need * (1 - 1e-9))
        gap = np.minimum(end - start, (k - 1) * self.dil) / max(k - 1, 1)  # point to point
        pos = start[:, None] + np.arange(k) * gap[:, None]
        i0 = np.clip(np.floor(pos).astype(np.int64), 0, top - 1)
        f = np.clip(pos - i0, 0.0, 1.0)
        pts = lv.pts[i0] * (1.0 - f[..., None]) + lv.pts[i0 + 1] * f[..., None]
        return pts, lv.x[i0] * (1.0 - f) + lv.x[i0 + 1] * f, ok

    def groups(self, parts: int) -> tuple[tuple[int, int, float], ...]:
        """:func:`~._bounds.speed_groups` of :attr:`tau` (once per query: a screen asks for
        them for every block of windows)."""
        key = ("groups", parts)
        hit = self.memo.get(key)
        if hit is None:
            hit = self.memo[key] = speed_groups(self.tau, parts)
        return hit
