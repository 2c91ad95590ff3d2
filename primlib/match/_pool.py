"""The candidate pool of the best-first search: distinct windows, best first, with ties.

Near-duplicate primitives that differ only in speed profile tie on the window grid, so the
pool keeps, besides the best ``n_best`` distinct windows, every window within ``tie_width``
of the best (at most ``cap``). A window is *distinct* when greedy suppression in order of
score keeps it (:func:`suppress`: one window per basin); equal scores are taken in order of
the windows' keys, so the pool does not depend on the order windows are offered in. Its
:attr:`CandidatePool.combined` is the score no window at or above which can still enter:
the best-first search stops when every unscored window's lower bound reaches it (or the
gate), and the pool is then exactly what scoring every window would give.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from typing import TYPE_CHECKING

import numpy as np

from primlib.match._options import Candidate

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery
    from primlib.match._index_search import IndexSearch

__all__ = ["suppress", "CandidatePool", "best_and_ties", "reshift"]

_SHIFTS = np.linspace(-0.5, 0.5, 5)  # sub-step re-scoring of the pool (reshift), in base steps


def _suppressed_order(prim, x0, x1, order, m: int) -> list[int]:
    """Positions (in ``order``, best first) that greedy suppression keeps; at most m.

    A piece is dropped when it overlaps a kept piece of the same primitive by more than half
    the shorter (:func:`_greedy`).
    """
    order = np.asarray(order, dtype=np.int64)
    lo_, hi_ = np.asarray(x0, dtype=float)[order], np.asarray(x1, dtype=float)[order]
    pr, lo, hi, at = np.asarray(prim)[order].tolist(), lo_.tolist(), hi_.tolist(), order.tolist()
    return [at[i] for i in _greedy(pr, lo, hi, 0, [], m, _ordinary(lo_, hi_))[0]]


def _ordinary(lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether every piece's length hi − lo is >= 0 (the search forms no other; a nan is
    not): :func:`_greedy` may then compare a piece with the kept pieces near it alone."""
    return bool(np.all(hi - lo >= 0))


def _greedy(pr: list, lo: list, hi: list, start: int, kept: list[int], m: int,
            ordinary: bool) -> tuple[list[int], int]:  # fmt: skip
    """Greedy suppression of the pieces [lo_i, hi_i] of primitives pr_i, taken in list
    order (best first), resumed at ``start``: ``kept`` are the positions before it that it
    keeps (its decisions there depend only on the pieces before them). Returns the kept
    positions (at most m) and how many positions are decided (up to the m-th kept one).

    Plain Python on lists (numpy scalars cost ~10x more per item here). A kept piece
    [o0, o1] of length ow suppresses [lo, hi] (length w) when min(o1, hi) − max(o0, lo) >
    0.5·min(w, ow). With every length >= 0 (``ordinary``) that needs the two to intersect
    (o0 < hi and o1 > lo; otherwise the overlap is <= 0, exactly, in floating point too),
    so a piece is compared only with the kept pieces of its primitive starting before hi
    (sorted by start), from the latest down, until a start lies more than the longest kept
    length (plus a round-off margin: o1 <= o0 + ow·(1 + 2u)) before lo: every earlier one
    ends before lo. The same comparisons decide, so the same pieces are kept; otherwise
    every kept piece of the primitive is compared.
    """
    if not ordinary:
        return _greedy_plain(pr, lo, hi, start, kept, m)
    boxes: dict[int, list] = {}  # primitive -> [kept starts (sorted), pieces, longest length]
    for i in kept:
        p, a, b = pr[i], lo[i], hi[i]
        box = boxes.setdefault(p, [[], [], 0.0])
        at = bisect_left(box[0], a)
        box[0].insert(at, a)
        box[1].insert(at, (a, b, b - a))
        box[2] = max(box[2], b - a)
    if len(kept) >= m:
        return kept[:m], kept[m - 1] + 1
    for i in range(start, len(pr)):
        p, a, b = pr[i], lo[i], hi[i]
        w = b - a
        box = boxes.get(p)
        if box is None:
            boxes[p] = [[a], [(a, b, w)], w]
        else:
            starts, pieces, widest = box
            stop = a - widest - 1e-9 * (widest + abs(a) + 1.0)
            suppressed, j = False, bisect_left(starts, b)
            while j:
                j -= 1
                o0, o1, ow = pieces[j]
                if o0 < stop:
                    break
                if (o1 if o1 < b else b) - (o0 if o0 > a else a) > 0.5 * (w if w < ow else ow):
                    suppressed = True
                    break
            if suppressed:
                continue
            at = bisect_left(starts, a)
            starts.insert(at, a)
            pieces.insert(at, (a, b, w))
            if w > widest:
                box[2] = w
        kept.append(i)
        if len(kept) == m:
            return kept, i + 1
    return kept, len(pr)


