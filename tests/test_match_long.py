"""Long paths: no probe samples more of the path than the longest piece any primitive can
match, a (nearly) stationary piece builds no fine index, and the cuts stay those of the
short path's search (issue 13)."""

import numpy as np
import pytest
from test_match_segment import DT, _compose, _library

from primlib.match import SearchOptions, segment_path
from primlib.match._index_search import IndexSearch
from primlib.match._options import PathPiece


def test_no_probe_samples_more_than_the_longest_matchable_piece(monkeypatch):
    index = _library(3, 200, seed=5)
    # 20 pieces: 1,900 samples, ~10x what a primitive can cover at time scale 0.25 (796)
    spec = [(i % 3, 0.05, 0.95, 1.0) for i in range(11)]
    pts, cuts = _compose(index, spec, seed=6)
    asked = []
    real_at = PathPiece.at

    def at(self, v):
        asked.append(np.size(v))
        return real_at(self, v)

    monkeypatch.setattr(PathPiece, "at", at)
    segs, _ = segment_path(index, pts, DT, 0.05)
    longest = (index.counts.max() - 1) / 0.25  # path samples, at the lowest time scale
    # the index query samples the piece twice as densely as the path (arc length)
    assert max(asked) <= 2 * longest + 1 + 64
    assert len(pts) > 2 * longest
    np.testing.assert_allclose([s.end for s in segs][:-1], cuts[1:-1], atol=1.5 / len(pts))
    assert all(s.primitive is not None for s in segs)


@pytest.mark.parametrize("wiggle", [0.0, 1e-9])
def test_a_stationary_piece_builds_no_fine_index(wiggle):
    index = _library(3, 300, seed=1)
    t = np.linspace(0.0, 1.0, 400)[:, None]
    pts = np.full((400, 3), 7.0) + wiggle * np.sin(40 * t)
    search = IndexSearch(index, SearchOptions())
    assert search.arc_query(PathPiece(pts, 399 * DT), 0.0, 1.0) is None
    assert index._fine == {}  # nothing built for it (up to ~4 million points otherwise)


@pytest.mark.parametrize("j", [1, 3, 30])
def test_finest_step_bounds_every_fine_index_from_below(j):
    index = _library(2, 150, seed=3)
    assert 0 < index.finest_step() <= index.fine_arc_index(j).step0
    assert index.finest_step() <= index.arc_index().step0
