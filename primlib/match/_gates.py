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
    fits: np.ndarray  # (M,) bool: the level's points with ``need`` of arc left
    need: float  # arc a window must have left

    @classmethod
    def of(cls, aq: ArcQuery, eps: float) -> Gates:
        # a stored copy starts within half a base step of some window start, which moves
        # every arc sample by at most that: its window's shape RMSD is below the gate; the
        # copy is within eps + smoothing (+ the stored window's own) of what the index holds
        gate = 3.0 * (eps + aq.smoothing) + 0.5 * aq.level.step * (1.0 + 1e-6)
        stored = aq.index.window_deviation(aq.jb, aq.n_windows, aq.span)
        # chord lengths under-estimate arc length a little (more for the stored samples than
        # for the densely sampled query): let a piece reach a primitive's very end
        need = aq.ell - max(aq.step, 0.02 * aq.ell)
        return cls(gate, stored, aq.level.fits(need), need)

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
