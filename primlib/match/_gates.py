"""Which windows of an index query can hold a stored copy, and each one's gate on the shape
RMSD (:class:`Gates`, used by :mod:`._index_search`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from primlib.match._rough import K_MAX, rough_scales
from primlib.match._rough_diff import DiffRoughness, diff_scales

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery
    from primlib.match._bank import BankIndex
    from primlib.match._options import PathPiece

__all__ = ["Gates", "rough_skip", "scale_ok"]


@dataclass(frozen=True)
class Gates:
    """Which windows of a query can hold a stored copy (``valid``: inside their primitive;
    ``over``: running past its last point with ``need`` of arc left, scored apart by
    :mod:`._ends`) and each one's gate on the shape RMSD
    (:meth:`._index_search.IndexSearch.seeds`)."""

    gate: float
    stored: np.ndarray | None  # RMS deviation of each window's smoothed samples, or None
    fits: np.ndarray  # (M,) bool: the windows inside their primitive
    need: float  # arc a window must have left
    over: np.ndarray  # starts of the windows with ``need`` left, not inside (any < M)

    @classmethod
    def of(cls, aq: ArcQuery, eps: float, skip: np.ndarray | None = None,
           ends: np.ndarray | None = None) -> Gates:  # fmt: skip
        """The gates of query ``aq``; no window of a primitive that ``skip`` (k,) marks
        (one no window of which can be within eps, :func:`._rough.rough_bounds`) valid, and
        of one that ``ends`` (k,) marks (none of whose inside windows can be,
        :mod:`._rough_diff`) only those near its first or last sample (:func:`_near_ends`,
        from the reach :func:`rough_skip` put in ``aq.memo["near"]``)."""
        # a stored copy starts within half a base step of some window start, which moves
        # every arc sample by at most that: its window's shape RMSD is below the gate; the
        # copy is within eps + smoothing (+ the stored window's own) of what the index holds
        gate = 3.0 * (eps + aq.smoothing) + 0.5 * aq.level.step * (1.0 + 1e-6)
        stored = aq.index.window_deviation(aq.jb, aq.n_windows, aq.span)
        # a window inside its primitive has (k - 1)·step > ell - step of arc: it fits. One
        # that runs past the primitive's last point (its last points another primitive's)
        # is scored ending there (:meth:`._arc_index.ArcQuery.at_starts`), apart: ``over``,
        # as far as a copy of another arc length is still within the gate (:func:`overrun`)
        lv = aq.level
        need = aq.ell - overrun(aq.ell, aq.step, gate)
        fit = lv.fit_counts(need)
        inside = np.minimum(np.maximum(lv.counts - aq.span + 1, 0), fit)
        extra = fit - inside  # a few per primitive at most
        if skip is not None:
            inside, extra = np.where(skip, 0, inside), np.where(skip, 0, extra)
        over = np.repeat(lv.start + inside, extra) + _ranks(extra)
        fits = lv.first_of(inside) if ends is None else _near_ends(aq, inside, ends)
        return cls(gate, stored, fits, need, over)

    @property
    def top(self) -> float:
        return self.gate if self.stored is None else self.gate + 3.0 * float(self.stored.max())

    def at(self, ws: np.ndarray | tuple[int, int]) -> np.ndarray | float:
        if isinstance(ws, tuple):  # a range, sliced (without deviations the gate alone)
            return self.gate if self.stored is None else self.gate + 3.0 * self.stored[slice(*ws)]
        if self.stored is None:
            return np.full(ws.size, self.gate)
        return self.gate + 3.0 * self.deviation(ws)

    def deviation(self, ws: np.ndarray) -> np.ndarray:
        """Each window's stored deviation; past the last whole window (the bank's last
        primitive's ``over`` windows) the last whole window's, which holds their points."""
        return self.stored[np.minimum(ws, self.stored.size - 1)]

    def valid(self, ws: np.ndarray | tuple[int, int]) -> np.ndarray:
        """Whether each window lies inside its primitive (a new array: callers narrow it);
        those with ``need`` of arc left that run past its end are :attr:`over`."""
        return self.fits[ws[0] : ws[1]].copy() if isinstance(ws, tuple) else self.fits[ws]


_SLACK = 2  # level points kept past the reach of an end's interval (a copy starts within Δ/2)


def rough_skip(bank: BankIndex, time_scale: tuple[float, float], aq: ArcQuery,
               path: PathPiece, a: float, b: float,
               eps: float) -> tuple[np.ndarray | None, np.ndarray | None]:  # fmt: skip
    """The primitives no window of which can be within eps of the piece's samples (the
    check's, :meth:`._segment._Segmenter.probe`) by its roughness, and those none of whose
    inside windows can (on a large bank, :mod:`._rough_diff`), or None: the arguments of
    :meth:`Gates.of`. The time scales where the others' windows can be go to
    ``aq.memo["scales"]`` (on a large bank those of the windows near a primitive's ends to
    ``aq.memo["near"]``), which :func:`scale_ok` keeps to (a noisy piece)."""
    kc = path.confirm_points(a, b)
    if not 5 <= kc <= K_MAX:
        return None, None
    q = path.at(np.linspace(a, b, kc))
    steps = (b - a) * path.duration / bank.dt
    table = bank.roughness()
    if isinstance(table, DiffRoughness):
        sc = diff_scales(table, q, steps, time_scale, eps)
        if sc is None:
            return None, None
        # the inside windows keep to the first range, those near an end to the second
        skip, ends = sc[2] > sc[3], sc[0] > sc[1]
        aq.memo["scales"] = sc[:2]
        aq.memo["near"] = (*end_reach(aq, bank.offsets), *sc[2:])
        return skip, ends & ~skip
    scales = rough_scales(table, q, steps, time_scale, eps)
    if scales is None:
        return None, None
    aq.memo["scales"] = scales
    return scales[0] > scales[1], None


def scale_ok(aq: ArcQuery, scale: np.ndarray, prim: np.ndarray, ws: np.ndarray | tuple[int, int],
             time_scale: tuple[float, float]) -> np.ndarray:  # fmt: skip
    """Whether each time scale (of window ``ws``, an index array or a range, of primitive
    ``prim``) is in the range, with 10 % slack (the index's screen and its exact test must
    agree on it, :meth:`._index_search.IndexSearch.in_range`): ``time_scale``, or each
    primitive's within it where the piece's roughness narrows it (:func:`rough_skip`; on a
    large bank the windows near a primitive's ends to a range of their own)."""
    lo, hi = aq.memo.get("scales", time_scale)
    if isinstance(lo, np.ndarray):
        lo, hi = lo[prim], hi[prim]
    ok = (scale >= lo / 1.1) & (scale <= hi * 1.1)
    near = aq.memo.get("near")
    if near is not None:
        a, b, lo_e, hi_e = (v[prim] for v in near)
        local = (np.arange(*ws) if isinstance(ws, tuple) else ws) - aq.level.start[prim]
        ok |= ((local < a) | (local >= b)) & (scale >= lo_e / 1.1) & (scale <= hi_e * 1.1)
    return ok


def end_reach(aq: ArcQuery, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per primitive, (a, b): its windows before number a start before its sample 1 and
    those from number b on end past its sample n − 2 (the windows that read a ghost,
    :mod:`._rough_diff`), ``_SLACK`` level points wider; ``offsets``: the bank's (k + 1,)."""
    lv, garc = aq.level, aq.index.garc_all
    last = garc.size - 1
    head = np.floor((garc[np.minimum(offsets[:-1] + 1, last)] - lv.first) / lv.step) + 1
    tail = np.floor((garc[np.maximum(offsets[1:] - 2, 0)] - lv.first) / lv.step) + 1
    return (head + _SLACK).astype(np.int64), (tail - aq.span - _SLACK).astype(np.int64)


def _near_ends(aq: ArcQuery, inside: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mask (M,) of the first ``inside`` windows of each primitive, of those that ``ends``
    marks only the ones near an end (:func:`end_reach`, as :func:`rough_skip` kept it)."""
    a, b = aq.memo["near"][:2]
    a = np.where(ends, np.clip(a, 0, inside), inside)
    b = np.where(ends, np.clip(b, a, inside), inside)
    runs = np.column_stack([a, b - a, inside - b, aq.level.counts - inside]).ravel()
    return np.repeat(np.tile(np.array([True, False, True, False]), a.size), runs)


def overrun(ell: float, step: float, gate: float) -> float:
    """How far past its primitive's last point a window of arc ``ell`` may run: at least a
    step or 2 % (chord lengths under-estimate arc, more for the stored samples than for the
    densely sampled query), and as far as a copy whose arc is shorter by r·ell is within
    ``gate`` of the window of the query's arc at its start, inside a primitive.

    That window's arc sample i (at s_i = i·ell/(k - 1) from the start) lies r·s_i further
    along the curve than the copy's, at most that far in space: r·ell/√3 RMS over the
    samples. The gate keeps such windows inside a primitive up to r = √3·gate/ell; at its
    end the same r is let through (capped at a quarter). Hand-drawn copies of one shape
    differ in arc by 10-20 % (LASA handwriting, ``benchmarks/bench_match_real.py``): with
    2 % alone, a whole demonstration was matched nowhere in the index while the exhaustive
    grid matched it whole.
    """
    return max(step, ell * max(0.02, min(0.25, math.sqrt(3.0) * gate / max(ell, 1e-300))))


def _ranks(c: np.ndarray) -> np.ndarray:
    """0, 1, ..., c_p - 1 for each p in turn."""
    total = int(c.sum())
    return np.arange(total) - np.repeat(np.cumsum(c) - c, c)
