"""Translation-only candidates from ball queries on half-centroid differences.

Under ``rotation="none"`` the search (:mod:`._index_search`) wants the windows whose shape
RMSD to the query is below its gate (:class:`._gates.Gates`) and whose combined score is
below the pool's threshold (:mod:`._pool`), which is never below the shape RMSD. On a fine
index level a short query has hundreds of thousands to millions of windows: bounding every
one cost ~25 ns a window, ~45 ms a query on 2 million, whatever the answer. This module
finds a superset of the windows with a shape RMSD below a radius ρ from a k-d tree per
(level, dilation, sub-window size), built once and cached on the index, so a query reads
the windows near it alone.

**The bound.** A window is K points w_i = p_{m+i·dil} of the level, the query K centred arc
samples q_i; with R = I the shape RMSD ρ (eq. (1), :mod:`._kabsch`) is that of the best
translation: K·ρ² = min_t Σ_i |D_i − t|² = Σ_i |D_i − D̄|², D_i = w_i − q_i. Take L ≤ K of
the indices, S, in two halves S1, S2 of L/2 consecutive ones. Dropping the other indices,
moving the centre to D̄_S (which minimises the sum over S) and dropping each half's spread
about its own mean (the variance decomposition) only lower the sum:

    K·ρ² ≥ Σ_{i∈S} |D_i − D̄_S|² ≥ (L/2)·(|D̄_1 − D̄_S|² + |D̄_2 − D̄_S|²) = (L/4)·|D̄_1 − D̄_2|².

The half means of D are those of w minus those of q, so with the descriptor
f = (w̄_1 − w̄_2)/2 (3 numbers in 3-D): L·|f(w) − f(q)|² ≤ K·ρ², that is

    ρ ≥ √(L/K)·|f(w_S) − f(q_S)|.

It holds for S the first L indices and for S the last L alike: the last L points of the
window at m are the first L of the window at m + (K − L)·dil, so one tree of the
descriptors of every L-point sub-window serves both. A window with ρ below a radius r
therefore has both descriptors within r·√(K/L) of the query's: the windows in both balls
hold every such window. L is 16 for queries of 16 or more arc samples, 8 for 8-15 (a tree
each). Nothing here depends on the time scale or on the smoothing: the inequality is
between the window's points and the query's arc samples exactly as the search scores them,
and the gate already holds every tolerance (arc offset, smoothing, stored deviation).

**Two rounds.** The balls of r = g/2 (g the query's largest gate) first: their valid
windows (:meth:`._gates.Gates.valid`) are bounded and drained into the pool as the search
does every window. Every window outside them has ρ ≥ g/2, so a combined score at least
that: where the pool's threshold (:attr:`~._pool.CandidatePool.combined`) is then at or
below g/2, none of them can enter (the drain drops windows by that threshold the same
way), and the search is done; else the balls of g bring the rest below the gate, drained
into the same pool. Either way the windows left
out are ones the search would have dropped at the gate or the threshold, and the pool,
which does not depend on the order windows are offered in, comes out the same. On 1,000
primitives the threshold ends at a median 0.39 g (the pool full of the 48 best), and the
half-gate balls hold a fraction of the windows of the gate's.

Measured and dropped: four quarters, a 9-number descriptor, bound ~25 % tighter and left
~25 % fewer windows, but its tree cost 3x as much to build and to search (slower on 1,000
primitives); 4-point sub-windows for queries of 4-7 samples held too many windows to pay;
a first radius of 0.35 g or 0.7 g was slower than 0.5 g.

**Round-off.** The search keeps a window whose *computed* ρ̂ is below the gate. ρ̂ comes
from moments of the window and the query (:meth:`._index_search.IndexSearch.score`): sums
of K·d products of magnitude ≤ 4c² (c the largest |coordinate| of the level's points and of
the query; the centred window's ≤ 2c), each off by at most (K·d + 2)·u·K·d·4c² (u = 2⁻⁵³);
K·ρ̂² takes four such terms, and errs besides by the window's centring (≤ 2·K·d·2c·K·u·c)
and by 2·|w̄|·|Σ q̃| ≤ 2c·K·d·4u·c where the computed q̃ do not sum to 0 exactly. In all
|K·ρ̂² − K·ρ²| < 64·(K·d + 2)·K·d·u·c², so |ρ̂ − ρ| ≤ √(64·(K·d + 2)·d·u)·c
(|√a − √b| ≤ √|a − b|). Each descriptor component is a sum of L coordinates over L, off by
less than 16·u·c, a descriptor by √d·16·u·c. The ball's radius is raised by both (twice the
descriptor's: window and query), and by a relative 10⁻⁹ for the tree's own
squared-distance comparison (about 10⁻⁶·c in all, far below any gate); the second round is
skipped only where the threshold is below g/2 by a relative 10⁻⁹ (the combined score
hypot(ρ̂, ·) ≥ ρ̂).

**When.** Rotation ``"none"``, queries of at least 8 arc samples on levels of more than
``search.chunk`` windows (fewer: bounding them all is as cheap). A level's tree is built
once its queries have asked for 2²¹ windows in all (at the second query on a level of 2
million, the 16th on one of 131,072): a tree costs ~0.2 µs a point to build and a ball
search has fixed costs of its own (~1-2 ms: two rounds, the trees' index lists), so on a
level asked a few times, or a small one, the plain search is cheaper. Built at every
level's first query, the trees cost the 14 bundled primitives up to 0.3 s a path (levels
of 15,000-500,000 windows asked 1-26 times: 1.14 against 0.83 s CPU on one path); on
1,000 primitives the 2²¹ rule measured no slower than that (4.5 and 3.2 against 4.7 and
3.6 s CPU on two paths), and 2²⁰ no faster on either library.
A first ball holding more than an eighth of the windows is dropped for the plain search (a
long straight query, where most windows are straight).
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

__all__ = ["SUBS", "descriptors", "query_descriptors", "radius", "candidates", "search"]

SUBS = (16, 8)  # points of the sub-windows described: the most a query's K allows
_U = 2.0**-53
_MOST = 0.125  # a first ball holding more of the windows: the plain search
_FIRST = 0.5  # the first ball's share of the gate
_BUILD = 1 << 21  # windows a level's queries ask for before its tree is built


def descriptors(pts: np.ndarray, dil: int, sub: int, chunk: int = 1 << 16) -> np.ndarray:
    """f of every sub-window of ``sub`` points taking every ``dil``-th of ``pts``: its
    first half's centroid minus its second half's, halved.

    Formed ``chunk`` sub-windows at a time: each one's half sums are the same additions in
    the same order whatever the chunk (the same numbers); the whole level's sums at once
    were two arrays the size of the level's points (48 MB each on 2 million points, fresh
    memory: 0.13-0.2 s a tree there, against 0.017 s by chunks).

    Parameters
    ----------
    pts : array, shape (M, d)
    dil, sub : int
        ``sub`` even.

    Returns
    -------
    array, shape (M − (sub − 1)·dil, d)
    """
    half = sub // 2
    n = pts.shape[0] - (sub - 1) * dil
    if n <= 0:
        return np.empty((0, pts.shape[1]))
    out = np.empty((n, pts.shape[1]))
    sums = np.empty((min(chunk, n) + half * dil, pts.shape[1]))
    for r0 in range(0, n, chunk):
        m = min(chunk, n - r0)
        reach = m + half * dil  # half sums are needed from these starts on
        s = sums[:reach]
        s[...] = pts[r0 : r0 + reach]
        for i in range(1, half):
            s += pts[r0 + i * dil : r0 + i * dil + reach]
        part = np.subtract(s[:m], s[half * dil : half * dil + m], out=out[r0 : r0 + m])
        part *= 1.0 / sub  # (S1/half − S2/half)/2
    return out


def query_descriptors(qc: np.ndarray, sub: int) -> tuple[np.ndarray, np.ndarray]:
    """f of the query's first and last ``sub`` arc samples, each shape (d,)."""
    return descriptors(qc[:sub], 1, sub)[0], descriptors(qc[-sub:], 1, sub)[0]


