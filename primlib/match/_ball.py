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

It holds for S any L consecutive indices j, ..., j + L − 1: the window at m, the points
m + j·dil, ... of which are the sub-window of L points starting at m + j·dil. So one tree of
the descriptors of the L-point sub-windows starting at every ``STRIDE``-th block of dil
points (the starts p with ⌊p/dil⌋ ≡ 0 mod s, s = ``STRIDE``: a tree of 1/s of the points,
1/s of the build) serves every window, each through its own offsets: for the first ball
the j < s with ⌊m/dil⌋ + j ≡ 0 (mod s) (the sub-window at m + j·dil is a stored one:
⌊(m + j·dil)/dil⌋ = ⌊m/dil⌋ + j), for the last the j' in K − L − s + 1 ... K − L with
⌊m/dil⌋ + j' ≡ 0 (one of any s consecutive integers), so K ≥ L + s − 1. Each offset is a
ball around the query's own descriptor of its samples j, ..., j + L − 1 (s balls a round
and side, the stored starts they hold less j·dil; a window is found through one offset
alone). A window with ρ below a radius r therefore has both descriptors within r·√(K/L) of
the query's: the windows in both balls hold every such window. Nothing is bounded between
neighbouring starts: each window's own points are in the inequality. L is 16 for queries
of 15 + s or more arc samples, 8 for 7 + s to 14 + s (a tree each), none below. Nothing
here depends on the time scale or on the smoothing: the inequality is between the window's
points and the query's arc samples exactly as the search scores them, and the gate
already holds every tolerance (arc offset, smoothing, stored deviation).

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
a first radius of 0.35 g or 0.7 g was slower than 0.5 g. Stride 2 against 1 (every start):
half the trees' build for ~15 % more windows bounded; stride 4 left ~50 % more bounded and
the queries of 8-10 samples without a ball, and measured no faster than 2. A tree of every
s-th start queried with a radius widened by a bound on how far f moves between
neighbouring starts was dropped: that bound is the level's point spacing h a start (a
step moves each of the L points by at most h, f by at most L·h/L), while the balls' radii
are ~0.4 h, so the widened ball held ~40x the volume; the offsets above need no widening.

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

