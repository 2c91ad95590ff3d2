"""The candidate pool of the best-first search: distinct windows, best first, with ties.

The pool is greedy suppression (:func:`suppress`: one window per basin) run on the ``cap``
best-scoring windows of all (equal scores in order of the windows' keys, so the pool does
not depend on the order windows are offered in). Near-duplicate primitives that differ only
in speed profile tie on the window grid, so it keeps, besides the best ``n_best`` distinct
windows, every window within ``tie_width`` of the best. Its
:attr:`CandidatePool.combined` is the score no window at or above which can still enter:
the best-first search stops when every unscored window's lower bound reaches it (or the
gate), and the pool is then exactly what scoring every window would give.
"""

from __future__ import annotations

import math

import numpy as np

from primlib.match._options import Candidate

__all__ = ["suppress", "CandidatePool", "best_and_ties"]


def _suppressed_order(prim, x0, x1, order, m: int) -> list[int]:
    """Positions (in ``order``, best first) that greedy suppression keeps; at most m.

    A piece is dropped when it overlaps a kept piece of the same primitive by more than half
    the shorter. Plain Python on lists (numpy scalars cost ~10x more per item here).
    """
    order = np.asarray(order, dtype=np.int64)
    pr = np.asarray(prim)[order].tolist()
    lo_ = np.asarray(x0, dtype=float)[order].tolist()
    hi_ = np.asarray(x1, dtype=float)[order].tolist()
    idx = order.tolist()
    kept: dict[int, list[tuple[float, float]]] = {}
    out: list[int] = []
    for i, p in enumerate(pr):
        lo, hi = lo_[i], hi_[i]
        same = kept.get(p)
        if same is None:
            kept[p] = [(lo, hi)]
        else:
            w = hi - lo
            hit = False
            for o0, o1 in same:
                ov = (o1 if o1 < hi else hi) - (o0 if o0 > lo else lo)
                if ov > 0.5 * (w if w < o1 - o0 else o1 - o0):
                    hit = True
                    break
            if hit:
                continue
            same.append((lo, hi))
        out.append(idx[i])
        if len(out) == m:
            break
    return out


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
    items : list of Candidate
        The pool, best first.
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
        self.items: list[Candidate] = []
        self.keys = np.zeros(0, dtype=np.int64)
        self.combined = math.inf
        self.threshold = gate
        self._cols = [np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0),
                      np.zeros(0, dtype=np.int64)]  # fmt: skip
        self._count = 0

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

        Only the ``cap`` best-scoring windows offered so far are kept (equal scores in
        order of their keys), and the suppression runs on those: the pool is what suppressing
        the ``cap`` best windows of all gives, whatever order they come in.
        """
        self._count += len(keys)
        cols = [np.concatenate([c, np.asarray(v)]) for c, v in
                zip(self._cols, (score, prim, x0, x1, keys), strict=True)]  # fmt: skip
        order = np.lexsort((cols[4], cols[0]))[: self.cap]
        cols = [c[order] for c in cols]
        sc, pr, a, b, ky = cols
        kept = _suppressed_order(pr, a, b, np.arange(sc.size), self.cap)
        if kept:
            tie = sc[kept[0]] + self.tie_width
            kept = [i for j, i in enumerate(kept) if j < self.n_best or sc[i] < tie]
        tau = math.inf
        if len(kept) >= self.n_best:
            tau = max(float(sc[kept[self.n_best - 1]]), tie)
        if sc.size == self.cap:
            # a newcomer at or above the worst of the best cap windows never enters them
            tau = min(tau, float(sc[-1]))
        self.items = [Candidate(int(pr[i]), float(a[i]), float(b[i]), float(sc[i])) for i in kept]
        self.keys = ky[kept] if kept else np.zeros(0, dtype=np.int64)
        self.combined = tau
        self.threshold = min(self.gate, tau)
        self._cols = cols
