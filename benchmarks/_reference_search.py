"""Exhaustive references for the index search (tests and benchmarks only, not the product).

``scan``
    The index search's windows, every one scored: its lower bounds replaced by zero. Same
    seeds as the pruned search whenever the bounds are bounds.
``grid``
    The time-uniform grid (``primlib.match._grid.GridSearch``) on every piece, not only on
    pieces too short in arc length: every primitive × start × time scale, vectorised.
``loop``
    The grid's candidates, every one resampled and scored by one ``kabsch`` call, no
    bound: the plain per-candidate loop the benchmark times against
    (:func:`every_window_seeds` scores every window with any scorer).
``invariant-bound``
    The index search with the rotation-invariant bound for every rotation family (the
    baseline of the per-axis bounds of ``rotation="none"`` and ``"z"``).

:func:`reference_segment_path` runs the production segmentation with one of them as the
seed finder, so only the seeds differ.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from primlib.match import BankIndex, SearchOptions, kabsch
from primlib.match._bank import as_index
from primlib.match._bounds import half_bound_margin, half_window_bound
from primlib.match._curvature import minus
from primlib.match._grid import GridSearch
from primlib.match._index_search import ArcQuery, IndexSearch
from primlib.match._options import Candidate, PathPiece
from primlib.match._pool import suppress
from primlib.match._segment import resolve_options, segment_with

__all__ = [
    "ScanSearch",
    "LoopSearch",
    "every_window_seeds",
    "GridSearch",
    "InvariantBoundSearch",
    "reference_segment_path",
    "SEARCHES",
]

SEARCHES = ("scan", "grid", "loop", "invariant-bound")


class ScanSearch(IndexSearch):
    """The index search with every window scored (no lower-bound pruning)."""

    name: ClassVar[str] = "scan"
    ball: ClassVar[bool] = False  # every window, not those of a ball query

    def first_bound(self, aq: ArcQuery, ws=None, stride: int = 1) -> np.ndarray:
        if isinstance(ws, tuple):
            return np.zeros(-(-(ws[1] - ws[0]) // stride))
        return np.zeros(aq.n_windows if ws is None else ws.size)

    def second_bound(self, aq: ArcQuery, ws: np.ndarray) -> np.ndarray:
        return np.zeros(ws.size)

    def speed_bound(self, aq: ArcQuery, ws, parts: int = 4) -> np.ndarray:
        return np.zeros(ws[1] - ws[0] if isinstance(ws, tuple) else ws.size)

    def speed_screen(self, aq: ArcQuery, block, tau: float) -> np.ndarray:
        return np.ones(block[1] - block[0] if isinstance(block, tuple) else block.size, dtype=bool)


class InvariantBoundSearch(IndexSearch):
    """The index search with the rotation-invariant half-window bound for every rotation
    family (as before the per-axis bounds of restricted families): the baseline of
    ``bench_match.py --restricted``."""

    name: ClassVar[str] = "invariant-bound"
    ball: ClassVar[bool] = False  # the bounds alone, as before the ball queries too

    def first_bound(self, aq: ArcQuery, ws=None, stride: int = 1) -> np.ndarray:
        psum, pmax, radius = aq.index.sums(aq.jb, aq.dil)
        margin = half_bound_margin(aq.k, aq.qc.shape[1], pmax, radius)
        if isinstance(ws, tuple):  # a range of windows: the columns from its first on
            n = -(-(ws[1] - ws[0]) // stride)
            return half_window_bound(psum[:, ws[0] :], n, aq.dil, aq.moments, margin,
                                     None, stride)  # fmt: skip
        n = aq.n_windows if ws is None else ws.size
        return half_window_bound(psum, n, aq.dil, aq.moments, margin, ws)


class _NamedGrid(GridSearch):
    name: ClassVar[str] = "grid"


class LoopSearch(GridSearch):
    """The same grid as :class:`GridSearch`, every window resampled and scored by one
    Kabsch call, no bound."""

    name: ClassVar[str] = "loop"

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        def loop(pts: np.ndarray, q: np.ndarray) -> np.ndarray:
            return np.array([kabsch(p, q, rotation=self.opts.rotation).rmsd for p in pts])

        return every_window_seeds(self, path, a, b, eps, loop)


def every_window_seeds(grid: GridSearch, path: PathPiece, a: float, b: float, eps: float,
                       score) -> list[Candidate]:  # fmt: skip
    """:meth:`GridSearch.seeds` with every window of every scale resampled and scored by
    ``score(points (m, K, d), query (K, d)) -> rmsd (m,)``: its windows below their gates,
    the ``8·seeds`` best of each scale by (RMSD, primitive, start), then suppression. The
    windows are the grid's: those the piece's turns rule out (``out``,
    :mod:`primlib.match._curvature`) are not among them."""
    k, d = grid.opts.grid_points, grid.bank.points.shape[1]
    q = path.at(np.linspace(a, b, k))
    pool: list[Candidate] = []
    grid.stats.queries += 1
    for whole in grid._scales(path, a, b, eps):
        grid.stats.windows += int(whole.n_start.sum())  # every window of the scale, as the grid
        sc = minus(whole, whole.out, whole)  # the windows the piece's turns leave
        if sc is None:
            continue
        runs = zip(sc.first(), sc.n_start, strict=True)
        m = np.concatenate([np.arange(f, f + n) for f, n in runs])
        prim, x0 = np.repeat(sc.prim, sc.n_start), m * sc.h
        at = ((m[:, None] + np.arange(k)) * sc.h).ravel()
        pts = grid._resample(np.repeat(prim, k), at).reshape(m.size, k, d)
        rmsd = score(pts, q)
        grid.stats.scored += m.size
        ok = np.flatnonzero(rmsd < eps + grid._slack(prim, x0, sc))
        top = ok[np.lexsort((x0[ok], prim[ok], rmsd[ok]))[: 8 * grid.opts.seeds]]
        pool += [Candidate(int(prim[t]), float(x0[t]), float(x0[t] + sc.dur), float(rmsd[t]))
                 for t in top]  # fmt: skip
    return suppress(pool, grid.opts.seeds)


def reference_segment_path(
    bank,
    points: np.ndarray,
    dt: float,
    eps: float,
    search: str,
    *,
    rotation: str = "full",
    time_scale: tuple[float, float] | None = None,
    min_step: float | None = None,
    options: SearchOptions | None = None,
):
    """``segment_path`` with the seeds of reference ``search`` (one of :data:`SEARCHES`)."""
    index: BankIndex = as_index(bank)
    opts = resolve_options(rotation, time_scale, options)
    kinds = {
        "scan": ScanSearch,
        "grid": _NamedGrid,
        "loop": LoopSearch,
        "invariant-bound": InvariantBoundSearch,
    }
    if search not in kinds:
        raise ValueError(f"search: expected one of {', '.join(SEARCHES)}, got {search!r}")
    return segment_with(kinds[search](index, opts), index, points, dt, eps, opts, min_step)
