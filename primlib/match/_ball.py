"""Translation-only candidates from a ball query on half-centroid differences.

Under ``rotation="none"`` the search (:mod:`._index_search`) wants every window whose shape
RMSD to the query is below its gate (:class:`._gates.Gates`); the rest of the score (the
speed term, the time-scale range) only drops more. On a fine index level a short query has
hundreds of thousands to millions of windows, of which some thousands pass: bounding every
one cost ~25 ns a window, ~45 ms a query on 2 million, whatever the answer. This module
finds a superset of the windows below the gate from a k-d tree per (level, dilation), built
once and cached on the index, so a query reads the windows near it alone.

**The bound.** A window is K points w_i = p_{m+i·dil} of the level, the query K centred arc
samples q_i; with R = I the shape RMSD ρ (eq. (1), :mod:`._kabsch`) is that of the best
translation: K·ρ² = min_t Σ_i |D_i − t|² = Σ_i |D_i − D̄|², D_i = w_i − q_i. Take L = 16 of
the indices, S, in two halves S1, S2 of 8 consecutive ones. Dropping the other indices,
moving the centre to D̄_S (which minimises the sum over S) and dropping each half's spread
about its own mean (the variance decomposition) only lower the sum:

    K·ρ² ≥ Σ_{i∈S} |D_i − D̄_S|² ≥ 8·(|D̄_1 − D̄_S|² + |D̄_2 − D̄_S|²) = 4·|D̄_1 − D̄_2|².

The half means of D are those of w minus those of q, so with the descriptor
f = (w̄_1 − w̄_2)/2 (3 numbers in 3-D): 16·|f(w) − f(q)|² ≤ K·ρ², that is

    ρ ≥ √(16/K)·|f(w_S) − f(q_S)|.

It holds for S the first 16 indices and for S the last 16 alike: the last 16 points of
the window at m are the first 16 of the window at m + (K − 16)·dil, so one tree of the
descriptors of every 16-point sub-window serves both. A window below its gate g_m ≤ g (the
largest gate of the query) therefore has both descriptors within g·√(K/16) of the query's:
the candidates are the windows in both balls, valid (:meth:`._gates.Gates.valid`). Nothing
here depends on the time scale or on the smoothing: the inequality is between the window's
points and the query's arc samples exactly as the search scores them, and the gate already
holds every tolerance (arc offset, smoothing, stored deviation). So the windows left out
are ones the search would have dropped at the gate, and the pool, which does not depend on
the order windows are offered in (:mod:`._pool`), comes out the same. (Four quarters, a
9-number descriptor, bound 25 % tighter and left 25 % fewer windows, but its tree cost 3x
as much to build and to search: slower on 1,000 primitives.)

**Round-off.** The search keeps a window whose *computed* ρ̂ is below the gate. ρ̂ comes
from moments of the window and the query (:meth:`._index_search.IndexSearch.score`): sums
of K·d products of magnitude ≤ 4c² (c the largest |coordinate| of the level's points and of
the query; the centred window's ≤ 2c), each off by at most (K·d + 2)·u·K·d·4c² (u = 2⁻⁵³);
K·ρ̂² takes four such terms, and errs besides by the window's centring (≤ 2·K·d·2c·K·u·c)
and by 2·|w̄|·|Σ q̃| ≤ 2c·K·d·4u·c where the computed q̃ do not sum to 0 exactly. In all
|K·ρ̂² − K·ρ²| < 64·(K·d + 2)·K·d·u·c², so |ρ̂ − ρ| ≤ √(64·(K·d + 2)·d·u)·c
(|√a − √b| ≤ √|a − b|). Each descriptor component is a sum of 16 coordinates over 16, off
by less than 16·u·c, a descriptor by √d·16·u·c. The ball's radius is raised by both (twice
the descriptor's: window and query), and by a relative 10⁻⁹ for the tree's own
squared-distance comparison: about 10⁻⁶·c in all, far below any gate.

**When.** Rotation ``"none"``, queries of at least 16 arc samples (shorter ones had too
many windows near them for a tree on 8-point sub-windows to pay) on levels of more than
``search.chunk`` windows (fewer: bounding them all is as cheap), from the second query on a
level on (a level asked once is cheaper to scan than to build a tree for: ~0.2 µs a point,
against ~25 ns a window a query); a ball holding more than an eighth of the windows is
dropped for the plain search (a long straight query, where most windows are straight).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcIndex, ArcQuery
    from primlib.match._gates import Gates
    from primlib.match._index_search import IndexSearch
    from primlib.match._pool import CandidatePool

__all__ = ["SUB", "descriptors", "query_descriptors", "radius", "candidates", "search"]

SUB = 16  # points of the sub-windows described (the fewest arc samples a query has)
HALF = SUB // 2
_U = 2.0**-53
_MOST = 0.125  # a ball holding more of the windows: the plain search


def descriptors(pts: np.ndarray, dil: int) -> np.ndarray:
    """f of every sub-window of ``SUB`` points taking every ``dil``-th of ``pts``: its
    first half's centroid minus its second half's, halved.

    Parameters
    ----------
    pts : array, shape (M, d)
    dil : int

    Returns
    -------
    array, shape (M − (SUB − 1)·dil, d)
    """
    n = pts.shape[0] - (SUB - 1) * dil
    if n <= 0:
        return np.empty((0, pts.shape[1]))
    reach = n + HALF * dil  # half sums are needed from these starts on
    sums = pts[:reach].copy()
    for i in range(1, HALF):
        sums += pts[i * dil : i * dil + reach]
    out = sums[:n] - sums[HALF * dil : HALF * dil + n]
    out *= 1.0 / SUB  # (S1/8 − S2/8)/2
    return out


def query_descriptors(qc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """f of the query's first and last ``SUB`` arc samples, each shape (d,)."""
    return descriptors(qc[:SUB], 1)[0], descriptors(qc[-SUB:], 1)[0]


