"""The arc-length index: uniform arc spacing, arc -> sample, cached prefix sums."""

import numpy as np
import pytest

from primlib.match import BankIndex
from primlib.match._bounds import strided_prefix_sums
from primlib.store import Bank


def _index(n: int = 2001) -> BankIndex:
    t = np.linspace(0, 1, n)
    circle = np.stack([np.cos(2 * np.pi * t), np.sin(2 * np.pi * t), 0 * t], 1) * 10
    line = np.stack([t, 2 * t, 2 * t], 1) * 30  # length 90
    return BankIndex(Bank.from_samples([circle, line], 0.01))


def test_level_zero_is_uniform_in_arc_length():
    bank = _index()
    idx = bank.arc_index()
    lv = idx.levels[0]
    for prim, length in ((0, 20 * np.pi), (1, 90.0)):
        pts = lv.pts[lv.prim == prim]
        gaps = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        # chords of arcs of length step0 on a circle of radius 10: shorter by < step0³/(24·r²)
        np.testing.assert_allclose(gaps, idx.step0, rtol=1e-3)
        assert len(pts) == int(np.floor(length * (1 - 1e-6) / idx.step0)) + 1
        np.testing.assert_allclose(pts.mean(axis=0), 0.0, atol=1e-9 * length)  # centred


@pytest.mark.parametrize("j", [0, 2])
def test_points_lie_on_the_samples_where_their_sample_index_says(j):
    # each point is the samples linear in the sample index x (taken from x's integer part
    # and fraction); a primitive's first point is its first sample, at x = 0 exactly
    bank = _index(301)
    idx = bank.fine_arc_index(j)
    lv = idx.levels[0]
    for prim in (0, 1):
        on = lv.prim == prim
        samples = bank.points_of(prim)
        x = lv.x[on]
        assert x[0] == 0.0 and np.all(np.diff(x) > 0) and x[-1] <= samples.shape[0] - 1
        ref = np.stack([np.interp(x, np.arange(samples.shape[0]), c) for c in samples.T], 1)
        pts = lv.pts[on]
        # centred per primitive: the differences from the samples are one constant
        np.testing.assert_allclose(pts - pts[0], ref - ref[0], atol=1e-12 * 90)


def test_levels_halve_and_double_the_step():
    idx = _index().arc_index()
    for a, b in zip(idx.levels[:-1], idx.levels[1:], strict=True):
        assert b.step == 2 * a.step
        assert abs(len(b.pts) - len(a.pts) / 2) <= 2


def test_arc_to_sample_follows_the_line_at_constant_speed():
    bank = _index()
    idx = bank.arc_index()
    lv = idx.levels[0]
    on_line = np.flatnonzero(lv.prim == 1)
    g = lv.garc[on_line]
    x = idx.arc_to_sample(g)
    # the line runs at constant speed: sample index proportional to arc length
    # (the global arc axis adds 1e-12·step per sample to stay strictly increasing)
    np.testing.assert_allclose(x, (g - g[0]) / 90.0 * 2000, atol=1e-5)


def test_arc_past_a_primitives_end_stays_at_its_last_sample():
    bank = _index()
    idx = bank.arc_index()
    n0 = int(bank.offsets[1] - bank.offsets[0])
    end = idx.end_arc[0]
    past = end + np.array([0.0, 0.5, 1.0, 3.0]) * idx.step0
    # without the primitive the arc axis runs into the gap before the next primitive,
    # where the sample index falls back towards 0
    assert np.all(np.diff(idx.arc_to_sample(past)) < 0)
    np.testing.assert_array_equal(idx.arc_to_sample(past, np.zeros(4, dtype=int)), n0 - 1)


def test_sums_are_cached_on_the_index():
    idx = _index().arc_index()
    a = idx.sums(0, 2)
    assert idx.sums(0, 2) is a
    np.testing.assert_array_equal(a[0], strided_prefix_sums(idx.levels[0].pts, 2)[0])
    # without the products: the first rows of those already built
    short = idx.sums(0, 2, products=False)
    assert np.shares_memory(short[0], a[0]) and short[0].shape[0] == 4


def test_sums_without_products_are_built_alone_and_cached():
    idx = _index().arc_index()
    short = idx.sums(1, 2, products=False)
    assert idx.sums(1, 2, products=False) is short
    full = idx.sums(1, 2)
    np.testing.assert_array_equal(short[0], full[0][:4])
    assert short[2] == full[2]


def test_fine_index_is_built_once_and_capped():
    bank = _index()
    fine = bank.fine_arc_index(2)
    assert bank.fine_arc_index(2) is fine
    # 4x the points of the base level 0 (which has one point per step plus the ends)
    assert fine.step0 == pytest.approx(bank.arc_index().step0 / 4, rel=0.01)
    assert bank.fine_arc_index(0) is bank.arc_index()


def test_fine_indexes_keep_level_zero_and_stay_within_the_cap(monkeypatch):
    import primlib.match._bank as bank_module

    bank = _index()
    n0 = bank.arc_index().levels[0].pts.shape[0]
    # room for the 2x and 4x indexes together, not for the 8x one beside them
    monkeypatch.setattr(bank_module, "_FINE_CAP", 8.5 * n0)
    two, four = bank.fine_arc_index(1), bank.fine_arc_index(2)
    assert len(two.levels) == len(four.levels) == 1
    assert bank.fine_arc_index(1) is two  # kept: 6x n0 points in all
    eight = bank.fine_arc_index(3)  # 8x: the least recently used (4x), then 2x, go
    assert bank.fine_arc_index(3) is eight
    assert bank.fine_arc_index(1) is not two
    assert sum(f.n_points for f in bank._fine.values()) <= 8.5 * n0 + 2 * bank.k
