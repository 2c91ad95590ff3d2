"""The cone rejection of the index search (primlib.match._cone): its block bound is below the
exact RMSD of every window of the block, and the search drops windows with it without
changing a seed or a segmentation."""

import numpy as np
import pytest
from test_match_index_search import DT, _harmonics

from primlib.match import BankIndex, SearchOptions, kabsch
from primlib.match._arc_index import ArcIndex, Level
from primlib.match._cone import block_slopes, cone_values, not_in, shape_first
from primlib.match._gates import Gates
from primlib.match._index_search import IndexSearch
from primlib.match._options import PathPiece
from primlib.match._segment import segment_with
from primlib.store import Bank


def _level(rng, lengths: list[int], d: int, turn: float) -> ArcIndex:
    """An index of one level: random walks (steps of ~1 turning by ``turn`` radians a point
    at most), one a primitive, laid end to end."""
    pts, prim = [], []
    for i, n in enumerate(lengths):
        ang = np.cumsum(rng.uniform(-turn, turn, size=(n, d - 1)), axis=0)
        step = np.ones((n, d))
        step[:, 0] = np.cos(ang[:, 0])
        step[:, 1] = np.sin(ang[:, 0])
        if d == 3:
            step[:, :2] *= np.cos(ang[:, 1])[:, None]
            step[:, 2] = np.sin(ang[:, 1])
        p = np.cumsum(step * rng.uniform(0.5, 1.0, size=(n, 1)), axis=0)
        pts.append(p - p.mean(axis=0))
        prim.append(np.full(n, i, dtype=np.int32))
    p = np.concatenate(pts)
    m = p.shape[0]
    zeros = np.zeros(m)
    # unit steps: global arc = the point's number (start + n), arc left = count − 1 − n
    start = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    level = Level(1.0, p, np.concatenate(prim), zeros, start, start.astype(float),
                  np.array(lengths) - 1.0, 1.0)  # fmt: skip
    return ArcIndex(1.0, (level,), zeros, zeros)


_CASES = [(3, 0.3, 4, 1, 16), (3, 1.5, 8, 2, 20), (2, 0.6, 8, 1, 17), (3, 0.05, 16, 2, 16)]


