"""Which windows of an index query can hold a stored copy, and each one's gate on the shape
RMSD (:class:`Gates`, used by :mod:`._index_search`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery

__all__ = ["Gates"]


@dataclass(frozen=True)
class Gates:
    """Which windows of a query can hold a stored copy (``valid``: enough arc left in the
    primitive) and each one's gate on the shape RMSD (:meth:`._index_search.IndexSearch.seeds`)."""

    gate: float
    stored: np.ndarray | None  # RMS deviation of each window's smoothed samples, or None
    fits: np.ndarray  # (M,) bool: the windows inside their primitive
    need: float  # arc a window must have left
    over: np.ndarray  # starts (< n_windows) of the windows with ``need`` left, not inside

    @classmethod
    def of(cls, aq: ArcQuery, eps: float) -> Gates:
        # a stored copy starts within half a base step of some window start, which moves
        # every arc sample by at most that: its window's shape RMSD is below the gate; the
        # copy is within eps + smoothing (+ the stored window's own) of what the index holds
        gate = 3.0 * (eps + aq.smoothing) + 0.5 * aq.level.step * (1.0 + 1e-6)
        stored = aq.index.window_deviation(aq.jb, aq.n_windows, aq.span)
        # chord lengths under-estimate arc length a little (more for the stored samples than
        # for the densely sampled query): let a piece reach a primitive's very end. A window
        # inside its primitive has (k - 1)·step > ell - step of arc: it fits. One that runs
        # past the primitive's last point (its last points another primitive's) is scored
        # ending there (:meth:`._arc_index.ArcQuery.at_starts`), apart: ``over``
        lv = aq.level
        need = aq.ell - max(aq.step, 0.02 * aq.ell)
        fit = lv.fit_counts(need)
        inside = np.minimum(np.maximum(lv.counts - aq.span + 1, 0), fit)
        extra = fit - inside  # a few per primitive at most
        over = np.repeat(lv.start + inside, extra) + _ranks(extra)
        return cls(gate, stored, lv.first_of(inside), need, over[over < aq.n_windows])

    @property
    def top(self) -> float:
        return self.gate if self.stored is None else self.gate + 3.0 * float(self.stored.max())

    def at(self, ws: np.ndarray | tuple[int, int]) -> np.ndarray | float:
        if isinstance(ws, tuple):  # a range, sliced (without deviations the gate alone)
            return self.gate if self.stored is None else self.gate + 3.0 * self.stored[slice(*ws)]
        if self.stored is None:
            return np.full(ws.size, self.gate)
        return self.gate + 3.0 * self.stored[ws]

    def valid(self, ws: np.ndarray | tuple[int, int]) -> np.ndarray:
        """Whether each window has ``need`` of arc left (a new array: callers narrow it)."""
        return self.fits[ws[0] : ws[1]].copy() if isinstance(ws, tuple) else self.fits[ws]


def _ranks(c: np.ndarray) -> np.ndarray:
    """0, 1, ..., c_p - 1 for each p in turn."""
    total = int(c.sum())
    return np.arange(total) - np.repeat(np.cumsum(c) - c, c)
