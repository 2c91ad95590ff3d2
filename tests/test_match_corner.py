"""The index's view of a noisy piece that holds the join of two shapes (``_smooth.piece_view``):
the whole path's smoothing rounds the corner; the piece is then smoothed alone."""

import numpy as np
import pytest
from _reference_search import reference_segment_path
from bench_import import benchmark_modules

from primlib.match import segment_path
from primlib.match._options import PathPiece
from primlib.match._smooth import piece_view, smooth_path


def _corner_path():
    t = np.linspace(0.0, 1.0, 401)[:, None]
    leg1 = np.hstack([t, 0 * t, 0 * t]) * 50.0
    leg2 = leg1[-1] + np.hstack([0 * t, t, 0 * t]) * 50.0
    clean = np.vstack([leg1, leg2[1:]])
    rng = np.random.default_rng(3)
    return PathPiece(clean + rng.normal(scale=0.5, size=clean.shape), 8.0)


def test_a_piece_the_smoothing_leaves_alone_is_viewed_on_the_whole_path():
    path = _corner_path()
    sm = smooth_path(path, 2.0)
    view, a, b, dev = piece_view(sm, path, 0.05, 0.4, 2.0)  # a straight leg: noise only
    assert view is sm.path and (a, b) == (0.05, 0.4)
    assert dev == sm.deviation(0.05, 0.4) <= 1.5 * sm.target


def test_a_piece_across_the_corner_is_smoothed_alone_within_its_own_bound():
    path = _corner_path()
    sm = smooth_path(path, 2.0)
    a, b = 392 / 800, 408 / 800  # samples 392-408 of 801: the corner at 400
    assert sm.deviation(a, b) > 1.5 * sm.target  # the whole path's width cut the corner
    view, a1, b1, dev = piece_view(sm, path, a, b, 2.0)
    assert view.n == 17 and (a1, b1) == pytest.approx((0.0, 1.0))
    assert view.duration == pytest.approx(path.duration * 16 / 800)
    own = smooth_path(PathPiece(path.points[392:409], view.duration), 2.0)
    np.testing.assert_array_equal(view.points, own.path.points)
    assert dev == own.deviation(0.0, 1.0) <= own.target * (1 + 1e-12)


@pytest.mark.slow
def test_a_noisy_join_of_random_primitives_is_cut_where_the_grid_cuts():
    # 1,000 random primitives, a path of three stored pieces with noise of 1 % of the
    # extent (bench_match_noisy.py): the first piece [0, 171] holds the join at 157. The
    # whole path smoothed to eps = 3.2 (the piece is wiggly) moved it by 6.8 RMS; its copy
    # in the library (primitive 386) was left out and the path cut at 71.
    with benchmark_modules("bench_match_noisy") as (bench,):
        bank = bench.library("random-1000")
        q = bench.joined_queries(bank, 1, 0.01, seed=21)[0]
    n = len(q.points) - 1
    segs, _ = segment_path(bank, q.points, bench.DT, q.eps)
    ref, _ = reference_segment_path(bank, q.points[:172], bench.DT, q.eps, "grid")
    assert [(s.end * 171, s.primitive) for s in ref] == [(171.0, 386)]
    assert round(segs[0].end * n) == 171 and segs[0].primitive == 386
    assert segs[0].rmsd == pytest.approx(ref[0].rmsd, rel=1e-6)
