"""The pruned best-first search against every window scored, on pieces of a path the library
does not hold (the pool then fills with near ties, and its threshold does the pruning)."""

import numpy as np
import pytest
from _reference_search import ScanSearch

from primlib.match import BankIndex, SearchOptions
from primlib.match._index_search import IndexSearch, _Gates
from primlib.match._options import PathPiece
from primlib.store import Bank

DT = 0.01


def _harmonics(rng, k: int, n: int, d: int = 3) -> list[np.ndarray]:
    """k smooth random curves (sums of 6 harmonics), n samples each, ~50 units wide."""
    t = np.linspace(0, 1, n)[:, None, None]
    f = np.arange(1, 7)[None, :, None]
    out = []
    for _ in range(k):
        amp = rng.normal(size=(1, 6, d)) * 50 / f**1.5
        ph = rng.uniform(0, 2 * np.pi, size=(1, 6, d))
        out.append((amp * np.sin(2 * np.pi * f * t + ph)).sum(axis=1))
    return out


@pytest.fixture(scope="module")
def novel():
    rng = np.random.default_rng(11)
    bank = BankIndex(Bank.from_samples(_harmonics(rng, 40, 400), DT))
    path = _harmonics(rng, 1, 600)[0]
    return bank, PathPiece(path, (len(path) - 1) * DT)


# chunk: windows a query has at most to be searched in one batch (a small library); 256
# sends every query here through the sample, the screen and the best-first batches
@pytest.mark.parametrize("chunk", [256, 8192])
@pytest.mark.parametrize("rotation", ["full", "none"])
@pytest.mark.parametrize(("a", "b"), [(0.0, 0.05), (0.2, 0.24), (0.5, 0.58), (0.3, 0.5)])
def test_pruned_seeds_equal_every_window_scored(novel, rotation, a, b, chunk):
    bank, path = novel
    opts = SearchOptions(rotation=rotation)
    eps = 0.05
    pruned = IndexSearch(bank, opts, chunk=chunk, first_batch=64)
    scan = ScanSearch(bank, opts, chunk=chunk, first_batch=64)
    assert pruned.seeds(path, a, b, eps) == scan.seeds(path, a, b, eps)
    assert pruned.stats.scored < scan.stats.scored


def test_the_pool_is_that_of_every_window_offered_at_once(novel):
    # a short piece: most windows are below the gate, the pool fills to its cap and only
    # its threshold prunes; the pool must be what offering every window at once gives
    bank, path = novel
    search = IndexSearch(bank, SearchOptions(), chunk=256, first_batch=64)
    aq = search.arc_query(path, 0.2, 0.24, 0.05)
    assert aq.n_windows > 4 * search.chunk  # the sample, the screen, the batches
    gates = _Gates.of(aq, 0.05)
    pool = search._best_first(aq, gates)
    assert len(pool.items) == search.pool_cap
    scan = ScanSearch(bank, SearchOptions(), chunk=256, first_batch=64)
    whole = scan._best_first(aq, gates)
    np.testing.assert_array_equal(pool.keys, whole.keys)
    assert pool.items == whole.items
    assert search.stats.scored < 0.2 * scan.stats.scored


def test_the_same_query_twice_in_a_row_is_answered_without_a_second_search(novel):
    # a probe that matches at once, then the segment's choice of its best match, ask for the
    # same piece: the second answer is the first, with no windows searched again
    bank, path = novel
    search = IndexSearch(bank, SearchOptions())
    first = search.seeds(path, 0.3, 0.5, 0.05)
    queries, scored = search.stats.queries, search.stats.scored
    again = search.seeds(path, 0.3, 0.5, 0.05)
    assert again == first and again is not first
    assert (search.stats.queries, search.stats.scored) == (queries, scored)
    # another piece, or the same piece of another path, is searched
    search.seeds(path, 0.3, 0.45, 0.05)
    assert search.stats.queries == queries + 1
    copy = PathPiece(path.points.copy(), path.duration)
    assert search.seeds(copy, 0.3, 0.45, 0.05) == IndexSearch(bank, SearchOptions()).seeds(
        copy, 0.3, 0.45, 0.05
    )
    assert search.stats.queries == queries + 2


