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


def test_sums_with_the_squares_alone_serve_fewer_rows_and_give_way_to_all():
    # rotation "none" builds the squares' rows alone; the d + 1 rows are sliced from them,
    # and the full sums, once built, serve both
    idx = _index().arc_index()
    sq = idx.sums(2, 1, products="squares")
    assert sq[0].shape[0] == 7 and idx.sums(2, 1, products="squares") is sq
    short = idx.sums(2, 1, products=False)
    assert np.shares_memory(short[0], sq[0]) and short[0].shape[0] == 4
    full = idx.sums(2, 1)
    np.testing.assert_array_equal(sq[0], full[0][:7])
    assert np.shares_memory(idx.sums(2, 1, products="squares")[0], full[0])


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


def _reference_arcs(sm, lv0_counts, levels):
    """Each level's global arc and arc left as the build once held them: level 0 formed by
    np.repeat over every point (first + n·step0, length − n·step0), each coarser level
    every other point of the one below (np.compress), as the pyramid is taken."""
    step0 = levels[0].step
    first = sm.starts + sm.gap
    base = np.concatenate([[0], np.cumsum(lv0_counts)])
    local = np.arange(base[-1]) - np.repeat(base[:-1], lv0_counts)
    arc = local * step0
    garc, left = np.repeat(first, lv0_counts) + arc, np.repeat(sm.length, lv0_counts) - arc
    out = []
    for _ in levels:
        out.append((garc, left))
        sel = local % 2 == 0
        garc, left, local = garc[sel], left[sel], local[sel] // 2
    return out


def _banks():
    rng = np.random.default_rng(7)
    walks = [np.cumsum(rng.normal(size=(int(n), 3)), axis=0) for n in rng.integers(2, 900, 9)]
    noisy = [w + rng.normal(size=w.shape) * 0.3 for w in walks[:3]]
    flat = [np.cumsum(rng.normal(size=(300, 2)), axis=0) for _ in range(3)]
    return [_index(), BankIndex(Bank.from_samples(walks + noisy, 0.01)),
            BankIndex(Bank.from_samples(flat, 0.01))]  # fmt: skip


@pytest.mark.parametrize("which", [0, 1, 2])
@pytest.mark.parametrize("j", [0, 1, 3])
def test_arcs_computed_on_access_are_those_the_pyramid_held(which, j):
    # garc and left are computed for the points asked (16 bytes a point not held): bit for
    # bit what a level built by np.repeat, then halved by np.compress, held, whichever way
    # they are indexed
    bank = _banks()[which]
    idx = bank.fine_arc_index(j)
    lv0 = idx.levels[0]
    counts = np.bincount(lv0.prim, minlength=bank.k)
    rng = np.random.default_rng(j)
    refs = _reference_arcs(bank.arc_samples(), counts, idx.levels)
    for lv, (garc, left) in zip(idx.levels, refs,
                                strict=True):  # fmt: skip
        assert lv.garc.shape == garc.shape and len(lv.left) == left.size
        np.testing.assert_array_equal(np.asarray(lv.garc), garc)
        np.testing.assert_array_equal(np.asarray(lv.left), left)
        some = rng.integers(0, garc.size, 40)
        np.testing.assert_array_equal(lv.garc[some], garc[some])
        np.testing.assert_array_equal(lv.left[3:-2], left[3:-2])
        mask = rng.random(garc.size) < 0.3
        np.testing.assert_array_equal(lv.left[mask], left[mask])


@pytest.mark.parametrize("j", [0, 2])
def test_points_that_fit_are_exactly_those_with_the_arc_left(j):
    # counted per primitive by bisection on the arc-left formula: the same points as
    # left >= need, for needs on, just above and just below a point's own arc left
    for bank in _banks():
        for lv in bank.fine_arc_index(j).levels:
            left = np.asarray(lv.left)
            rng = np.random.default_rng(lv.prim.size)
            needs = [*left[rng.integers(0, left.size, 12)], 0.0, -1.0, left.max() * 1.01]
            for need in needs:
                for v in (need, np.nextafter(need, np.inf), np.nextafter(need, -np.inf)):
                    np.testing.assert_array_equal(lv.fits(v), left >= v)
