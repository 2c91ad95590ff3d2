"""Blocks of the time-uniform grid's window starts (:class:`._grid.GridSearch`): one lower
bound a block, before any of its windows is resampled, and the windows of a set of blocks
as runs.

A scale of the grid has a window at every start m·h of every primitive long enough: on 1,000
primitives of 2,000 samples up to 7 million at the shortest durations. The stretches of
:mod:`._grid_bound` bound them s at a time from P resampled at every s-th grid point, the
whole bank each scale (~10-30 ms), and under a tight limit nearly all of that is wasted: a
piece at rest (a path that stops) is matched only by the bank's stillest windows. Here the
intervals of the bank are cut in blocks of W and each block's box holds P over it
(:func:`._grid_bound.block_boxes`), so the chords of the windows that start in a block lie
in one box difference and one bound covers them all (:func:`._grid_bound.box_gaps`; module
notes of :mod:`._grid_bound`, *Block bound*). W is the power of 2 at or below (⌊D⌋ − 1)/3,
so that a window ends 3 to 7 blocks on (neighbouring boxes touch: a chord to the next block
may be 0): a block's bound is within about two blocks' motion of the chords' own. Scales of
windows shorter than 7 samples (W would be 1) are searched whole: their blocks would hold
as many bytes as the bank and bound little. Per W the boxes, the chords' length range to the
blocks 3 to 7 on (float32, rounded outwards) and the blocks' order by its least length
(with the ranges in that order) are kept, 48 bytes a block, formed a chunk of blocks at a
time (on 1,000 primitives of 2,000 samples 48 MB at W = 2, half that at each width after).

:class:`StartBlocks` gives a scale's blocks not beyond a limit and their bounds: the blocks
whose least chord length can be near enough to the query's, a prefix of them in that order
(or, where that is most blocks, all of them in block order: no gather and no sort), bounded
by the length range, then the blocks that leave by the box of this duration's 3.
:func:`runs` turns a set of blocks into the runs of windows m0, ..., m0 + n − 1 that start
in them, by the computed m·h every resampling takes, so that every window is in exactly one
block and disjoint sets of blocks never share a window (:func:`without`: a scale less some
runs). The grid searches first 64 blocks whose chords are nearest the query's
(:meth:`StartBlocks.head`), then the others not beyond the limit that leaves
(``GridSearch._scale_seeds``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from primlib.match._grid_bound import (
    above32,
    below32,
    beyond,
    block_boxes,
    box_gaps,
    chord_boxes,
    chord_radii,
    halved_boxes,
    spare,
)

__all__ = ["Scale", "StartBlocks", "runs", "without"]

_GATHER = 16  # blocks (1 / this of them, at most) whose boxes are gathered, not sliced
_CHUNK = 1 << 16  # blocks whose chords' boxes are formed at a time (bounded memory)


@dataclass(frozen=True)
class Scale:
    """One time scale of the grid: the primitives long enough (``prim``), their window
    counts, the duration D and stride h (samples), the cell half-width c, and the stretch of
    intervals a window's slack takes, [j − back, j − back + size) for a start in [j, j + 1)
    (``GridSearch._local_speeds``). With ``m0``, runs of windows m0, ..., m0 + n_start − 1 of
    the primitives ``prim`` (one may have several: :func:`runs`). ``out``: runs of windows
    no match can be in, left out of every search of the scale (:mod:`._curvature`)."""

    prim: np.ndarray
    n_start: np.ndarray
    dur: float
    h: float
    cell: float
    m0: np.ndarray | None = None
    out: Scale | None = None

    def first(self) -> np.ndarray:
        """Each run's first window (0: every window of its primitive)."""
        return np.zeros_like(self.n_start) if self.m0 is None else self.m0

    @property
    def back(self) -> int:
        return math.ceil(self.cell) + 1

    @property
    def size(self) -> int:
        return self.back + math.ceil(self.dur) + math.ceil(self.cell) + 3


