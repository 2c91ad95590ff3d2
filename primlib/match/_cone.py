"""Cone rejection: a proven lower bound at every B-th window rejects the windows between.

Windows m and m' = m + δ of one index level (K points p_{m+i·dil}, :mod:`._index_search`)
whose points all lie in one primitive differ point by point by
D_i = p_{m'+i·dil} − p_{m+i·dil} = Σ_{j<δ} d_{m+i·dil+j}, sums of δ of the consecutive
differences d_j = p_{j+1} − p_j over the windows' point range. Each D_i therefore lies in
δ·[lo, hi] (lo, hi: the bounding box of those d_j), so |D_i − t| ≤ δ·h with t the box's
centre times δ and h = ½|hi − lo|, or with t = 0 and h = max_j |d_j|; the smaller of the two
holds. For any family F of orthogonal R ("full", "z", "none"), (R', t') optimal for P':
rmsd(P, Q) ≤ rms(R'P + t' + R't − Q) ≤ rmsd(P', Q) + rms(R'(P' − P − t)) ≤ rmsd(P', Q) + δ·h
(the triangle inequality; R' keeps lengths). So a lower bound LB at the windows c and c + B
(the block's ends) bounds every window m between:
rmsd(m) ≥ max(LB(c) − (m − c)h, LB(c + B) − (c + B − m)h)
≥ max((LB(c) + LB(c + B) − B·h)/2, LB(c) − B·h, LB(c + B) − B·h).
A block whose value reaches the largest gate of its windows holds no window the pool can
take (it takes shape RMSDs below the gate alone): it is dropped before any of its windows
is bounded. Blocks whose point range [c, c + B + span − 1] crosses a primitive's end (a
window may run a little past it, :class:`._gates.Gates`) are not covered and keep every
window. Round-off: the differences and the box err by a few u·max|p| each (u = 2⁻⁵³), B·h
by B·~12u·max|p| < 10⁻¹²·max|p| for B < 700; the value is lowered by
10⁻¹²·(max|p| + |LB(c)| + |LB(c + B)| + the query's radius of gyration), the LBs carry their
own margins (:mod:`._bounds`).

The slopes h of every block of a level are cached in the index's ``cache`` per (level, B,
tiles a block reads) (:func:`block_slopes`), so queries on the same level share them; the
strided bounds at every B-th window (:func:`alive_blocks`) are the one cost a query adds,
and a probe of ~512 blocks (:func:`_pays`) skips the cone where it would leave too many
of them (the rotation-invariant bound is mostly too weak for it), as do queries of fewer
than 65,536 windows.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from primlib.match._bounds import products_for

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcIndex, ArcQuery, Level
    from primlib.match._gates import Gates
    from primlib.match._index_search import IndexSearch

__all__ = ["SIZES", "block_slopes", "cone_values", "alive_blocks", "alive", "screen_shape",
           "shape_first", "not_in"]  # fmt: skip

# block sizes of the bisection (:func:`alive_blocks`): the strided bounds at every 8th
# window, the survivors halved into blocks of 4 (on 1,000 primitives, rotation "none":
# 6.5 % of the windows left for the fine bound; starting at 16 or 32 costs more in gathered
# middle bounds than it saves in strided ones)
SIZES = (8, 4)
# fewer windows a query: no cone (the probe's ~1.5 ms would cost more than the fine bound
# the cone saves: the 14 bundled primitives' queries, ~20,000 windows, ran 10 % slower)
MIN_WINDOWS = 1 << 16
PROBE, PROBE_BLOCKS = 8, 512  # :func:`_pays`: every PROBE-th block, ~PROBE_BLOCKS at most


def block_slopes(index: ArcIndex, jb: int, span: int, size: int) -> np.ndarray:
    """The slope h of every block j (windows jB .. jB + B − 1, B = ``size``) of level jb,
    for windows of ``span`` points: the smaller of half the diagonal of the bounding box,
    and the largest norm, of the differences d_i over tiles j .. j + w − 1 of B differences
    (w = 1 + ⌈(span − 1)/B⌉: they hold the block's, d_jB .. d_jB+B+span−2); +inf where
    the points jB .. jB + w·B (all of the block's, and a few more) are not all of one
    primitive. Cached in ``index.cache`` per (level, B, w), rounded up to float32 (half the
    memory; a larger slope only loosens the bound)."""
    w = 1 + -(-(span - 1) // size)
    key = ("cone", jb, size, w)
    hit = index.cache.get(key)
    if hit is not None:
        return hit
    lo, hi, top = _tiles(index, jb, size)
    prim = index.levels[jb].prim
    up = np.empty(top.shape[0], dtype=np.float32)
    for j0 in range(0, up.size, _ROWS):  # the blocks j0 .. j1 - 1 read tiles j0 .. j1 + w - 2
        j1 = min(j0 + _ROWS, up.size)
        cut = slice(j0, j1 + w - 1)
        up[j0:j1] = _slopes(lo[cut], hi[cut], top[cut], j1 - j0, w,
                            prim, np.arange(j0, j1) * size, size)  # fmt: skip
    index.cache[key] = up
    return up


_ROWS = 1 << 13  # blocks a pass of :func:`block_slopes` (its temporaries stay in cache)


def _slopes(lo: np.ndarray, hi: np.ndarray, top: np.ndarray, n: int, w: int,
            prim: np.ndarray, first: np.ndarray, size: int) -> np.ndarray:  # fmt: skip
    """:func:`block_slopes` of n blocks from their tiles and the next w − 1 (those the level
    has): the sliding box and largest norm over w tiles, the slope, +inf across a
    primitive's end, rounded up to float32. Each block's value from its own tiles alone
    (min and max are exact): the same numbers whatever blocks are taken together; the
    whole level's at once took ~40 ms of temporaries a (B, w) on 2 million points, mostly
    fresh memory faulted in."""
    lo, hi, top = -_sliding_max(-lo, w)[:n], _sliding_max(hi, w)[:n], _sliding_max(top, w)[:n]
    hi -= lo
    box = 0.5 * np.sqrt(np.einsum("ij,ij->i", hi, hi))
    h = np.minimum(np.where(np.isfinite(box), box, np.inf), top)
    h[prim[first] != prim[np.minimum(first + w * size, prim.size - 1)]] = np.inf
    up = h.astype(np.float32)
    low = up < h
    up[low] = np.nextafter(up[low], np.float32(np.inf))
    return up


def _tiles(index: ArcIndex, jb: int, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per tile of ``size`` consecutive differences d_i of level jb (tile j: d_jB ..
    d_jB+B−1): their bounding box (lo, hi, (nb, d)) and largest norm (nb,). A difference
    across a primitive's end counts as zero (a block whose points cross one is not
    covered, whatever its tiles hold; a zero only widens the box of the tiles it is in).
    Tiles of 2B from those of B; cached in ``index.cache`` per (level, B) for B >= 4."""
    key = ("cone-tiles", jb, size)
    hit = index.cache.get(key)
    if hit is not None:
        return hit
    if size > 4 and size % 2 == 0:  # pairs of the tiles of size / 2 (the last one alone)
        lo, hi, top = _tiles(index, jb, size // 2)
        lo, hi, top = _pairs(lo, np.minimum), _pairs(hi, np.maximum), _pairs(top, np.maximum)
    elif size in (1, 2, 4):
        lo, hi, top = first_tiles(index.levels[jb], size)
    else:
        raise ValueError(f"Expected a cone block size of 1 or even, got {size}")
    if size >= 4:
        index.cache[key] = (lo, hi, top)
    return lo, hi, top


def first_tiles(lv: Level, size: int, chunk: int = 1 << 16) -> tuple[np.ndarray, np.ndarray,
                                                                      np.ndarray]:  # fmt: skip
    """:func:`_tiles` of ``size`` (1, 2 or 4) differences, formed ``chunk`` points at a time:
    the differences of a chunk, zero across a primitive's end and after the level's last
    point, their norms, and the box and largest norm of each tile (min and max are exact:
    the same numbers as the differences of the whole level reduced two by two). The whole
    level's differences and norms (48 + 16 MB on a level of 2 million points, fresh memory
    a first call faults in) took 0.28 s there, against 0.09 s once the memory was reused."""
    pts, prim = lv.pts, lv.prim
    n, d = pts.shape
    nb = -(-n // size)
    lo, hi, top = np.empty((nb, d)), np.empty((nb, d)), np.empty(nb)
    chunk -= chunk % size
    dif = np.empty((chunk, d))
    nrm = np.empty(chunk)
    for r0 in range(0, n, chunk):
        m = min(chunk, n - r0)
        inner = min(m, n - 1 - r0)  # the rows with a next point
        np.subtract(pts[r0 + 1 : r0 + 1 + inner], pts[r0 : r0 + inner], out=dif[:inner])
        dif[inner:m] = 0.0
        dif[:inner][prim[r0 + 1 : r0 + 1 + inner] != prim[r0 : r0 + inner]] = 0.0
        np.sqrt(np.einsum("ij,ij->i", dif[:m], dif[:m]), out=nrm[:m])
        full = -(-m // size) * size  # the last tile's missing rows: copies of its last row
        dif[m:full], nrm[m:full] = dif[m - 1], nrm[m - 1]
        g, t = dif[:full].reshape(-1, size, d), nrm[:full].reshape(-1, size)
        rows = slice(r0 // size, r0 // size + g.shape[0])
        out_lo, out_hi, out_top = lo[rows], hi[rows], top[rows]
        out_lo[...], out_hi[...], out_top[...] = g[:, 0], g[:, 0], t[:, 0]
        for i in range(1, size):
            np.minimum(out_lo, g[:, i], out=out_lo)
            np.maximum(out_hi, g[:, i], out=out_hi)
            np.maximum(out_top, t[:, i], out=out_top)
    return lo, hi, top


def _pairs(a: np.ndarray, op) -> np.ndarray:
    """``op`` (np.minimum or np.maximum) of the rows 2i and 2i + 1 of ``a``, the last row
    alone when their number is odd (op(x, x) = x: the values of pairing it with itself)."""
    n = a.shape[0]
    out = np.empty(((n + 1) // 2,) + a.shape[1:], a.dtype)
    op(a[0 : n - 1 : 2], a[1::2], out=out[: n // 2])
    if n % 2:
        out[-1] = a[-1]
    return out


def _sliding_max(a: np.ndarray, w: int) -> np.ndarray:
    """max of a[j : j + w] along the first axis for every j (past the end: what is left),
    by doubling: log2(w) passes."""
    n = a.shape[0]
    tail = np.full((w - 1,) + a.shape[1:], -np.inf)
    r = np.concatenate([a, tail])
    span = 1
    while 2 * span <= w:
        r = np.maximum(r[:-span], r[span:])
        span *= 2
    if span < w:
        r = np.maximum(r[: r.shape[0] - (w - span)], r[w - span :])
    return r[:n]


def cone_values(lb_a: np.ndarray, lb_b: np.ndarray, h: np.ndarray, size: int,
                scale: float) -> np.ndarray:  # fmt: skip
    """Lower bound of every window's shape RMSD in each block, from the bounds ``lb_a`` and
    ``lb_b`` at its ends (−inf where the far end is past the last window), its slope ``h``
    and the round-off scale (max|p| + the query's radius of gyration) (module notes)."""
    with np.errstate(invalid="ignore"):  # inf − inf: a block not covered, nan, not below
        rise = size * h
        v = np.maximum(np.maximum(0.5 * (lb_a + lb_b - rise), lb_a - rise), lb_b - rise)
        v -= 1e-12 * (scale + np.abs(lb_a) + np.where(np.isfinite(lb_b), np.abs(lb_b), 0.0))
    return np.where(np.isnan(v), -np.inf, v)


def _block_gates(gates: Gates, n: int, size: int) -> np.ndarray | float:
    """The largest gate of the windows of each block of ``size`` windows of 0 .. n − 1
    (the gate alone when windows carry no deviations)."""
    g = gates.at((0, n))
    if np.ndim(g) == 0:
        return g
    nb = -(-n // size)
    return np.pad(g, (0, nb * size - n), constant_values=-np.inf).reshape(nb, size).max(1)


def _scale(search: IndexSearch, aq: ArcQuery) -> float:
    """max |p| of the level plus the query's radius of gyration (:func:`cone_values`)."""
    radius = aq.index.sums(aq.jb, aq.dil, products=products_for(search.opts.rotation))[2]
    return radius + aq.moments.gyration


def _pays(search: IndexSearch, aq: ArcQuery, gates: Gates, size: int, scale: float) -> bool:
    """Whether the cone leaves at most ``search.gather_fraction`` of the blocks of ``size``
    windows, estimated on every p-th block (p ≥ ``PROBE``, ~``PROBE_BLOCKS`` at most
    blocks: a strided bound costs a cache miss a row, and the estimate needs no more) from
    the bound at its first window alone (LB(c) − B·h against the largest gate)."""
    nb = -(-aq.n_windows // size)
    every = max(PROBE, nb // PROBE_BLOCKS)
    lb = search.first_bound(aq, (0, aq.n_windows), stride=every * size)
    if np.count_nonzero(lb < gates.top) > search.gather_fraction * lb.size:
        return False  # too many below the gate already
    h = _sample_slopes(aq.index, aq.jb, aq.span, size, np.arange(lb.size) * every)
    left = cone_values(lb, np.full(lb.size, -np.inf), h, size, scale) < gates.top
    return bool(np.count_nonzero(left) <= search.gather_fraction * lb.size)


def _sample_slopes(index: ArcIndex, jb: int, span: int, size: int,
                   blocks: np.ndarray) -> np.ndarray:  # fmt: skip
    """:func:`block_slopes` of a few ``blocks`` alone, from their points (the probe of
    :func:`_pays` builds no slopes for the whole level when the cone does not pay)."""
    lv = index.levels[jb]
    w = 1 + -(-(span - 1) // size)
    at = np.minimum(blocks[:, None] * size + np.arange(w * size + 1), lv.prim.size - 1)
    d = np.diff(lv.pts[at], axis=1)
    d[lv.prim[at[:, 1:]] != lv.prim[at[:, :-1]]] = 0.0
    box = d.max(axis=1) - d.min(axis=1)
    h = np.minimum(0.5 * np.linalg.norm(box, axis=1), np.linalg.norm(d, axis=2).max(axis=1))
    h[lv.prim[at[:, 0]] != lv.prim[at[:, -1]]] = np.inf
    return h


def alive_blocks(search: IndexSearch, aq: ArcQuery, gates: Gates,
                 sizes: tuple[int, ...] = SIZES) -> np.ndarray | None:  # fmt: skip
    """Mask of the windows of the query that may be below their gate, by bisection: the
    cone (module notes) on blocks of ``sizes[0]`` windows from strided bounds at every
    ``sizes[0]``-th window, then each surviving block halved with the bound at its middle
    window (gathered), down to ``sizes[-1]``; in those left, each window's own cone.
    None when a probe (:func:`_pays`, the bounds of a sample of blocks) finds that more than
    ``search.gather_fraction`` of the blocks would be left (the fine bound on the few left,
    gathered, costs ~3.5 times as much a window as on all, sliced), or the query has fewer
    than ``search.cone_min`` windows. Memoised on the query (one set of gates a query)."""
    key = ("cone", sizes)
    if key in aq.memo:
        return aq.memo[key]
    n = aq.n_windows
    scale = _scale(search, aq)
    size = sizes[0]
    if n < search.cone_min or not _pays(search, aq, gates, size, scale):
        aq.memo[key] = None
        return None
    nb = -(-n // size)
    ends = search.first_bound(aq, (0, min(nb * size + 1, n)), stride=size)
    blk = np.arange(nb)
    la = ends[:nb]
    lb = np.full(nb, -np.inf)
    lb[: ends.size - 1] = ends[1:]
    for i, size in enumerate(sizes):
        if i:  # halve the survivors: the bound at each one's middle window
            half = sizes[i - 1] // size
            if half != 2:
                raise ValueError(f"Expected cone block sizes halving, got {sizes}")
            mid = (2 * blk + 1) * size
            inside = mid < n
            lm = np.full(blk.size, -np.inf)
            lm[inside] = search.first_bound(aq, mid[inside])
            blk = np.stack([2 * blk, 2 * blk + 1], axis=1)
            la = np.stack([la, lm], axis=1)
            lb = np.stack([lm, lb], axis=1)
            keep = (blk * size < n).ravel()
            blk, la, lb = blk.ravel()[keep], la.ravel()[keep], lb.ravel()[keep]
        h = block_slopes(aq.index, aq.jb, aq.span, size)[blk]
        g = _block_gates(gates, n, size)
        live = cone_values(la, lb, h, size, scale) < (g if np.ndim(g) == 0 else g[blk])
        blk, la, lb, h = blk[live], la[live], lb[live], h[live]
    out = np.zeros(n, dtype=bool)
    out[_windows_left(gates, n, blk, la, lb, h, size, scale)] = True
    aq.memo[key] = out
    return out


def _windows_left(gates: Gates, n: int, blk: np.ndarray, la: np.ndarray, lb: np.ndarray,
                  h: np.ndarray, size: int, scale: float) -> np.ndarray:  # fmt: skip
    """The windows of blocks ``blk`` of ``size`` (bounds ``la``, ``lb`` at their ends,
    slopes ``h``) that each one's own cone, max(LB(c) − o·h, LB(c + B) − (B − o)·h) at
    offset o, leaves below its gate (module notes; no bound computed)."""
    o = np.arange(size)
    ws = blk[:, None] * size + o
    with np.errstate(invalid="ignore"):  # 0·inf, inf − inf: not covered (nan, not below)
        v = np.maximum(la[:, None] - o * h[:, None], lb[:, None] - (size - o) * h[:, None])
        v -= 1e-12 * (scale + np.abs(la) + np.where(np.isfinite(lb), np.abs(lb), 0.0))[:, None]
    ws, v = ws.ravel(), np.where(np.isnan(v), -np.inf, v).ravel()
    inside = ws < n
    ws, v = ws[inside], v[inside]
    return ws[v < gates.at(ws)]


def alive(search: IndexSearch, aq: ArcQuery, gates: Gates, ws: np.ndarray,
          sizes: tuple[int, ...] = SIZES) -> np.ndarray:  # fmt: skip
    """Mask of windows ``ws`` the cone does not reject (:func:`alive_blocks`): all True
    when they are too few for the coarse bounds to pay (fewer than one a ``sizes[0]``), or
    the cone would leave too many."""
    if not sizes or ws.size * sizes[0] < aq.n_windows:
        return np.ones(ws.size, dtype=bool)
    cone = alive_blocks(search, aq, gates, sizes)
    return np.ones(ws.size, dtype=bool) if cone is None else cone[ws]


def screen_shape(search: IndexSearch, aq: ArcQuery, gates: Gates, sizes: tuple[int, ...] = SIZES,
                 tau: float = math.inf) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Every valid window whose shape bound is below its gate (and ``tau``) and whose time
    scale is in range, and those bounds (:meth:`._index_search.IndexSearch._screen_shape`),
    by chunks of windows: the time-scale test then reads the few below the gate, and no
    index array of every window is formed; with ``sizes`` (empty: none) the cone
    (:func:`alive_blocks`) drops the blocks that cannot hold one first, and the fine bound
    is taken on the valid windows of the others alone (gathered when few, else on the whole
    chunk, sliced)."""
    out, bounds = [], []
    n = aq.n_windows
    cone = alive_blocks(search, aq, gates, sizes) if sizes else None
    for c0 in range(0, n, 1 << 16):
        c1 = min(c0 + (1 << 16), n)
        ok = gates.valid((c0, c1))
        search.stats.windows += int(np.count_nonzero(ok))
        if cone is not None:
            ok &= cone[c0:c1]
        if cone is None or np.count_nonzero(ok) > search.gather_fraction * (c1 - c0):
            lb1 = search.first_bound(aq, (c0, c1))
            ok &= lb1 < _below(gates.at((c0, c1)), tau)
            at = np.flatnonzero(ok)
            ws, lb1 = c0 + at, lb1[at]
        else:
            ws = c0 + np.flatnonzero(ok)
            lb1 = search.first_bound(aq, ws)
            keep = lb1 < _below(gates.at(ws), tau)
            ws, lb1 = ws[keep], lb1[keep]
        inside = search.in_range(aq, ws, screen=True)[0]
        out.append(ws[inside])
        bounds.append(lb1[inside])
    return np.concatenate(out), np.concatenate(bounds)


def _below(gate: np.ndarray | float, tau: float) -> np.ndarray | float:
    """The gates lowered to ``tau`` (as they are without one: no pass over the windows)."""
    return gate if tau == math.inf else np.minimum(gate, tau)


def shape_first(search: IndexSearch, aq: ArcQuery, gates: Gates, tau: float,
                head: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The windows :meth:`._index_search.IndexSearch._best_first` bounds once the pool has a
    threshold ``tau`` (not in ``head``, the first batch), the shape bound first: every valid
    window whose shape bound is below its gate and ``tau`` (a window whose combined bound
    hypot(shape, speed) reaches tau cannot enter the pool), in time-scale range, whose two-
    and four-group speed bounds and combined bound are below ``tau``; their speed and
    combined bounds. The same tests as the speed screen first (:meth:`_screen`), in another
    order (a window the cone drops has its RMSD at or above the gate: it cannot enter).

    For ``rotation="none"``: its per-axis half-window bound keeps 7 % of the windows where
    the speed and time-scale tests keep 95 % (the short pieces of a novel path, seed 103 of
    ``bench_match_novel.py``: 3.6 M windows, 1.53 M through the screen, 0.26 M through the
    shape bound); taken first, the speed tests read the few it keeps. 7 % less time a query
    on those paths; 2 % more on the default's (the speed test sifts there).
    """
    rest, lb1 = screen_shape(search, aq, gates, search.cone, tau)
    keep = search.speed_screen(aq, rest, tau)
    keep &= not_in(rest, head, aq.n_windows)
    rest, lb1 = rest[keep], lb1[keep]
    lbs = search.speed_bound(aq, rest)
    lbc = np.hypot(np.maximum(lb1, 0.0), np.maximum(lbs, 0.0))
    keep = (lbs < tau) & (lbc < tau)
    return rest[keep], lbs[keep], lbc[keep]


def not_in(rest: np.ndarray, head: np.ndarray, n: int) -> np.ndarray:
    """Mask of the values of ``rest`` not in ``head`` (integers in [0, n), ``head`` increasing):
    by binary search in ``head`` for fewer than n/16, else from n flags (np.isin sorts)."""
    if rest.size * 16 < n and head.size:
        at = np.minimum(np.searchsorted(head, rest), head.size - 1)
        return head[at] != rest
    seen = np.zeros(n, dtype=bool)
    seen[head] = True
    return ~seen[rest]
