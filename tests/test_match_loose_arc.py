"""On a small bank, a piece whose arc is short against eps takes the exhaustive grid's seeds
beside the index's (``primlib.match._index_search.LOOSE_ARC``): there a match within eps can
run over a stored arc a third shorter or longer than the piece's, which no arc window of the
piece's length finds (issue 13, a real hand-drawn path)."""

from __future__ import annotations

import numpy as np
import pytest
from bench_import import benchmark_modules

from primlib.match import BankIndex, SearchOptions, segment_path
from primlib.match._grid import GridSearch
from primlib.match._index_search import GRID_BANK, LOOSE_ARC, IndexSearch
from primlib.match._options import PathPiece
from primlib.match._rough import K_MAX
from primlib.match._segment import _Segmenter
from primlib.store import Bank

DT = 0.005


def _bank(samples: int, k: int = 3) -> BankIndex:
    """k smooth random planar curves of ``samples`` samples each, ~50 units wide."""
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 1.0, samples)[:, None, None]
    f = np.arange(1, 5)[None, :, None]
    curves = []
    for _ in range(k):
        amp = rng.normal(size=(1, 4, 2)) * 50 / f**1.5
        curves.append((amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 6, (1, 4, 2)))).sum(axis=1))
    return BankIndex(Bank.from_samples(curves, DT))


def _piece(bank: BankIndex, n: int) -> tuple[PathPiece, float]:
    """A stored piece of n samples (primitive 1, from sample 100) and its arc length."""
    p = bank.points_of(1)[100 : 100 + n]
    return PathPiece(p, (n - 1) * DT), float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


@pytest.mark.parametrize("n", [K_MAX + 8, 60])
def test_a_small_banks_piece_short_in_arc_against_eps_gets_the_grids_seeds_too(n):
    bank, opts = _bank(800), SearchOptions()
    path, ell = _piece(bank, n)
    eps = ell / (0.8 * LOOSE_ARC)  # the arc 0.8 LOOSE_ARC eps long: loose
    search = IndexSearch(bank, opts)
    aq = search.arc_query(path, 0.0, 1.0, eps)
    assert aq is not None and search._loose(aq, path, 0.0, 1.0, eps)  # the index could place it
    grid = GridSearch(bank, opts).seeds(path, 0.0, 1.0, eps)
    own = IndexSearch(bank, opts)._indexed(aq, path, 0.0, 1.0, eps)
    assert grid and own and search.seeds(path, 0.0, 1.0, eps) == own + grid
    tight = ell / (2.0 * LOOSE_ARC)  # twice as long against eps: the index's own seeds
    search = IndexSearch(bank, opts)
    aq = search.arc_query(path, 0.0, 1.0, tight)
    assert aq is not None and not search._loose(aq, path, 0.0, 1.0, tight)


def test_short_pieces_and_large_banks_keep_the_index():
    """Pieces of at most K_MAX samples (the unmatched noisy probes, which the grid made 4x
    slower) and banks above GRID_BANK samples (where the grid costs seconds a query) stay
    on the index, however loose their arc."""
    opts = SearchOptions()
    small = _bank(800)
    path, ell = _piece(small, K_MAX)
    search = IndexSearch(small, opts)
    eps = ell / (0.8 * LOOSE_ARC)
    aq = search.arc_query(path, 0.0, 1.0, eps)
    assert aq is not None and not search._loose(aq, path, 0.0, 1.0, eps)
    big = _bank(GRID_BANK // 2 + 1, k=2)
    assert big.points.shape[0] > GRID_BANK
    path, ell = _piece(big, 60)
    search = IndexSearch(big, opts)
    eps = ell / (0.8 * LOOSE_ARC)
    aq = search.arc_query(path, 0.0, 1.0, eps)
    assert aq is not None and not search._loose(aq, path, 0.0, 1.0, eps)


@pytest.mark.slow
def test_a_real_match_over_a_third_less_stored_arc_is_found_as_the_grid_finds_it():
    """LASA, 30 shapes stored: on bench_match_real's joined path 5 at eps 2 % of its extent,
    from sample 747 the grid matches shape 5 up to sample 1221 (0.9955 eps). Its piece to
    1205 is within 0.85 eps of shape 5's samples 0-199, whose arc is 32 % shorter than the
    piece's (21.6 against 28.5 mm, the stored shape nearly at rest while the drawing moves
    5 mm): the arc window of the piece's length ends at 247 and scores 2 eps, 442nd of 3,213.
    The index cut at 1204 (another shape) before LOOSE_ARC."""
    with benchmark_modules("bench_match_real") as (bench,):
        demos = bench.demonstrations(bench.data_dir(), 30)
        bank = bench.library(demos)
        q = bench.joined_queries(demos, 10, 0.02, seed=40)[5]
    piece = q.points[747:1206]
    arc = float(np.linalg.norm(np.diff(piece, axis=0), axis=1).sum())
    assert arc < LOOSE_ARC * q.eps  # the piece is loose: 22 eps of arc
    segs, _ = segment_path(bank, q.points, bench.DT, q.eps)
    n = q.points.shape[0] - 1
    cuts = [(round(s.start * n), round(s.end * n), s.primitive) for s in segs]
    assert (747, 1221, 5) in cuts


class _Counted(GridSearch):
    """The grid, counting the pieces it is asked for."""

    calls = 0

    def seeds(self, path, a, b, eps):
        self.calls += 1
        return super().seeds(path, a, b, eps)


def _probed(bank: BankIndex, path: PathPiece, eps: float):
    """A segmentation's whole search of the piece [0, 1] through the index, whose grid counts
    its calls: the match (or None), the segmenter and the index."""
    opts = SearchOptions()
    search = IndexSearch(bank, opts)
    search._grid = _Counted(bank, opts, search.stats)
    seg = _Segmenter(search, bank, path, eps, opts)
    found, _ = seg.probe(0.0, 1.0)
    return found, seg, search


def test_a_loose_piece_the_indexs_seeds_match_does_not_ask_the_grid():
    """The grid's seeds of a loose piece are tried only when the index's give no match: a
    stored copy matches from the index's, and the grid is never run."""
    bank = _bank(800)
    path, ell = _piece(bank, 60)
    eps = ell / (0.8 * LOOSE_ARC)
    found, _, search = _probed(bank, path, eps)
    assert found is not None and found.rmsd < eps and found.cand.prim == 1
    assert search._grid.calls == 0


def test_a_loose_piece_nothing_matches_tries_both_seed_sets():
    """A loose piece that no seed brings within eps (a stored piece bent by a full period
    of a sine 3 eps high, across its chord): the failing search has tried the index's seeds
    and the grid's (the union ``seeds`` gives), kept for the shrunk retries."""
    bank = _bank(800)
    path, ell = _piece(bank, 60)
    eps = ell / (0.5 * LOOSE_ARC)
    chord = path.points[-1] - path.points[0]
    across = np.array([-chord[1], chord[0]]) / np.linalg.norm(chord)
    bend = 3 * eps * np.sin(np.linspace(0.0, 2 * np.pi, 60))[:, None] * across
    bent = PathPiece(path.points + bend, path.duration)
    found, seg, search = _probed(bank, bent, eps)
    assert found is None and search._grid.calls == 1
    a, b, seeds, refined = seg.failed
    fresh = IndexSearch(bank, SearchOptions())
    assert (a, b) == (0.0, 1.0) and seeds == fresh.seeds(bent, 0.0, 1.0, eps)
    assert len(refined) == len(seeds)
