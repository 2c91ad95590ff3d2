"""The grid's blocks of starts and caps across scales (``_grid``, ``_grid_bound``): a block's
bound is below every window that starts in it, blocks split the windows exactly, and the
search under caps and blocks returns the seeds (and the segmentation) of the search without."""

import math

import numpy as np
import pytest
from match_helpers import smooth_walk

from primlib.match import BankIndex, segment_path
from primlib.match._grid import GridSearch, _coefficient_table, _coefficients_at
from primlib.match._grid_blocks import Scale, StartBlocks, _in_block_order, runs, without
from primlib.match._grid_bound import (
    above32,
    below32,
    beyond,
    block_boxes,
    box_gaps,
    chord_boxes,
    chord_radii,
    endpoint_gap,
    halved_boxes,
    speed_bounds,
)
from primlib.match._interp import cubic_at
from primlib.match._options import PathPiece, SearchOptions
from primlib.store import Bank

DT = 0.01
K = 16


def _walk(rng, n: int, speed: float, stop: bool = False) -> np.ndarray:
    """A smooth random 3-D curve of n samples moving ~``speed`` a sample; with ``stop``, at
    rest over its middle third."""
    return smooth_walk(rng, n, speed, width=9, rest=slice(n // 3, 2 * n // 3) if stop else None,
                       spread=20.0)  # fmt: skip


def _bank(rng, k: int = 6, n: int = 400) -> BankIndex:
    """Primitives at several speeds and lengths (so that blocks straddle their seams), every
    third at rest a while, and one of 3 samples."""
    prims = [_walk(rng, n + 37 * i, rng.uniform(0.02, 0.3), stop=i % 3 == 0) for i in range(k)]
    prims.append(_walk(rng, 3, 0.1))
    return BankIndex(Bank.from_samples(prims, DT))


def _windows(bank: BankIndex, sc: Scale) -> tuple[np.ndarray, np.ndarray]:
    """Every window of a whole scale: its primitive and index m."""
    prim = np.repeat(sc.prim, sc.n_start)
    m = np.concatenate([np.arange(n) for n in sc.n_start])
    return prim, m


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
def test_a_blocks_bounds_are_below_every_window_that_starts_in_it(rotation):
    rng = np.random.default_rng(11)
    bank = _bank(rng)
    speeds = speed_bounds(bank.points, bank.offsets)
    root = math.sqrt(2 * K)
    for trial in range(12):
        q_chord = np.zeros(3) if trial % 3 == 0 else rng.normal(size=3) * rng.uniform(0.1, 3)
        dq = rng.uniform(6.0, 120.0)
        grid = GridSearch(bank, SearchOptions(rotation=rotation))
        path = PathPiece(np.zeros((2, 3)), dq * DT)
        for sc in grid._scales(path, 0.0, 1.0):
            fd = math.floor(sc.dur)
            if fd < 7:
                continue
            width = 1 << int(math.log2((fd - 1) / 3.0))
            lo, hi = block_boxes(bank.points, speeds, chunk=6)  # chunks: the same boxes
            for _ in range(int(math.log2(width)) - 1):
                lo, hi = halved_boxes(lo, hi)
            span = ((fd - 1) // width, 1 + fd // width)  # the blocks a window ends in
            exact = box_gaps(*chord_boxes(lo, hi, *span), q_chord, rotation) / root
            near, far = chord_radii(*chord_boxes(lo, hi, 3, 7))
            length = np.linalg.norm(q_chord)
            wide = np.maximum(np.maximum(near - length, length - far), 0.0) / root
            prim, m = _windows(bank, sc)
            x0 = m * sc.h
            starts = cubic_at(bank.points, bank.offsets[prim], bank.counts[prim], x0)
            ends = cubic_at(bank.points, bank.offsets[prim], bank.counts[prim],
                            (m + K - 1) * sc.h)  # fmt: skip
            g = endpoint_gap(ends - starts, q_chord, rotation) / root
            block = (bank.offsets[prim] + np.floor(x0).astype(int)) // width
            assert np.all(g >= exact[block] - 1e-12)
            assert np.all(exact >= wide - 1e-12)  # the wider union: the smaller bound
            # and the search's blocks, with no limit, keep every block with a bound at
            # least as large; under a limit, those whose bound is not beyond it
            grid.few = 0
            starts = grid._start_blocks(sc)
            live, bound = starts.bounds(sc.dur, q_chord, rotation, K, math.inf, 0.0, 0.0)
            assert live.tolist() == list(range(near.size))
            assert np.all(g >= bound[block] - 1e-12)
            for part in (0.02, 0.3, 0.8):  # few blocks (sorted), some (a mask), most (all)
                limit = float(np.quantile(bound, part))
                some, below = starts.bounds(sc.dur, q_chord, rotation, K, limit, 0.0, 0.0)
                np.testing.assert_array_equal(some, live[~beyond(bound, limit, 0.0, 0.0)])
                np.testing.assert_array_equal(below, bound[some])
            # the gathered chords (a few blocks' bounds): the sliced ones, but at and before
            # a seam, whose own parts raise the bound and still hold every window
            rows = np.arange(0, near.size, 3)
            gathered = box_gaps(*starts._chords_at(width, rows, span), q_chord, rotation) / root
            seam = np.zeros(rows.size, dtype=bool)
            seam[starts._near_seams(width, rows, span)] = True
            np.testing.assert_array_equal(gathered[~seam], exact[rows][~seam])
            assert np.all(gathered >= exact[rows])
            at = np.flatnonzero(block % 3 == 0)
            assert np.all(g[at] >= gathered[block[at] // 3] - 1e-12)


@pytest.mark.parametrize("share", [0.01, 0.2, 0.9])
def test_kept_blocks_come_in_block_order_with_their_values(share):
    rng = np.random.default_rng(int(share * 100))
    count = 5000
    rows = rng.permutation(count)[: count // 2]  # a prefix of the blocks in some order
    values = rng.normal(size=rows.size)
    keep = rng.random(rows.size) < share  # few: sorted; more: through a mask of all blocks
    live, kept = _in_block_order(rows, values, keep, count)
    order = np.argsort(rows[keep])
    np.testing.assert_array_equal(live, rows[keep][order])
    np.testing.assert_array_equal(kept, values[keep][order])


def test_a_seams_boxes_hold_its_last_primitives_starts_and_its_firsts_ends():
    # where a primitive starts inside a block, windows start there only on the block's last
    # primitive's intervals and end there only on its first's: each part has its own box
    rng = np.random.default_rng(4)
    bank = _bank(rng)
    speeds = speed_bounds(bank.points, bank.offsets)
    starts = StartBlocks(bank.points, bank.offsets, speeds)
    low, high = bank.points - speeds[:, None], bank.points + speeds[:, None]
    for width in (2, 8, 32):
        block, mask, s_lo, s_hi, e_lo, e_hi = starts.seams(width)
        inner = bank.offsets[1:-1]
        want = np.unique(inner[inner % width != 0] // width)
        np.testing.assert_array_equal(block, want)
        assert mask.sum() == block.size and np.all(mask[block])
        for j, x in enumerate(block):
            cut = inner[(inner > x * width) & (inner < (x + 1) * width)]
            last = slice(cut.max(), min((x + 1) * width, len(bank.points)))
            first = slice(x * width, cut.min())
            np.testing.assert_allclose(s_lo[j], low[last].min(axis=0), rtol=1e-6)
            np.testing.assert_allclose(s_hi[j], high[last].max(axis=0), rtol=1e-6)
            np.testing.assert_allclose(e_lo[j], low[first].min(axis=0), rtol=1e-6)
            np.testing.assert_allclose(e_hi[j], high[first].max(axis=0), rtol=1e-6)
            assert np.all(s_lo[j] <= low[last].min(axis=0))
            assert np.all(e_hi[j] >= high[first].max(axis=0))
    # and they bound: a seam's union box spans two primitives apart, its own parts less
    for dur in (40.0, 130.0):
        live, bound = starts.bounds(dur, np.zeros(3), "full", K, math.inf, 0.0, 0.0)
        width = starts.width(dur)
        block = starts.seams(width)[0]
        fd = math.floor(dur)
        span = ((fd - 1) // width, 1 + fd // width)
        c_lo, c_hi = chord_boxes(*starts.boxes(width), *span)
        union = box_gaps(c_lo[block], c_hi[block], np.zeros(3), "full") / math.sqrt(2 * K)
        own = bound[np.searchsorted(live, block)]
        assert np.all(own >= union) and np.any(own > union + 1e-3)


def test_float32_boxes_and_ranges_round_outwards():
    rng = np.random.default_rng(2)
    x = rng.normal(size=10_000) * 10.0 ** rng.uniform(-6, 6, 10_000)
    assert np.all(below32(x).astype(np.float64) <= x)
    assert np.all(above32(x).astype(np.float64) >= x)
    assert np.all(above32(x) - below32(x) <= 2 * np.spacing(np.abs(x).astype(np.float32)))
    pts, speeds = rng.normal(size=(103, 3)), rng.uniform(0, 0.1, 103)
    lo, hi = halved_boxes(*block_boxes(pts, speeds, chunk=10))
    assert lo.shape == hi.shape == (26, 3) and lo.dtype == np.float32
    for b in range(26):
        i = slice(4 * b, min(103, 4 * b + 4))
        assert np.all(lo[b] <= (pts[i] - speeds[i, None]).min(axis=0))
        assert np.all(hi[b] >= (pts[i] + speeds[i, None]).max(axis=0))


def test_the_runs_of_a_set_of_blocks_hold_each_of_their_windows_once():
    rng = np.random.default_rng(3)
    bank = _bank(rng, k=5, n=300)
    grid = GridSearch(bank, SearchOptions())
    for dq in (6.0, 13.0, 40.0):
        for sc in list(grid._scales(PathPiece(np.zeros((2, 3)), dq * DT), 0.0, 1.0))[::5]:
            width = 1 << int(rng.integers(0, 4))
            prim, m = _windows(bank, sc)
            block = (bank.offsets[prim] + np.floor(m * sc.h).astype(int)) // width
            n_blocks = -(-bank.points.shape[0] // width)
            parts = np.array_split(rng.permutation(n_blocks), 3)
            seen = []
            for part in parts:
                got = runs(part, width, bank.offsets, sc)
                if got is None:
                    continue
                for p, a, n in zip(got.prim, got.first(), got.n_start, strict=True):
                    seen += [(p, w) for w in range(a, a + n)]
                    assert np.all(np.isin(block[(prim == p) & (m >= a) & (m < a + n)], part))
            assert sorted(seen) == sorted(zip(prim.tolist(), m.tolist(), strict=True))


def test_a_scale_without_some_runs_holds_every_other_window_once():
    rng = np.random.default_rng(1)
    for _ in range(200):
        k = int(rng.integers(1, 6))
        prim = np.sort(rng.choice(20, k, replace=False))
        n = rng.integers(1, 30, k)
        sc = Scale(prim, n, 5.0, 0.3, 1.0)
        runs = []
        for p, c in zip(prim, n, strict=True):
            cuts = np.sort(rng.choice(c + 1, min(c + 1, 2 * int(rng.integers(0, 3))) // 2 * 2,
                                      replace=False))  # fmt: skip
            runs += [(p, a, b) for a, b in zip(cuts[0::2], cuts[1::2], strict=True) if b > a]
        taken = None
        if runs:
            p, a, b = map(np.array, zip(*runs, strict=True))
            taken = Scale(p, b - a, 5.0, 0.3, 1.0, a)
        rest = without(sc, taken)
        every = {(p, w) for p, c in zip(prim, n, strict=True) for w in range(c)}
        out = {(p, w) for p, a, b in runs for w in range(a, b)}
        got = [(p, w) for p, a, c in zip(rest.prim, rest.first(), rest.n_start, strict=True)
               for w in range(a, a + c)]  # fmt: skip
        assert len(got) == len(set(got)) and set(got) == every - out


def test_coefficients_formed_from_neighbours_are_the_tables_to_the_bit():
    rng = np.random.default_rng(0)
    counts = np.array([2, 3, 5, 40, 2, 17])
    offsets = np.concatenate([[0], np.cumsum(counts)])
    pts = rng.normal(size=(offsets[-1], 3)) * 1e3
    table = _coefficient_table(pts, offsets)
    prim = rng.integers(0, counts.size, 500)
    i = np.array([rng.integers(0, counts[p] - 1) for p in prim])
    rows = offsets[prim] + i
    for got, want in zip(_coefficients_at(pts, rows, i, counts[prim]), table, strict=True):
        assert np.array_equal(got, want[rows])


def test_searches_on_one_index_share_its_grid_tables():
    # a segmentation makes a GridSearch of its own: the tables of the bank (coefficients,
    # speed bounds, blocks) are kept on the index, so a second search makes none again,
    # whatever its options, and finds what the first found
    rng = np.random.default_rng(5)
    bank = _bank(rng)
    pieces = [
        PathPiece(np.zeros((30, 3)) + bank.points[7], 29 * DT),  # at rest
        PathPiece(_walk(rng, 300, 0.01), 299 * DT),
    ]  # long: the coefficient table
    first = GridSearch(bank, SearchOptions())
    first.few = 0  # blocks on every scale
    seeds = [first.seeds(p, 0.0, 1.0, 0.05) for p in pieces]
    kept = dict(bank.grid_tables)
    assert {"table", "starts", "block_max", "speeds", "extent"} <= kept.keys()
    for rotation in ("none", "full"):
        other = GridSearch(bank, SearchOptions(rotation=rotation))
        other.few = 0
        found = [other.seeds(p, 0.0, 1.0, 0.05) for p in pieces]
        assert bank.grid_tables.keys() == kept.keys()
        assert all(bank.grid_tables[k] is v for k, v in kept.items())  # none made again
    assert found == seeds
    assert BankIndex(bank.bank).grid_tables == {}  # a new index: its own, made when asked


def _plain(monkeypatch) -> None:
    """The grid without blocks or caps, as before them."""
    monkeypatch.setattr(GridSearch, "_start_blocks", lambda self, sc: None)
    pooled = GridSearch._pooled
    monkeypatch.setattr(GridSearch, "_pooled",
                        lambda self, *a, capped: pooled(self, *a, capped=False))  # fmt: skip


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_blocks_and_caps_return_the_seeds_of_the_plain_grid(rotation, seed, monkeypatch):
    rng = np.random.default_rng(40 + seed)
    bank = _bank(rng)
    opts = SearchOptions(rotation=rotation)
    pieces = [
        PathPiece(np.zeros((30, 3)) + rng.normal(size=3), 29 * DT),  # at rest
        PathPiece(_walk(rng, 40, 0.01), 39 * DT),  # slow
        PathPiece(bank.points[bank.offsets[1] + 50 : bank.offsets[1] + 90], 39 * DT),  # stored
    ]
    got = []
    for piece in pieces:
        grid = GridSearch(bank, opts)
        grid.few = 0  # blocks on every scale
        got.append([(c.prim, c.x0, c.x1, c.score) for c in grid.seeds(piece, 0.0, 1.0, 0.05)])
    _plain(monkeypatch)
    for piece, seeds in zip(pieces, got, strict=True):
        grid = GridSearch(bank, opts)
        want = [(c.prim, c.x0, c.x1, c.score) for c in grid.seeds(piece, 0.0, 1.0, 0.05)]
        assert [s[:3] for s in seeds] == [w[:3] for w in want]
        # an RMSD from moments may differ in its last bits with the batch it was scored in
        np.testing.assert_allclose([s[3] for s in seeds], [w[3] for w in want], rtol=1e-9,
                                   atol=1e-12)  # fmt: skip


def test_a_path_that_stops_is_cut_as_by_the_plain_grid(monkeypatch):
    # a path at rest for a while: its pieces at rest go to the grid (too short in arc length
    # to index); blocks and caps change what the grid scores, not the segmentation
    rng = np.random.default_rng(5)
    bank = _bank(rng, k=8)
    pts = _walk(rng, 500, 0.1, stop=True)
    monkeypatch.setattr(GridSearch, "few", 0)
    got, _ = segment_path(bank, pts, DT, 0.05)
    _plain(monkeypatch)
    want, _ = segment_path(bank, pts, DT, 0.05)
    assert [(s.end, s.primitive) for s in got] == [(s.end, s.primitive) for s in want]
    assert any(s.primitive is not None for s in got)