def _greedy_plain(pr: list, lo: list, hi: list, start: int, kept: list[int],
                  m: int) -> tuple[list[int], int]:  # fmt: skip
    """:func:`_greedy` comparing each piece with every kept piece of its primitive."""
    boxes: dict[int, list[tuple[float, float, float]]] = {}
    for i in kept:
        boxes.setdefault(pr[i], []).append((lo[i], hi[i], hi[i] - lo[i]))
    if len(kept) >= m:
        return kept[:m], kept[m - 1] + 1
    for i in range(start, len(pr)):
        a, b = lo[i], hi[i]
        w = b - a
        same = boxes.setdefault(pr[i], [])
        for o0, o1, ow in same:
            if (o1 if o1 < b else b) - (o0 if o0 > a else a) > 0.5 * (w if w < ow else ow):
                break
        else:
            same.append((a, b, w))
            kept.append(i)
            if len(kept) == m:
                return kept, i + 1
    return kept, len(pr)


def suppress(cands: list[Candidate], m: int) -> list[Candidate]:
    """Greedy non-maximum suppression, best score first: one candidate per basin (another of
    the same primitive overlapping it by more than half the shorter is dropped); at most m."""
    order = sorted(range(len(cands)), key=lambda i: cands[i].score)
    prim = [c.prim for c in cands]
    x0 = [c.x0 for c in cands]
    x1 = [c.x1 for c in cands]
    return [cands[i] for i in _suppressed_order(prim, x0, x1, order, m)]


def best_and_ties(cands: list[Candidate], m: int, width: float) -> list[Candidate]:
    """The first m of ``cands`` (sorted best first) and every later one scoring below the
    best's score + ``width``."""
    if not cands:
        return []
    tie = cands[0].score + width
    return [c for i, c in enumerate(cands) if i < m or c.score < tie]


