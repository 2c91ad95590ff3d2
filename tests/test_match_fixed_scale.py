"""A fixed time scale: the exhaustive grid at that scale on small banks, the index on large
ones (``_segment.seeder_for``: the grid resamples the whole bank for every piece, 10x the
index's time on 1,000 primitives), and either finds a path composed at that scale; the
grid's cell slack from the steps of the window's own stretch."""

import numpy as np
import pytest
from test_match_index_search import DT, _harmonics

from primlib.match import BankIndex, kabsch, segment_path
from primlib.match._grid import GridSearch, _Scale
from primlib.match._grid_bound import speed_bounds
from primlib.match._index_search import GRID_BANK, IndexSearch
from primlib.match._segment import resolve_options, seeder_for
from primlib.store import Bank


def _bank(k: int) -> tuple[BankIndex, list[np.ndarray]]:
    prims = _harmonics(np.random.default_rng(5), k, 400)
    return BankIndex(Bank.from_samples(prims, DT)), prims


@pytest.mark.parametrize("k", [20, 90])
def test_a_fixed_time_scale_searches_the_grid_only_on_a_small_bank(k):
    bank, _ = _bank(k)
    fixed = seeder_for(bank, resolve_options("full", (1.0, 1.0), None))
    small = bank.points.shape[0] <= GRID_BANK
    assert small == (k == 20)  # 8,000 and 36,000 samples
    assert isinstance(fixed, GridSearch if small else IndexSearch)
    assert isinstance(seeder_for(bank, resolve_options("full", (0.5, 2.0), None)), IndexSearch)


def test_a_path_composed_at_the_fixed_scale_is_found_on_a_large_bank():
    bank, prims = _bank(90)
    rng = np.random.default_rng(8)
    pieces, used = [], [(7, 40, 200), (31, 100, 260), (64, 20, 180)]
    for i, s0, s1 in used:
        r = kabsch(np.eye(3), np.linalg.qr(rng.normal(size=(3, 3)))[0]).rotation
        p = prims[i][s0:s1] @ np.asarray(r).T
        pieces.append(p - p[0] + (pieces[-1][-1] if pieces else 0.0))
    path = np.vstack([pieces[0]] + [p[1:] for p in pieces[1:]])
    segs, _ = segment_path(bank, path, DT, 1e-3, time_scale=(1.0, 1.0))
    assert [s.primitive for s in segs] == [bank.ids[i] for i, _, _ in used]
    assert all(s.time_scale == pytest.approx(1.0) and s.rmsd < 1e-3 for s in segs)


@pytest.mark.parametrize(("dur", "cell"), [(3.0, 0.4), (17.5, 2.2), (60.0, 0.05)])
def test_the_grid_cell_slack_takes_the_largest_speed_of_the_window_stretch(dur, cell):
    # primitives that run slow, then fast: a slow window's slack is the slow steps'
    rng = np.random.default_rng(3)
    prims = []
    for _ in range(3):
        v = np.concatenate([np.full(150, 0.01), np.full(150, 1.0)])[:, None] * rng.normal(size=3)
        prims.append(np.cumsum(v * rng.uniform(0.5, 1.5, (300, 1)), axis=0))
    bank = BankIndex(Bank.from_samples(prims, DT))
    grid = GridSearch(bank, resolve_options("full", None, None))
    sc = _Scale(np.arange(bank.k), np.ones(bank.k, dtype=np.int64), dur, dur / 15, cell)
    got = grid._local_speeds(sc, np.arange(bank.points.shape[0]))
    pts, offsets = bank.points, bank.offsets
    step = np.r_[np.linalg.norm(np.diff(pts, axis=0), axis=1), 0.0]
    step[offsets[1:] - 1] = 0.0  # no step from one primitive to the next
    speed = speed_bounds(pts, offsets)  # the interpolant's speed bound per interval
    lo, hi = int(np.ceil(cell)) + 1, int(np.ceil(dur)) + int(np.ceil(cell)) + 2
    want = [speed[max(j - lo, 0) : j + hi + 1].max() for j in range(pts.shape[0])]
    np.testing.assert_array_equal(got, want)
    assert np.all(got >= [step[max(j - lo, 0) : j + hi + 1].max() for j in range(pts.shape[0])])
    # the bank's own steps: the arc samples' largest per primitive is theirs
    np.testing.assert_allclose(bank.steps(), step, rtol=1e-14)
    np.testing.assert_allclose(bank.max_step(), np.maximum.reduceat(step, offsets[:-1]), rtol=1e-14)
    # far below the primitive's largest step where a window starts slow and stays slow
    assert got[offsets[1] + 10] < 0.05 * bank.max_step()[1]  # reaches sample 75 at most
    # a stretch's speed bound: at or above that of every start in [a, a + extra]
    # (module notes of _grid_bound)
    for extra in (0, 3, 40):
        at = np.arange(pts.shape[0])
        wide = grid._stretch_speeds(sc, at, extra)
        assert np.all(wide >= [got[j : j + extra + 1].max() for j in at])
        lo, hi = sc.back, sc.size - sc.back + extra
        assert np.all(wide >= [speed[max(j - lo, 0) : j + hi].max() for j in at])


def test_the_grid_resamples_as_cubic_at_does():
    # the coefficient table: the same numbers as cubic_at to the last bit
    from primlib.match._interp import cubic_at

    bank, _ = _bank(20)
    grid = GridSearch(bank, resolve_options("none", None, None))
    rng = np.random.default_rng(11)
    prim = rng.integers(0, bank.k, 5000)
    counts = bank.counts[prim]
    x = rng.uniform(-0.5, 1.2, prim.size) * (counts - 1)
    x[:50], x[50:100] = counts[:50] - 1.0, np.floor(x[50:100])  # the ends; on samples
    want = cubic_at(bank.points, bank.offsets[prim], counts, x)
    np.testing.assert_array_equal(grid._resample(prim, x), want)


def test_the_grid_cell_slack_bounds_how_far_a_point_moves_between_alternating_steps():
    # a zigzag: d_{i+1} = -d_i, where Catmull-Rom's speed reaches 1.5 |d| at mid-interval
    # (1.25 times the largest step, as the slack took before, falls short)
    from primlib.match._interp import cubic_at

    n = 40
    zig = np.zeros((n, 3))
    zig[:, 0] = np.arange(n) * 0.01
    zig[:, 1] = 0.5 * (-1.0) ** np.arange(n)
    bank = BankIndex(Bank.from_samples([zig], DT))
    grid = GridSearch(bank, resolve_options("full", None, None))
    dur, cell = 6.0, 0.5
    sc = _Scale(np.arange(1), np.ones(1, dtype=np.int64), dur, dur / 15, cell)
    x0 = np.array([10.0, 17.25, 20.5])
    slack = grid._slack(np.zeros(3, dtype=np.int64), x0, sc)
    x = x0[:, None] + np.linspace(0.0, dur, 16)  # the window's grid points

    def at(xs):  # the stored curve at sample indices xs
        m = xs.size
        return cubic_at(bank.points, np.zeros(m, dtype=np.int64), np.full(m, n), xs.ravel())

    base = at(x)
    for shift in np.linspace(-cell, cell, 41):  # every move within the cell
        moved = at(x + shift)
        far = np.linalg.norm(moved - base, axis=1).reshape(x.shape).max(axis=1)
        assert np.all(far <= slack * (1 + 1e-12))
    # and the bound is not slack for nothing: the point at mid-interval moves ~1.5 |d| c
    mid = at(np.array([20.45, 20.55]))
    assert np.linalg.norm(mid[1] - mid[0]) / 0.1 > 1.25 * bank.max_step()[0]