@dataclass
class StartBlocks:
    """The bank's blocks of starts, their boxes and chord ranges kept per width W.

    Parameters
    ----------
    points, offsets, speeds : arrays
        The bank's samples, its primitives' first rows (and the end) and each interval's
        speed bound Λ_i (:func:`._grid_bound.speed_bounds`).
    """

    points: np.ndarray
    offsets: np.ndarray
    speeds: np.ndarray
    _box: dict = field(default_factory=dict, init=False, repr=False)
    _radius: dict = field(default_factory=dict, init=False, repr=False)
    _order: dict = field(default_factory=dict, init=False, repr=False)
    _seam: dict = field(default_factory=dict, init=False, repr=False)

    @staticmethod
    def width(dur: float) -> int | None:
        """W for windows of duration ``dur`` samples (None below 7: blocks of one interval
        would hold as many bytes as the bank for the shortest windows, where a block's box
        holds nearly as much motion as the chord)."""
        fd = math.floor(dur)
        return None if fd < 7 else 1 << int(math.log2((fd - 1) / 3.0))

    def ends(self, dur: float) -> tuple[int, int]:
        """The blocks on (first, last) from a window's start block in which a window of
        duration ``dur`` ends (``_grid_bound``, *Block bound*)."""
        fd, width = math.floor(dur), self.width(dur)
        return (fd - 1) // width, 1 + fd // width

    def bounds(self, dur: float, q_chord: np.ndarray, rotation: str, k: int, limit: float,
               rg_q: float, slack: float) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """For windows of duration ``dur`` (7 samples or more) and K = ``k`` points: the
        blocks of :meth:`width` whose bound on ρ is not beyond ``limit``
        (:func:`._grid_bound.beyond`), in block order, and those bounds.

        Every block's bound is first that of its chords to the blocks 3 to 7 on (their
        lengths' range, :meth:`radii`), taken only on the blocks whose least length can be
        near enough to |c_q| (a prefix of the blocks in that order: under a tight limit no
        pass over every block); the blocks it leaves take the larger of it and
        :func:`._grid_bound.box_gaps` of their chords to the 3 blocks a window of this
        duration ends in (and their directions, under ``"none"``; at and before a seam, its
        own parts: :meth:`seams`). Both are over √(2K), bounds on ρ as the stretches' are
        (ρ ≥ g(c_w)/√(2K))."""
        width = self.width(dur)
        near, far = self.radii(width)
        root = math.sqrt(2.0 * k)
        length = float(np.linalg.norm(q_chord))
        # the blocks whose chords can be short enough: a prefix of them by their least
        # length (its bound rounded up to float32, so no such block is left out)
        reach = root * (float(spare(limit, rg_q)) + slack) * (1.0 + 1e-9) + length
        order, ranked, far_ranked = self._order[width]
        n = int(np.searchsorted(ranked, above32(np.array([reach]))[0], side="right"))
        if 2 * n > near.size:  # most: every block in block order (those past the prefix
            wide = _radius_gaps(near, far, length, root)  # are beyond the limit too)
            live = np.flatnonzero(~beyond(wide, limit, rg_q, slack))
            wide = wide[live]
        else:  # (the prefix's length ranges: slices of the ranked copies, no gather)
            wide = _radius_gaps(ranked[:n], far_ranked[:n], length, root)
            live, wide = _in_block_order(order[:n], wide, ~beyond(wide, limit, rg_q, slack),
                                         near.size)  # fmt: skip
        ends = self.ends(dur)
        if live.size <= near.size // _GATHER:
            gap = box_gaps(*self._chords_at(width, live, ends), q_chord, rotation)
        else:  # many: by slices, a chunk of blocks at a time, then each seam's own parts
            lo, hi = self.boxes(width)
            gap = np.empty(live.size)
            cuts = np.searchsorted(live, np.arange(0, near.size + _CHUNK, _CHUNK))
            for j, (c0, c1) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
                if c1 > c0:
                    start = j * _CHUNK
                    c_lo, c_hi = chord_boxes(lo, hi, *ends, start, min(start + _CHUNK, near.size))
                    at = live[c0:c1] - start
                    gap[c0:c1] = box_gaps(c_lo[at], c_hi[at], q_chord, rotation)
            fix = self._near_seams(width, live, ends)
            if fix.size:
                c_lo, c_hi = self._chords_at(width, live[fix], ends)
                gap[fix] = np.maximum(gap[fix], box_gaps(c_lo, c_hi, q_chord, rotation))
        bound = np.maximum(gap / root, wide)
        keep = ~beyond(bound, limit, rg_q, slack)
        return live[keep], bound[keep]

    def seams(self, width: int) -> tuple[np.ndarray, ...]:
        """The blocks of ``width`` intervals where a primitive starts inside (sorted), a mask
        of them over every block, and per such block the boxes (float32, outwards) of its
        last primitive's intervals and of its first's, kept.

        A window of duration D >= 3W + 1 starts in such a block only on its last
        primitive's intervals (on the first's it would run past that primitive's end, a
        primitive wholly inside being shorter than W) and ends in one only on its first's
        (it starts more than W before): the union box of the block, which holds the motion
        of two primitives that need not be near each other, is no bound there."""
        if width not in self._seam:
            n = self.points.shape[0]
            inner = self.offsets[1:-1]
            inner = inner[inner % width != 0]
            block, first_at = np.unique(inner // width, return_index=True)
            last_at = np.append(first_at[1:], inner.size)[: block.size] - 1
            top = np.minimum((block + 1) * width, n)
            starts = self._range_boxes(inner[last_at], top)  # the last primitive's part
            ends = self._range_boxes(block * width, inner[first_at])  # the first's
            mask = np.zeros(self.count(width), dtype=bool)
            mask[block] = True
            self._seam[width] = (block, mask, *starts, *ends)
        return self._seam[width]

    def _range_boxes(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The boxes of the intervals [a_j, b_j) (disjoint, in order, none empty)."""
        if a.size == 0:
            none = np.empty((0, self.points.shape[1]), np.float32)
            return none, none
        idx = np.concatenate([np.arange(x, y) for x, y in zip(a, b, strict=True)])
        at = np.concatenate([[0], np.cumsum(b - a)[:-1]])
        p, v = self.points[idx], self.speeds[idx, None]
        return (below32(np.minimum.reduceat(p - v, at, axis=0)),
                above32(np.maximum.reduceat(p + v, at, axis=0)))  # fmt: skip

    def _near_seams(self, width: int, live: np.ndarray, ends: tuple[int, int]) -> np.ndarray:
        """Positions in ``live`` of the blocks that are seams or end windows in one."""
        block, mask = self.seams(width)[:2]
        if block.size == 0 or live.size == 0:
            return np.empty(0, dtype=np.int64)
        hit = mask[live].copy()
        for off in range(ends[0], ends[1] + 1):
            y = live + off
            ok = (y >= 0) & (y < mask.size)
            hit[ok] |= mask[y[ok]]
        return np.flatnonzero(hit)

    def _chords_at(self, width: int, rows: np.ndarray,
                   ends: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """:func:`._grid_bound.chord_boxes` of the blocks ``rows`` alone (gathered), each
        seam with its own part: its last primitive's box where it is the start block, its
        first's where an end block (:meth:`seams`)."""
        block, mask, s_lo, s_hi, e_lo, e_hi = self.seams(width)
        lo, hi = self.boxes(width)
        nb = lo.shape[0]
        a_lo, a_hi = lo[rows].astype(np.float64), hi[rows].astype(np.float64)
        at = mask[rows]
        j = np.searchsorted(block, rows[at])
        a_lo[at], a_hi[at] = s_lo[j], s_hi[j]
        end_lo = np.full_like(a_lo, np.inf)
        end_hi = np.full_like(a_hi, -np.inf)
        for off in range(ends[0], ends[1] + 1):
            y = rows + off
            ok = np.flatnonzero((y >= 0) & (y < nb))
            y_lo, y_hi = lo[y[ok]].astype(np.float64), hi[y[ok]].astype(np.float64)
            seam = mask[y[ok]]
            j = np.searchsorted(block, y[ok][seam])
            y_lo[seam], y_hi[seam] = e_lo[j], e_hi[j]
            end_lo[ok] = np.minimum(end_lo[ok], y_lo)
            end_hi[ok] = np.maximum(end_hi[ok], y_hi)
        return end_lo - a_hi, end_hi - a_lo

    def count(self, width: int) -> int:
        """The number of blocks of ``width`` intervals."""
        return -(-self.points.shape[0] // width)

    def head(self, dur: float, q_chord: np.ndarray, rotation: str, n: int) -> np.ndarray:
        """``n`` blocks (in block order) likely to hold a scale's best windows: of the 8n
        whose least chord length to the blocks 3 to 7 on is nearest |c_q| (the stillest,
        for a piece at rest), the n of the smallest bounds of :meth:`bounds`."""
        width = self.width(dur)
        self.radii(width)
        order, ranked, _ = self._order[width]
        at = int(np.searchsorted(ranked, float(np.linalg.norm(q_chord))))
        lo = max(0, min(at - 4 * n, order.size - 8 * n))
        rows = np.sort(order[lo : lo + 8 * n])
        gap = box_gaps(*self._chords_at(width, rows, self.ends(dur)), q_chord, rotation)
        if gap.size > n:
            rows = np.sort(rows[np.argpartition(gap, n - 1)[:n]])
        return rows

    def radii(self, width: int) -> tuple[np.ndarray, np.ndarray]:
        """Per block of ``width`` intervals, the least and greatest chord length to the
        blocks 3 to 7 on (:func:`._grid_bound.chord_radii`; at and near seams, of each
        seam's own parts: :meth:`seams`), in float32 rounded down and up, kept."""
        if width not in self._radius:
            lo, hi = self.boxes(width)
            nb = lo.shape[0]
            near, far = np.empty(nb, np.float32), np.empty(nb, np.float32)
            for start in range(0, nb, _CHUNK):
                stop = min(nb, start + _CHUNK)
                n64, f64 = chord_radii(*chord_boxes(lo, hi, 3, 7, start, stop))
                near[start:stop], far[start:stop] = below32(n64), above32(f64)
            seam = self._near_seams(width, np.arange(nb), (3, 7))  # each seam's own parts
            if seam.size:
                n64, f64 = chord_radii(*self._chords_at(width, seam, (3, 7)))
                near[seam] = np.maximum(near[seam], below32(n64))
                far[seam] = np.minimum(far[seam], above32(f64))
            self._radius[width] = near, far
            order = np.argsort(near, kind="stable").astype(np.int32)
            self._order[width] = order, near[order], far[order]
        return self._radius[width]

    def boxes(self, width: int) -> tuple[np.ndarray, np.ndarray]:
        """The boxes of blocks of ``width`` intervals (2: :func:`._grid_bound.block_boxes`,
        twice as wide: :func:`._grid_bound.halved_boxes` of these), kept."""
        if width not in self._box:
            if width == 2:
                self._box[2] = block_boxes(self.points, self.speeds)
            else:
                self._box[width] = halved_boxes(*self.boxes(width // 2))
        return self._box[width]


def _radius_gaps(near: np.ndarray, far: np.ndarray, length: float, root: float) -> np.ndarray:
    """The distance of ``length`` from each range [near, far] of chord lengths, over ``root``."""
    wide = near.astype(np.float64) - length
    if length > 0.0:
        np.maximum(wide, length - far.astype(np.float64), out=wide)
    np.maximum(wide, 0.0, out=wide)
    wide /= root
    return wide


def _in_block_order(rows: np.ndarray, values: np.ndarray, keep: np.ndarray,
                    count: int) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The blocks ``rows[keep]`` (distinct, of ``count`` blocks) in block order, with their
    ``values``: by a sort where they are few, else by a mask over every block (no sort of
    a large part of a million blocks)."""
    at = np.flatnonzero(keep)
    if at.size * 16 < count:
        at = at[np.argsort(rows[at])]
        return rows[at], values[at]
    slot = np.full(count, -1, dtype=np.int32)
    slot[rows[at]] = at
    live = np.flatnonzero(slot >= 0)
    return live, values[slot[live]]


def runs(live: np.ndarray, width: int, offsets: np.ndarray, sc: Scale) -> Scale | None:
    """The windows of scale ``sc`` that start on the intervals of the blocks ``live`` (of
    ``width`` intervals through the bank, distinct), as runs per primitive (a
    :class:`Scale` with ``m0``; None if none).

    A block holds the end of one primitive and the start of the next at most where either
    has windows (W <= D/2 is shorter than a primitive holding one; one wholly inside a block
    holds none). Its intervals [i0, i1) of primitive p (offset o) hold the windows m whose
    computed start m·h (the float every resampling takes) has ⌊m·h⌋ in [i0 − o, i1 − o):
    each window is in exactly one block, so the runs of disjoint sets of blocks never share
    a window. Runs that touch are merged.
    """
    row = np.full(offsets.size - 1, -1)
    row[sc.prim] = np.arange(sc.prim.size)  # each primitive's row in the scale (-1: none)
    b0 = live * width
    b1 = b0 + width
    first = np.searchsorted(offsets, b0, side="right") - 1
    last = np.minimum(np.searchsorted(offsets, b1 - 1, side="right"), offsets.size - 1) - 1
    two = last != first
    p = np.concatenate([first, last[two]])
    b0, b1 = np.concatenate([b0, b0[two]]), np.concatenate([b1, b1[two]])
    keep = row[p] >= 0
    p, b0, b1 = p[keep], b0[keep], b1[keep]
    o = offsets[p]
    n = sc.n_start[row[p]]
    m_lo = np.minimum(_first_at(np.maximum(b0, o) - o, sc.h), n)
    m_hi = np.minimum(_first_at(np.minimum(b1, offsets[p + 1]) - o, sc.h), n)
    ok = m_hi > m_lo
    p, m_lo, m_hi = p[ok], m_lo[ok], m_hi[ok]
    if p.size == 0:
        return None
    order = np.lexsort((m_lo, p))
    p, m_lo, m_hi = p[order], m_lo[order], m_hi[order]
    new = np.ones(p.size, dtype=bool)
    new[1:] = (p[1:] != p[:-1]) | (m_lo[1:] != m_hi[:-1])  # disjoint: merged where they touch
    at = np.flatnonzero(new)
    end = np.append(at[1:], p.size) - 1
    return Scale(p[at], m_hi[end] - m_lo[at], sc.dur, sc.h, sc.cell, m_lo[at])


def _first_at(i: np.ndarray, h: float) -> np.ndarray:
    """The least window m >= 0 whose computed start m·h is at or past the integer i."""
    m = np.maximum(np.ceil(i / h).astype(np.int64), 0)
    m = np.where((m > 0) & ((m - 1) * h >= i), m - 1, m)  # i / h rounded up one too many
    return np.where(m * h < i, m + 1, m)


def without(sc: Scale, taken: Scale | None) -> Scale:
    """The windows of the whole scale ``sc`` (``m0`` None) but those of ``taken`` (sorted by
    primitive and start, disjoint, as :func:`runs` gives them), as runs."""
    if taken is None:
        return sc
    row = np.searchsorted(sc.prim, taken.prim)  # sc.prim is increasing
    end = taken.m0 + taken.n_start
    same = np.zeros(row.size, dtype=bool)
    same[1:] = row[1:] == row[:-1]
    before = np.where(same, np.roll(end, 1), 0)  # each run's gap before it: [before, m0)
    last = np.zeros(sc.prim.size, dtype=np.int64)
    last[row] = end  # the last run's end per primitive (runs in order: the last write wins)
    lo = np.concatenate([before, last])
    hi = np.concatenate([taken.m0, sc.n_start])
    r = np.concatenate([row, np.arange(sc.prim.size)])
    ok = hi > lo
    lo, hi, r = lo[ok], hi[ok], r[ok]
    order = np.lexsort((lo, r))
    lo, hi, r = lo[order], hi[order], r[order]
    return Scale(sc.prim[r], hi - lo, sc.dur, sc.h, sc.cell, lo)
