"""The candidate pool of the best-first search: distinct windows, best first, with ties.

Near-duplicate primitives that differ only in speed profile tie on the window grid, so the
pool keeps, besides the best ``n_best`` distinct windows, every window within ``tie_width``
of the best (at most ``cap``). Its :attr:`CandidatePool.threshold` is the score no window at
or above which can still enter: the best-first search stops when every unscored window's
lower bound reaches it, and the pool is then exactly what scoring every window would give.
"""

from __future__ import annotations

import math

from primlib.match._options import Candidate

__all__ = ["suppress", "CandidatePool", "best_and_ties"]


def suppress(cands: list[Candidate], m: int) -> list[Candidate]:
    """Greedy non-maximum suppression, best score first: one candidate per basin (another of
    the same primitive overlapping it by more than half the shorter is dropped); at most m."""
    out: list[Candidate] = []
    for c in sorted(cands, key=lambda c: c.score):
        same = False
        for o in out:
            if o.prim == c.prim:
                ov = min(o.x1, c.x1) - max(o.x0, c.x0)
                if ov > 0.5 * min(o.x1 - o.x0, c.x1 - c.x0):
                    same = True
                    break
        if not same:
            out.append(c)
            if len(out) == m:
                break
    return out


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
    """

    def __init__(self, n_best: int, cap: int, gate: float, tie_width: float) -> None:
        self.n_best = n_best
        self.cap = cap
        self.gate = gate
        self.tie_width = tie_width
        self.items: list[Candidate] = []
        self.threshold = gate
        self._offered: list[Candidate] = []

    def offer(self, cands: list[Candidate]) -> None:
        """Add scored windows (each below the gate) and update :attr:`threshold`.

        The suppression runs on every window offered so far, not on the pool kept so far:
        greedy suppression is not transitive (a window dropped for overlapping a kept one
        comes back when a better newcomer suppresses that one), so only the whole set gives
        what offering every window at once gives. The search offers at most ``cap`` windows
        per chunk of thousands, so the set stays small.
        """
        self._offered.extend(cands)
        pool = suppress(self._offered, self.cap)
        tie = pool[0].score + self.tie_width if pool else math.inf
        pool = [c for i, c in enumerate(pool) if i < self.n_best or c.score < tie]
        tau = self.gate
        if len(pool) >= self.n_best:
            tau = min(tau, max(pool[self.n_best - 1].score, tie))
        if len(pool) == self.cap:
            tau = min(tau, pool[-1].score)
        self.items = pool
        self.threshold = tau