@pytest.mark.parametrize(("rotation", "d", "turn", "size", "dil", "k"), [
    (r, *case) for r in ("full", "z", "none") for case in _CASES if r != "z" or case[0] == 3
])  # fmt: skip
def test_the_cone_is_below_the_rmsd_of_every_window_of_its_block(rotation, d, turn, size,
                                                                 dil, k):  # fmt: skip
    # the tightest lower bounds at a block's ends (the exact RMSDs there) make the cone's
    # inequality as tight as it can be; every window between must score at least its value
    rng = np.random.default_rng(size * 100 + dil * 10 + d)
    index = _level(rng, [90, 47, 130], d, turn)
    pts = index.levels[0].pts
    span = (k - 1) * dil + 1
    n = pts.shape[0] - span + 1
    h = block_slopes(index, 0, span, size)
    nb = -(-n // size)
    covered = np.isfinite(h[:nb])
    assert covered.mean() > 0.5  # most blocks lie in one primitive
    # a noisy copy of a window (the RMSD then varies fastest near it) and a random query
    copy = pts[100 : 100 + span : dil] + rng.normal(size=(k, d)) * 0.05
    for q in (copy, rng.normal(size=(k, d)) * 3.0):
        exact = np.array([kabsch(pts[m : m + span : dil], q, rotation=rotation).rmsd
                          for m in range(n)])  # fmt: skip
        # the slope: |rmsd(m') − rmsd(m)| ≤ |m' − m|·h over each covered block and its far end
        for j in np.flatnonzero(covered):
            e = exact[j * size : min((j + 1) * size + 1, n)]
            gap = np.abs(np.arange(e.size)[:, None] - np.arange(e.size))
            assert np.all(np.abs(e[:, None] - e[None, :]) <= gap * h[j] * (1 + 1e-12) + 1e-12)
        lb_a = exact[np.arange(nb) * size]
        far = (np.arange(nb) + 1) * size
        lb_b = np.where(far < n, exact[np.minimum(far, n - 1)], -np.inf)
        worst = np.array([exact[j * size : min((j + 1) * size, n)].min() for j in range(nb)])
        value = cone_values(lb_a, lb_b, h[:nb], size, 0.0)
        assert np.all(value <= worst)
    assert np.mean(value[covered] > 0) > 0.5  # far from the random query: not vacuous
    # a block whose points cross a primitive's end is not covered
    prim = index.levels[0].prim
    first = np.arange(nb) * size
    crosses = prim[first] != prim[np.minimum(first + size + span - 1, prim.size - 1)]
    np.testing.assert_array_equal(~covered, crosses)


@pytest.fixture(scope="module")
def library():
    rng = np.random.default_rng(5)
    bank = BankIndex(Bank.from_samples(_harmonics(rng, 40, 400), DT))
    path = _harmonics(rng, 1, 600)[0]
    return bank, path


class _Counting(IndexSearch):
    """The index search, counting the windows its fine shape bound is taken on."""

    fine = 0

    def first_bound(self, aq, ws=None, stride=1):
        out = super().first_bound(aq, ws, stride)
        if stride == 1:
            self.fine += out.size
        return out


@pytest.mark.parametrize("rotation", ["full", "none"])
def test_segmentations_with_and_without_the_cone_are_equal(library, rotation):
    bank, path = library
    opts = SearchOptions(rotation=rotation)
    runs = []
    # chunk 256: every query through the sample, the screen and the best-first batches;
    # cone_min 0 and gather_fraction 1: the cone taken wherever it applies, whether it pays
    # or not
    for cone, gather in (((), 0.25), ((8, 4), 0.25), ((8, 4), 1.0), ((16, 8, 4), 1.0)):
        search = _Counting(bank, opts, chunk=256, first_batch=64, cone=cone,
                           gather_fraction=gather, cone_min=0)  # fmt: skip
        segments, _ = segment_with(search, bank, path, DT, 0.05, opts)
        runs.append((repr(segments), search.fine))
    assert all(r[0] == runs[0][0] for r in runs)
    if rotation == "none":  # the per-axis bound is tight: the cone drops most blocks
        assert runs[1][1] < 0.3 * runs[0][1]


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
def test_the_cone_keeps_every_window_below_its_gate(library, rotation):
    # a short piece at a generous eps: windows below the gate; the screen with the cone
    # (taken wherever it applies: gather_fraction 1) returns exactly those of the screen
    # without it, with the same bounds
    bank, path = library
    piece = PathPiece(path, (len(path) - 1) * DT)
    out = {}
    for cone in ((), (8, 4), (16, 8, 4)):
        search = IndexSearch(bank, SearchOptions(rotation=rotation), chunk=256, cone=cone,
                             gather_fraction=1.0, cone_min=0)  # fmt: skip
        aq = search.arc_query(piece, 0.2, 0.26, 1.0)
        out[cone] = search._screen_shape(aq, Gates.of(aq, 1.0))
    assert out[()][0].size > 0
    for cone in ((8, 4), (16, 8, 4)):
        np.testing.assert_array_equal(out[cone][0], out[()][0])
        np.testing.assert_allclose(out[cone][1], out[()][1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
@pytest.mark.parametrize("stride", [8, 16])
def test_coarse_bounds_are_those_of_every_window(library, rotation, stride):
    # every 8th (16th) window's bound from strided slices of the sums: the bounds of those
    # windows taken one by one
    bank, path = library
    piece = PathPiece(path, (len(path) - 1) * DT)
    search = IndexSearch(bank, SearchOptions(rotation=rotation))
    aq = search.arc_query(piece, 0.1, 0.3, 0.05)
    whole = search.first_bound(aq)
    for c0, c1 in ((0, aq.n_windows), (stride * 3, aq.n_windows - 5)):
        coarse = search.first_bound(aq, (c0, c1), stride=stride)
        np.testing.assert_allclose(coarse, whole[c0:c1:stride], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("quantile", [0.05, 0.3, 0.9])
def test_shape_first_keeps_the_windows_of_the_speed_screen_first(library, quantile):
    # rotation "none" takes the shape bound first once the pool has a threshold: the same
    # windows, speed and combined bounds as the speed and time-scale screen first, then the
    # speed bound, then the shape bound (the cone off, which drops windows either way)
    bank, path = library
    piece = PathPiece(path, (len(path) - 1) * DT)
    search = IndexSearch(bank, SearchOptions(rotation="none"), cone=())
    aq = search.arc_query(piece, 0.2, 0.26, 1.0)
    gates = Gates.of(aq, 1.0)
    n = aq.n_windows
    head = np.arange(0, n, 32)
    ws = np.flatnonzero(gates.valid((0, n)))
    lb = search.first_bound(aq, ws)
    tau = float(np.quantile(lb[lb > 0], quantile))
    rest, lbs, lbc = shape_first(search, aq, gates, tau, head)
    want = search._screen(aq, gates, tau, share=1.0)
    want = want[not_in(want, head, n)]
    s4, lb1 = search.speed_bound(aq, want), search.first_bound(aq, want)
    c = np.hypot(np.maximum(lb1, 0.0), np.maximum(s4, 0.0))
    keep = (s4 < tau) & (lb1 < gates.at(want)) & (c < tau)
    assert 0 < keep.sum() < want.size
    np.testing.assert_array_equal(rest, want[keep])
    np.testing.assert_array_equal(lbs, s4[keep])
    np.testing.assert_allclose(lbc, c[keep], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("chunk", [8, 12, 64, 1 << 16])
def test_the_tiles_by_chunks_are_those_of_the_whole_level(chunk):
    # the differences of the whole level (zero across a primitive's end and after the last
    # point), reduced two by two (the last tile alone): the same numbers, bit for bit
    from primlib.match._cone import first_tiles

    rng = np.random.default_rng(chunk)
    lv = _level(rng, [37, 1, 50, 2, 61], 3, 0.8).levels[0]
    pts = lv.pts
    dif = np.zeros_like(pts)
    dif[:-1] = pts[1:] - pts[:-1]
    dif[:-1][lv.prim[1:] != lv.prim[:-1]] = 0.0
    want = (dif, dif, np.sqrt(np.einsum("ij,ij->i", dif, dif)))
    for size in (1, 2, 4):
        got = first_tiles(lv, size, chunk)
        for a, b in zip(got, want, strict=True):
            assert a.shape[0] == -(-pts.shape[0] // size)
            assert a.tobytes() == b.tobytes()
        n = want[0].shape[0]  # the next size: pairs, the last row alone when odd
        want = tuple(
            np.concatenate([op(a[0 : n - 1 : 2], a[1::2]), a[n - 1 :] if n % 2 else a[:0]])
            for a, op in zip(want, (np.minimum, np.maximum, np.maximum), strict=True)
        )


@pytest.mark.parametrize("rows", [1, 5, 64])
def test_the_slopes_by_rows_are_those_of_the_whole_level(rows, monkeypatch):
    # the sliding box and norm of the whole level's tiles at once (the last blocks reading
    # what is left): the same float32 numbers, bit for bit, whatever rows a pass takes
    import primlib.match._cone as cone

    rng = np.random.default_rng(rows)
    index = _level(rng, [37, 1, 50, 2, 61], 3, 0.8)
    prim = index.levels[0].prim
    for size, span in ((4, 9), (8, 31), (4, 23), (8, 9)):
        w = 1 + -(-(span - 1) // size)
        lo, hi, top = cone._tiles(index, 0, size)
        n = top.shape[0]
        box = [np.array([a[j : j + w].min(axis=0) for j in range(n)]) for a in (lo,)]
        box += [np.array([a[j : j + w].max(axis=0) for j in range(n)]) for a in (hi, top)]
        d = box[1] - box[0]
        h = np.minimum(0.5 * np.sqrt(np.einsum("ij,ij->i", d, d)), box[2])
        first = np.arange(n) * size
        h[prim[first] != prim[np.minimum(first + w * size, prim.size - 1)]] = np.inf
        want = h.astype(np.float32)
        want[want < h] = np.nextafter(want[want < h], np.float32(np.inf))
        monkeypatch.setattr(cone, "_ROWS", rows)
        index.cache.pop(("cone", 0, size, w), None)
        got = cone.block_slopes(index, 0, span, size)
        assert got.dtype == np.float32 and got.tobytes() == want.tobytes(), (size, span)