@pytest.mark.parametrize("rotation", ["full", "none", "z"])
def test_both_screen_orders_keep_the_same_windows_with_the_same_bounds(novel, rotation):
    # the shape bound first (most windows in time-scale range) or the time-scale test first
    # (few): the same windows below the gate, with the same bounds, the head left out
    bank, path = novel
    search = IndexSearch(bank, SearchOptions(rotation=rotation), chunk=256, first_batch=64)
    aq = search.arc_query(path, 0.2, 0.24, 0.05)  # short: many windows below the gate
    gates = _Gates.of(aq, 0.05)
    head = np.arange(0, aq.n_windows, search.sample)
    first, bounds = search._below_gate(aq, gates, head, share=1.0)
    later, bounds_later = search._below_gate(aq, gates, head, share=0.0)
    assert first.size > 0
    np.testing.assert_array_equal(first, later)
    np.testing.assert_allclose(bounds, bounds_later, rtol=1e-12, atol=1e-12)
    assert not np.isin(first, head).any()
    assert np.all(bounds < gates.gate)
    # a range of windows is bounded as those windows of the whole array
    whole = search.first_bound(aq)
    np.testing.assert_array_equal(search.first_bound(aq, (5, 105)), whole[5:105])


def test_the_drain_from_sorted_bounds_scores_what_a_selection_per_batch_does(novel, monkeypatch):
    # short pieces, clean and under noise of ten times eps (nothing matches: the threshold
    # stays up and the drain visits most windows): the bounds sorted a front at a time give
    # the seeds and the counts of choosing each batch from all that is left (._drain)
    from primlib.match import _drain, _index_search

    bank, path = novel
    rng = np.random.default_rng(3)
    noisy = PathPiece(path.points + rng.normal(scale=0.5, size=path.points.shape), path.duration)
    pieces = [(path, 0.2, 0.24), (path, 0.5, 0.53), (noisy, 0.2, 0.22), (noisy, 0.6, 0.63)]
    fronts = []
    sorted_drain = _drain.drain_sorted

    def counted(search, aq, gates, pool, windows, size):
        fronts.append(windows[0].size)
        return sorted_drain(search, aq, gates, pool, windows, size)

    monkeypatch.setattr(_index_search, "drain_sorted", counted)
    monkeypatch.setattr(_drain, "FRONT", 2)  # several fronts: their ends join the rest

    def run(sorted_from):
        monkeypatch.setattr(_index_search, "_SORTED_FROM", sorted_from)
        search = IndexSearch(bank, SearchOptions(), chunk=256, first_batch=64)
        seeds = [search.seeds(p, a, b, 0.05) for p, a, b in pieces]
        return seeds, (search.stats.bounded, search.stats.scored)

    per_batch = run(10**9)
    assert not fronts
    assert run(1) == per_batch
    assert max(fronts) > 2 * 2 * 256  # drained from sorted bounds, over several fronts


@pytest.mark.parametrize("time_scale", [(1.0, 1.0), (0.95, 1.05)])
def test_rotation_none_after_the_screen_the_shape_bound_first_keeps_the_same_seeds(
    novel, time_scale, monkeypatch
):
    # a narrow time-scale range: the screen's time-scale test sifts, and under rotation
    # none the shape bound then goes before the speed bound (no ball: the plain search)
    bank, path = novel
    monkeypatch.setattr(IndexSearch, "ball", False)
    opts = SearchOptions(rotation="none", time_scale=time_scale)
    taken = []
    real = IndexSearch._shape_then_speed
    monkeypatch.setattr(IndexSearch, "_shape_then_speed", lambda *x: taken.append(1) or real(*x))
    for a, b in [(0.0, 0.05), (0.2, 0.24), (0.5, 0.58), (0.3, 0.5)]:
        for eps in (0.05, 0.5, 2.0):  # the larger: the first batch fills the pool
            pruned = IndexSearch(bank, opts, chunk=256, first_batch=64)
            scan = ScanSearch(bank, opts, chunk=256, first_batch=64)
            assert pruned.seeds(path, a, b, eps) == scan.seeds(path, a, b, eps)
    assert taken  # the order under test was taken
