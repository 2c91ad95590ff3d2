"""Which windows of an index query can hold a stored copy, and each one's gate on the shape
RMSD (:class:`Gates`, used by :mod:`._index_search`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery

__all__ = ["Gates"]


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
    def of(cls, aq: ArcQuery, eps: float, skip: np.ndarray | None = None) -> Gates:
        """The gates of query ``aq``; no window of a primitive that ``skip`` (k,) marks
        (one no window of which can be within eps, :func:`._rough.rough_bounds`) valid."""
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
        return cls(gate, stored, lv.first_of(inside), need, over)

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
