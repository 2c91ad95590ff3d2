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

import numpy as np

from primlib.match._options import Candidate

__all__ = ["suppress", "CandidatePool", "best_and_ties"]


def _suppressed_order(prim, x0, x1, order, m: int) -> list[int]:
    """Positions (in ``order``, best first) that greedy suppression keeps; at most m.

    A piece is dropped when it overlaps a kept piece of the same primitive by more than half
    the shorter (:func:`_greedy`).
    """
    order = np.asarray(order, dtype=np.int64)
    pr = np.asarray(prim)[order].tolist()
    lo = np.asarray(x0, dtype=float)[order].tolist()
    hi = np.asarray(x1, dtype=float)[order].tolist()
    at = order.tolist()
    return [at[i] for i in _greedy(pr, lo, hi, 0, [], m)[0]]


def _greedy(pr: list, lo: list, hi: list, start: int, kept: list[int],
            m: int) -> tuple[list[int], int]:  # fmt: skip
    """Greedy suppression of the pieces [lo_i, hi_i] of primitives pr_i, taken in list
    order (best first), resumed at ``start``: ``kept`` are the positions before it that it
    keeps (its decisions there depend only on the pieces before them). Returns the kept
    positions (at most m) and how many positions are decided (up to the m-th kept one).

    Plain Python on lists (numpy scalars cost ~10x more per item here); each piece is
    compared only with the kept pieces that can overlap it (:class:`_Kept`), not with every
    kept piece of its primitive: the same comparisons decide, so the same pieces are kept.
    """
    boxes: dict[int, _Kept] = {}
    for i in kept:
        boxes.setdefault(pr[i], _Kept()).admits(lo[i], hi[i])
    if len(kept) >= m:
        return kept[:m], kept[m - 1] + 1
    for i in range(start, len(pr)):
        box = boxes.get(pr[i])
        if box is None:
            box = boxes[pr[i]] = _Kept()
        if box.admits(lo[i], hi[i]):
            kept.append(i)
            if len(kept) == m:
                return kept, i + 1
    return kept, len(pr)


class _Kept:
    """The kept pieces of one primitive, sorted by start, for :func:`_suppressed_order`.

    A piece [o0, o1] of length ow = o1 − o0 suppresses [lo, hi] (length w) when
    min(o1, hi) − max(o0, lo) > 0.5·min(w, ow). Where both lengths are >= 0 that needs the
    two to intersect (o0 < hi and o1 > lo: otherwise the overlap is <= 0, exactly, in
    floating point too), so only the kept pieces starting before hi are read, from the
    latest start down, until a start lies more than the longest kept length (plus a
    round-off margin) before lo: every earlier one ends before lo. Pieces of negative
    length (not formed by the search, but allowed) are compared with every kept piece, and
    every kept one of negative length with every piece, as before.
    """

    __slots__ = ("starts", "pieces", "widest", "odd")

    def __init__(self) -> None:
        self.starts: list[float] = []
        self.pieces: list[tuple[float, float, float]] = []  # (start, end, length)
        self.widest = 0.0
        self.odd: list[tuple[float, float, float]] = []  # those of negative length

    def admits(self, lo: float, hi: float) -> bool:
        """Whether no kept piece suppresses [lo, hi]; if so it is kept."""
        w = hi - lo
        if w < 0 or w != w:
            near = self.pieces
        else:
            near = self._near(lo, hi)
        for group in (near, self.odd):
            for o0, o1, ow in group:
                ov = (o1 if o1 < hi else hi) - (o0 if o0 > lo else lo)
                if ov > 0.5 * (w if w < ow else ow):
                    return False
        if w >= 0:
            at = bisect_left(self.starts, lo)
            self.starts.insert(at, lo)
            self.pieces.insert(at, (lo, hi, w))
            if w > self.widest:
                self.widest = w
        else:
            self.odd.append((lo, hi, w))
        return True

    def _near(self, lo: float, hi: float) -> list[tuple[float, float, float]]:
        """The kept pieces (length >= 0) that can intersect [lo, hi]: starting before hi,
        and not more than the longest length before lo (a start o0 below that has
        o1 <= o0 + widest·(1 + 2u) < lo)."""
        starts, pieces = self.starts, self.pieces
        i = bisect_left(starts, hi)
        stop = lo - self.widest - 1e-9 * (self.widest + abs(lo) + 1.0)
        j = i
        while j > 0 and starts[j - 1] >= stop:
            j -= 1
        return pieces[j:i]


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
                                        before_start, self.cap)  # fmt: skip
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