class CandidatePool:
    """Best distinct windows found so far (see the module notes).

    Parameters
    ----------
    n_best : int
        Distinct windows always kept.
    cap : int
        Most windows kept in all.
    gate : float
        No window scoring at or above the gate is a candidate.
    tie_width : float
        Windows within this of the best are kept besides the best ``n_best``.

    Attributes
    ----------
    keys : array of int
        Each item's key (the search's window index).
    combined : float
        No window scoring at or above it can enter the pool (inf until ``n_best`` are in).
    threshold : float
        min(gate, combined).
    """

    def __init__(self, n_best: int, cap: int, gate: float, tie_width: float) -> None:
        self.n_best = n_best
        self.cap = cap
        self.gate = gate
        self.tie_width = tie_width
        self._items: list[Candidate] | None = []
        self._kept: tuple = ()
        self.keys = np.zeros(0, dtype=np.int64)
        self.combined = math.inf
        self.threshold = gate
        self._cols = [np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
                      np.zeros(0, dtype=np.int64)]  # fmt: skip
        self._count = 0
        # the columns in order (score, then key), how many of them the suppression has
        # decided, and which of those it keeps (before the ties are cut)
        self._decided = 0
        self._greedy: list[int] = []

    @property
    def items(self) -> list[Candidate]:
        """The pool, best first (formed when asked for: a search offers several batches
        and reads the pool once)."""
        if self._items is None:
            kept, pr, a, b, sc = self._kept
            self._items = [Candidate(int(pr[i]), float(a[i]), float(b[i]), float(sc[i]))
                           for i in kept]  # fmt: skip
        return self._items

    def offer(self, cands: list[Candidate]) -> None:
        """Add scored windows (each below the gate), keyed in the order offered."""
        n = len(cands)
        keys = np.arange(self._count, self._count + n, dtype=np.int64)
        self.offer_arrays(np.array([c.score for c in cands], dtype=float),
                          np.array([c.prim for c in cands], dtype=np.int64),
                          np.array([c.x0 for c in cands], dtype=float),
                          np.array([c.x1 for c in cands], dtype=float), keys)  # fmt: skip

    def offer_arrays(self, score, prim, x0, x1, keys) -> None:
        """Add scored windows (each below the gate) as arrays, and update the thresholds.

        The suppression runs on every window offered so far that can still matter (those
        above :attr:`combined` cannot: they come after the whole pool in score order), not
        on the pool kept so far: greedy suppression is not transitive (a window dropped for
        overlapping a kept one comes back when a better newcomer suppresses that one).
        """
        self._count += len(keys)
        before = self._cols[0].size
        cols = [np.concatenate([c, np.asarray(v)]) for c, v in
                zip(self._cols, (score, prim, x0, x1, keys), strict=True)]  # fmt: skip
        order = np.lexsort((cols[4], cols[0]))
        new = np.flatnonzero(order >= before)
        # the kept columns are in order already: the decisions before the first newcomer
        # (and before the last run stopped) stand, the suppression resumes there
        start = min(int(new[0]) if new.size else order.size, self._decided)
        if new.size:
            cols = [c[order] for c in cols]
        sc, pr, a, b, ky = cols
        before_start = [i for i in self._greedy if i < start]
        greedy, self._decided = _greedy(pr.tolist(), a.tolist(), b.tolist(), start,
                                        before_start, self.cap, _ordinary(a, b))  # fmt: skip
        self._greedy = list(greedy)
        kept = greedy
        if kept:
            tie = sc[kept[0]] + self.tie_width
            kept = [i for j, i in enumerate(kept) if j < self.n_best or sc[i] < tie]
        tau = math.inf
        if len(kept) >= self.n_best:
            tau = max(float(sc[kept[self.n_best - 1]]), tie)
        if len(kept) == self.cap:
            tau = min(tau, float(sc[kept[-1]]))
        self._kept, self._items = (kept, pr, a, b, sc), None  # items: formed when asked for
        self.keys = ky[kept] if kept else np.zeros(0, dtype=np.int64)
        self.combined = tau
        self.threshold = min(self.gate, tau)
        if math.isfinite(tau):  # those above tau: the last in order
            live = int(np.count_nonzero(sc <= tau))
            cols = [c[:live] for c in cols]
            self._decided = min(self._decided, live)
            self._greedy = [i for i in self._greedy if i < live]
        self._cols = cols


def reshift(search: IndexSearch, aq: ArcQuery, pool: CandidatePool, eps: float,
            need: float) -> list[Candidate]:  # fmt: skip
    """The index search's seeds from its pool (:class:`._index_search.IndexSearch`): the
    pool re-scored at sub-step shifts of its starts (the window grid puts a stored copy up
    to half a base step from a window start), each window's best kept; the best ``seeds``
    and every window within √2·(3·eps + Δ_b/8) of the best are the seeds."""
    base = pool.keys.astype(float)
    r, x0 = search.score_shifted(aq, (base[:, None] + _SHIFTS).ravel(), need)
    r, x0 = r.reshape(base.size, -1), x0.reshape(base.size, -1)
    best = np.argmin(r, axis=1)
    g0 = aq.level.garc[pool.keys] + _SHIFTS[best] * aq.level.step
    x_end = aq.index.arc_to_sample(g0 + aq.ell, aq.level.prim[pool.keys])
    rows = np.arange(base.size)
    rb, xb = r[rows, best], x0[rows, best]
    live = np.flatnonzero(np.isfinite(rb)).tolist()  # one array op each, not per item
    rb, xb, xe = rb.tolist(), xb.tolist(), x_end.tolist()
    items = pool.items
    kept = suppress([Candidate(items[i].prim, xb[i], xe[i], rb[i]) for i in live],
                    search.pool_cap)  # fmt: skip
    # a stored copy now starts within an eighth of a base step of a shift: it scores
    # below √2·(3·eps + Δ_b/8); every window within that of the best may be it
    width = math.sqrt(2.0) * (3.0 * eps + 0.125 * aq.level.step)
    return best_and_ties(kept, search.opts.seeds, width)
