"""Best-first draining of many bounded windows: :func:`drain_sorted`.

The index search scores windows in increasing order of their combined lower bound, batch by
batch, until every window left reaches the pool's threshold
(:meth:`._index_search.IndexSearch._drain`). A partial selection of each batch from what is
left (``argpartition``) is cheapest when the threshold soon stops the drain, as it does when
a window matches. When it does not — a short noisy piece that nothing matches: its gate is
wide, the pool never holds a window below it, and the bound of nearly every window stays
under the threshold — the drain visits them all, and one selection per batch over all that is
left costs O(n) a batch: 1.84 M windows drained in 225 batches of 8,192 spent 3.2 s of a
4.9 s search on selecting and compressing (issue 13: a noisy novel path on 1,000 primitives,
``benchmarks/bench_match_novel.py --big --noise 0.001``).

Here the ``FRONT`` × ``chunk`` smallest bounds are selected once and sorted, and the batches are
consecutive slices of them; a slice shorter than its batch (the front's end) joins what is
left before the next front is selected, so each batch is the ``size`` smallest bounds of what
is left, as the selection per batch takes them (up to which of equal bounds comes first).
Bounds are ascending along the front, so the windows of a slice below the threshold are its
head, and the first one at or above it ends the drain: every one after it is at least as
large. Each batch is passed in the order of the windows' positions, as the selection per
batch passes it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery
    from primlib.match._gates import Gates
    from primlib.match._index_search import IndexSearch
    from primlib.match._pool import CandidatePool

__all__ = ["FRONT", "drain_sorted"]

FRONT = 16  # batches of the largest size selected and sorted at once


def drain_sorted(
    search: IndexSearch,
    aq: ArcQuery,
    gates: Gates,
    pool: CandidatePool,
    windows: tuple[np.ndarray, np.ndarray, np.ndarray],
    size: int,
) -> None:
    """Score (``search._batch``) ``windows`` — their indexes, speed bounds and combined bounds
    — in increasing order of the combined bound, ``size`` at a time (doubling after each
    batch up to ``search.chunk``), until the next one reaches the pool's threshold (read
    again before each batch: scoring lowers it) or none is left."""
    rest, lbs, lbc = windows
    cap = search.chunk
    left = np.arange(lbc.size)
    while left.size:
        f = FRONT * cap
        if left.size > f:
            part = np.argpartition(lbc[left], f - 1)
            front, left = left[part[:f]], left[part[f:]]
        else:
            front, left = left, left[:0]
        front = front[np.argsort(lbc[front], kind="stable")]
        i = 0
        while i < front.size and (front.size - i >= size or left.size == 0):
            take = front[i : i + size]
            live = lbc[take] < pool.combined
            last = not live.all()
            take = np.sort(take[live])  # the head of the slice: the bounds ascend
            if take.size:
                search._batch(aq, pool, rest[take], lbs[take], lbc[take], gates.at(rest[take]))
            if last:
                return
            i += take.size
            size = min(2 * size, cap)
        left = np.concatenate([front[i:], left])  # the front's end: the smallest of the rest