def radius(rho: float, k: int, sub: int, d: int, coord: float) -> float:
    """Ball radius that holds every window of k points with a shape RMSD below ``rho``:
    ρ·√(k/sub) and the round-off margins of the module notes (``coord``: the largest
    |coordinate| of window and query)."""
    err = math.sqrt(64.0 * (k * d + 2) * d * _U) * coord
    desc = math.sqrt(d) * 16.0 * _U * coord
    return (rho * math.sqrt(k / sub) + err + 2.0 * desc) * (1.0 + 1e-9)


def _tree(index: ArcIndex, jb: int, dil: int, sub: int, n_windows: int):
    """The k-d tree of level jb's descriptors of ``sub``-point sub-windows at dilation dil,
    and the level's largest |coordinate|; None until the level's queries (of
    ``n_windows`` windows each) have asked for ``_BUILD`` windows in all, then built and
    kept."""
    key = ("ball", jb, dil, sub)
    hit = index.cache.get(key)
    if hit is None:
        hit = index.cache[key] = [0, None, 0.0]
    if hit[1] is None:
        hit[0] += n_windows
        if hit[0] < _BUILD:
            return None
        from scipy.spatial import cKDTree

        pts = index.levels[jb].pts
        hit[1] = cKDTree(
            descriptors(pts, dil, sub), leafsize=32, balanced_tree=False, compact_nodes=False
        )
        # max |x| as max(max x, −min x): the same number, without a copy of the level's points
        hit[2] = max(float(pts.max()), -float(pts.min())) if pts.size else 0.0
    return hit[1], hit[2]