**When.** Rotation ``"none"``, queries of at least 7 + s arc samples on levels of more than
``search.chunk`` windows (fewer: bounding them all is as cheap). A level's tree is built
once its queries have asked for 2²⁰ windows in all (at the first query on a level of 2
million, the 8th on one of 131,072): a tree costs ~0.2 µs a point it holds to build (half
the level's at stride 2) and a ball search has fixed costs of its own (~1-2 ms: two rounds,
the trees' index lists), so on a level asked a few times, or a small one, the plain search
is cheaper. Trees of every start built at every level's first query cost the 14 bundled
primitives up to 0.3 s a path (levels of 15,000-500,000 windows asked 1-26 times: 1.14
against 0.83 s CPU on one path), and 2²¹ windows were chosen then. Half the build moves
the break-even to half the windows.
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
_BUILD = 1 << 20  # windows a level's queries ask for before its tree is built
STRIDE = 2  # a tree holds the sub-windows starting at every STRIDE-th block of dil points


def descriptors(pts: np.ndarray, dil: int, sub: int, stride: int = 1,
                chunk: int = 1 << 16) -> np.ndarray:  # fmt: skip
    """f of the sub-windows of ``sub`` points taking every ``dil``-th of ``pts`` that start
    at the points p with ⌊p/dil⌋ ≡ 0 (mod ``stride``) (every one with ``stride`` 1): each
    one's first half's centroid minus its second half's, halved; in increasing p.

    Formed about ``chunk`` sub-windows at a time, every one's half sums as contiguous
    slices added (strided views of the kept starts alone measured 2x slower), the kept
    ones' then subtracted: each one's sums are the same additions in the same order whatever the
    chunk and the stride (the same numbers); the whole level's sums at once were two arrays
    the size of the level's points (48 MB each on 2 million points, fresh memory: 0.13-0.2
    s a tree there, against 0.017 s by chunks).

    Parameters
    ----------
    pts : array, shape (M, d)
    dil, sub, stride : int
        ``sub`` even.

    Returns
    -------
    array, shape (c, d)
        c = ⌊n/(stride·dil)⌋·dil + min(n mod stride·dil, dil), n = M − (sub − 1)·dil.
    """
    half, row = sub // 2, stride * dil
    n = pts.shape[0] - (sub - 1) * dil
    if n <= 0:
        return np.empty((0, pts.shape[1]))
    out = np.empty(((n // row) * dil + min(n % row, dil), pts.shape[1]))
    chunk = max(1, chunk // row) * row  # chunks start at multiples of stride·dil
    keep = (np.arange(min(chunk, n)) // dil) % stride == 0  # the kept starts of a chunk
    sums = np.empty((min(chunk, n) + half * dil, pts.shape[1]))
    at = 0
    for r0 in range(0, n, chunk):
        m = min(chunk, n - r0)
        reach = m + half * dil  # half sums are needed from these starts on
        s = sums[:reach]
        s[...] = pts[r0 : r0 + reach]
        for i in range(1, half):
            s += pts[r0 + i * dil : r0 + i * dil + reach]
        s1, s2 = s[:m], s[half * dil : half * dil + m]
        if m % row == 0:  # whole rows of stride·dil starts: the first dil of each, strided
            q = m // row
            s1, s2 = (x.reshape(q, row, -1)[:, :dil] for x in (s1, s2))
        elif stride > 1:
            s1, s2 = s1[keep[:m]], s2[keep[:m]]
        c = s1.shape[0] * (dil if s1.ndim == 3 else 1)
        part = np.subtract(s1, s2, out=out[at : at + c].reshape(s1.shape))
        part *= 1.0 / sub  # (S1/half − S2/half)/2
        at += c
    return out


def query_descriptors(qc: np.ndarray, sub: int) -> tuple[np.ndarray, np.ndarray]:
    """f of the query's first and last ``sub`` arc samples, each shape (d,)."""
    f = descriptors(qc, 1, sub)
    return f[0], f[-1]


def radius(rho: float, k: int, sub: int, d: int, coord: float) -> float:
    """Ball radius that holds every window of k points with a shape RMSD below ``rho``:
    ρ·√(k/sub) and the round-off margins of the module notes (``coord``: the largest
    |coordinate| of window and query)."""
    err = math.sqrt(64.0 * (k * d + 2) * d * _U) * coord
    desc = math.sqrt(d) * 16.0 * _U * coord
    return (rho * math.sqrt(k / sub) + err + 2.0 * desc) * (1.0 + 1e-9)


def _tree(index: ArcIndex, jb: int, dil: int, sub: int, n_windows: int):
    """The k-d tree of level jb's descriptors of the ``sub``-point sub-windows at dilation
    dil that start at every ``STRIDE``-th block of dil points (:func:`descriptors`), the
    level's largest |coordinate| and the stride; None until the level's queries (of
    ``n_windows`` windows each) have asked for ``_BUILD`` windows in all, then built and
    kept."""
    key = ("ball", jb, dil, sub, STRIDE)
    hit = index.cache.get(key)
    if hit is None:
        hit = index.cache[key] = [0, None, 0.0, STRIDE]
    if hit[1] is None:
        hit[0] += n_windows
        if hit[0] < _BUILD:
            return None
        from scipy.spatial import cKDTree

        pts = index.levels[jb].pts
        hit[1] = cKDTree(
            descriptors(pts, dil, sub, hit[3]),
            leafsize=32,
            balanced_tree=False,
            compact_nodes=False,
        )
        # max |x| as max(max x, −min x): the same number, without a copy of the level's points
        hit[2] = max(float(pts.max()), -float(pts.min())) if pts.size else 0.0
    return hit[1], hit[2], hit[3]


def candidates(aq: ArcQuery, got: tuple, sub: int, rho: float, n_most: int) -> np.ndarray | None:
    """Sorted starts of the windows (< ``aq.n_windows``) whose two sub-window descriptors
    lie in the balls of ``rho`` (a superset of the windows with a shape RMSD below it,
    module notes); ``got``: :func:`_tree`'s; None when the first ball holds more than
    ``n_most``."""
    n, k = aq.n_windows, aq.k
    tree, coord, stride = got
    fq = descriptors(aq.qc, 1, sub)  # f of every sub-window of the query
    r = radius(rho, k, sub, aq.qc.shape[1], max(coord, float(np.abs(aq.qc).max())))
    first = _starts(tree, fq, 0, r, aq.dil, stride, n)
    if first.size > n_most:
        return None
    last = _starts(tree, fq, k - sub - stride + 1, r, aq.dil, stride, n)
    seen = np.zeros(n, dtype=bool)
    seen[first] = True
    out = last[seen[last]]
    out.sort()
    return out


def _starts(tree, fq: np.ndarray, j0: int, r: float, dil: int, stride: int,
            n: int) -> np.ndarray:  # fmt: skip
    """Starts m < n of the windows whose sub-window at offset j (j0 ≤ j < j0 + stride, the
    one with ⌊m/dil⌋ + j ≡ 0 mod stride: a stored start) has its descriptor within r of
    the query's, fq[j] (module notes)."""
    hits = tree.query_ball_point(fq[j0 : j0 + stride], r, return_sorted=False)
    out = []
    for j, h in enumerate(hits, start=j0):  # one ball a phase: at most 4 of them
        t = np.asarray(h, dtype=np.int64)
        m = t // dil * (stride * dil) + t % dil - j * dil  # stored start minus j points
        out.append(m[(m >= 0) & (m < n)])
    return np.concatenate(out)


def search(search: IndexSearch, aq: ArcQuery, gates: Gates, pool: CandidatePool) -> bool:
    """Fill ``pool`` from the windows of the balls (:func:`candidates`), valid, bounded and
    drained best-first as :meth:`._index_search.IndexSearch._few` does every window: first
    those of half the gate; the rest below the gate only when the pool's threshold is not
    below half the gate then. False (the pool untouched) where no ball applies (module
    notes)."""
    if not search.ball or search.opts.rotation != "none" or aq.n_windows <= search.chunk:
        return False
    sub = next((s for s in SUBS if s + STRIDE - 1 <= aq.k), None)
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