def radius(gate: float, k: int, d: int, coord: float) -> float:
    """Ball radius for windows of k points below ``gate``: g·√(k/SUB) and the round-off
    margins of the module notes (``coord``: the largest |coordinate| of window and query)."""
    rho = math.sqrt(64.0 * (k * d + 2) * d * _U) * coord
    desc = math.sqrt(d) * 16.0 * _U * coord
    return (gate * math.sqrt(k / SUB) + rho + 2.0 * desc) * (1.0 + 1e-9)


def _tree(index: ArcIndex, jb: int, dil: int):
    """The k-d tree of level jb's sub-window descriptors at dilation dil and the level's
    largest |coordinate|: built on the second call for the pair (None on the first)."""
    key = ("ball", jb, dil)
    hit = index.cache.get(key)
    if hit is None:
        index.cache[key] = hit = [0, None, 0.0]
    if hit[1] is None:
        hit[0] += 1
        if hit[0] < 2:
            return None
        from scipy.spatial import cKDTree

        pts = index.levels[jb].pts
        hit[1] = cKDTree(descriptors(pts, dil), leafsize=32, balanced_tree=False,
                         compact_nodes=False)  # fmt: skip
        hit[2] = float(np.abs(pts).max()) if pts.size else 0.0
    return hit[1], hit[2]


def candidates(index: ArcIndex, aq: ArcQuery, gate: float, n_most: int) -> np.ndarray | None:
    """Sorted starts of the windows (< ``aq.n_windows``) whose two sub-window descriptors
    lie within the ball of the largest gate ``gate`` (a superset of the windows below it,
    module notes); None for fewer than ``SUB`` arc samples, when no tree is built for the
    level yet, or when the first ball holds more than ``n_most``."""
    n, k = aq.n_windows, aq.k
    got = None if k < SUB else _tree(index, aq.jb, aq.dil)
    if got is None:
        return None
    tree, coord = got
    f1, f2 = query_descriptors(aq.qc)
    r = radius(gate, k, aq.qc.shape[1], max(coord, float(np.abs(aq.qc).max())))
    first = np.asarray(tree.query_ball_point(f1, r, return_sorted=False), dtype=np.int64)
    first = first[first < n]
    if first.size > n_most:
        return None
    last = np.asarray(tree.query_ball_point(f2, r, return_sorted=False), dtype=np.int64)
    last -= (k - SUB) * aq.dil  # the window whose last SUB points these are
    last = last[(last >= 0) & (last < n)]
    seen = np.zeros(n, dtype=bool)
    seen[first] = True
    out = last[seen[last]]
    out.sort()
    return out


def search(search: IndexSearch, aq: ArcQuery, gates: Gates, pool: CandidatePool) -> bool:
    """Fill ``pool`` from the windows of the balls (:func:`candidates`), valid, bounded and
    drained best-first as :meth:`._index_search.IndexSearch._few` does every window;
    False (the pool untouched) where the ball does not apply (module notes)."""
    if not search.ball or search.opts.rotation != "none" or aq.n_windows <= search.chunk:
        return False
    ws = candidates(aq.index, aq, gates.top, int(_MOST * aq.n_windows))
    if ws is None:
        return False
    ws = ws[gates.valid(ws)]
    search.stats.windows += ws.size
    search.stats.bounded += ws.size
    if ws.size == 0:
        return True
    lbs = search.speed_bound(aq, ws)
    lb1 = search.first_bound(aq, ws)
    lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
    keep = lb1 < gates.at(ws)
    search._drain(aq, gates, pool, ws[keep], lbs[keep], lbc[keep], True)
    return True