def candidates(aq: ArcQuery, got: tuple, sub: int, rho: float, n_most: int) -> np.ndarray | None:
    """Sorted starts of the windows (< ``aq.n_windows``) whose two sub-window descriptors
    lie in the balls of ``rho`` (a superset of the windows with a shape RMSD below it,
    module notes); ``got``: :func:`_tree`'s; None when the first ball holds more than
    ``n_most``."""
    n, k = aq.n_windows, aq.k
    tree, coord = got
    f1, f2 = query_descriptors(aq.qc, sub)
    r = radius(rho, k, sub, aq.qc.shape[1], max(coord, float(np.abs(aq.qc).max())))
    first = np.asarray(tree.query_ball_point(f1, r, return_sorted=False), dtype=np.int64)
    first = first[first < n]
    if first.size > n_most:
        return None
    last = np.asarray(tree.query_ball_point(f2, r, return_sorted=False), dtype=np.int64)
    last -= (k - sub) * aq.dil  # the window whose last sub points these are
    last = last[(last >= 0) & (last < n)]
    seen = np.zeros(n, dtype=bool)
    seen[first] = True
    out = last[seen[last]]
    out.sort()
    return out


def search(search: IndexSearch, aq: ArcQuery, gates: Gates, pool: CandidatePool) -> bool:
    """Fill ``pool`` from the windows of the balls (:func:`candidates`), valid, bounded and
    drained best-first as :meth:`._index_search.IndexSearch._few` does every window: first
    those of half the gate; the rest below the gate only when the pool's threshold is not
    below half the gate then. False (the pool untouched) where no ball applies (module
    notes)."""
    if not search.ball or search.opts.rotation != "none" or aq.n_windows <= search.chunk:
        return False
    sub = next((s for s in SUBS if s <= aq.k), None)
    if sub is None:
        return False
    got = _tree(aq.index, aq.jb, aq.dil, sub, aq.n_windows)
    if got is None:
        return False
    rho = _FIRST * gates.top
    ws = candidates(aq, got, sub, rho, int(_MOST * aq.n_windows))
    if ws is None:
        return False
    _offer(search, aq, gates, pool, ws)
    # every window outside the first balls scores at least rho (module notes)
    if pool.combined > rho * (1.0 - 1e-9):
        more = candidates(aq, got, sub, gates.top, aq.n_windows)
        _offer(search, aq, gates, pool, more[~np.isin(more, ws, assume_unique=True)])
    return True


def _offer(
    search: IndexSearch, aq: ArcQuery, gates: Gates, pool: CandidatePool, ws: np.ndarray
) -> None:
    """Bound the valid windows of ``ws`` and drain them best-first into ``pool``."""
    ws = ws[gates.valid(ws)]
    search.stats.windows += ws.size
    search.stats.bounded += ws.size
    if ws.size == 0:
        return
    search.drain_bounded(aq, gates, pool, ws, search.speed_bound(aq, ws),
                         search.first_bound(aq, ws))  # fmt: skip
