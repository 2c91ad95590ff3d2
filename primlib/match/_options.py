"""Small records the search passes around: options, candidates, the query path, counters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib.defaults import TIME_SCALE
from primlib.match._interp import cubic_at

__all__ = ["SearchOptions", "Candidate", "PathPiece", "SearchStats", "SeedMemo"]


@dataclass(frozen=True)
class SearchOptions:
    """Knobs of the search, documented in the notes of ``primlib.match._index_search``.

    Attributes
    ----------
    rotation : {"full", "z", "none"}
        Rotation family: any proper rotation, rotations about the z axis, or none.
    time_scale : (float, float)
        Allowed primitive duration / segment duration
        (default :data:`primlib.defaults.TIME_SCALE`).
    grid_points : int
        K of the time-uniform grid (used for pieces too short in arc length to index, and
        for every piece at a fixed time scale on a small bank).
    scale_ratio : float
        Largest ratio between neighbouring time scales of that grid.
    seeds : int
        Seeds refined per query (distinct basins, best first).
    refine_points : int
        Uniform-time points used by the continuous refinement.
    """

    rotation: str = "full"
    time_scale: tuple[float, float] = TIME_SCALE
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
        """Points of the check: the path's own samples in [a, b] (cuts lie on samples)."""
        return int(max(round((b - a) * (self.n - 1)) + 1, 2))


@dataclass
class SearchStats:
    """Counters of one segmentation's searches (reported in ``Match.info``)."""

    windows: int = 0  # candidates considered
    bounded: int = 0  # candidates past the cheap first bound (index search)
    scored: int = 0  # candidates scored exactly
    queries: int = 0


@dataclass
class SeedMemo:
    """One whole search's seeds, kept for the same query asked again: the piece [a, b] of
    ``path`` (the object itself) at ``eps``, the first seeds, whether the piece is loose
    (the grid's seeds may be asked after them) and those (None until asked)."""

    path: PathPiece
    a: float
    b: float
    eps: float
    first: tuple[Candidate, ...]
    loose: bool
    more: tuple[Candidate, ...] | None = None

    def holds(self, path: PathPiece, a: float, b: float, eps: float) -> bool:
        """Whether this is the memo of that query."""
        return self.path is path and (self.a, self.b, self.eps) == (a, b, eps)
