"""Cases built to break the index search's heuristics (the admission gate 3·eps + Δ_b/2 and
the speed-profile ranking term): near-duplicate primitives differing only in speed profile,
pieces at the edges of the time-scale range, and a fast wiggle that stretches arc length."""

import numpy as np
import pytest
from _reference_search import reference_segment_path
from test_match_segment import DT, _check_segments, _compose, _library, _spline

from primlib.match import BankIndex, segment_path
from primlib.store import Bank


def _key(segs):
    return [(round(s.end, 6), s.primitive) for s in segs]


def _near_duplicates(n_copies: int = 12, n: int = 1201) -> BankIndex:
    """One random curve traversed with n_copies speed profiles t + a·sin(2πt)/π, |a| ≤ 0.04
    (monotone): the same shape, uniform-time RMSD ≈ 1.4 between neighbouring copies."""
    curve = _spline(_library(1, n, seed=3).points_of(0))
    t = np.linspace(0.0, 1.0, n)
    amps = (np.arange(n_copies) - (n_copies - 1) / 2) / ((n_copies - 1) / 2) * 0.04
    pieces = [curve(t + a * np.sin(2 * np.pi * t) / np.pi) for a in amps]
    return BankIndex(Bank.from_samples(pieces, DT, ids=np.arange(200, 200 + n_copies)))


@pytest.mark.parametrize("eps", [0.05, 0.2])
@pytest.mark.parametrize("first", [3, 7])
def test_near_duplicates_in_speed_profile_are_told_apart(first, eps):
    # every copy has the same arc-length shape, so on the window grid they tie within the
    # discretisation slack: all windows in the tie are re-scored, and all re-scored ties
    # are checked exactly, so the one copy that matches is found and no extra cut appears
    bank = _near_duplicates()
    pts, cuts = _compose(bank, [(first, 0.1, 0.5, 0.8), (first + 2, 0.5, 0.9, 1.3)], seed=5)
    segs, _ = segment_path(bank, pts, DT, eps)
    assert [s.primitive for s in segs] == [200 + first, 202 + first]
    # the longest prefix within eps may run a few samples past the join (more for larger eps)
    assert segs[0].end == pytest.approx(cuts[1], abs=10.0 / (len(pts) - 1))
    _check_segments(bank, pts, segs, eps)


def test_near_duplicates_never_cut_more_segments_than_the_time_grid():
    # the time grid keeps its best 3 seeds after suppression: here it cuts 4 segments for
    # 2 pieces (the first piece goes to neighbouring copies), the index search 2
    bank = _near_duplicates()
    pts, _ = _compose(bank, [(7, 0.1, 0.5, 0.8), (9, 0.5, 0.9, 1.3)], seed=5)
    segs, _ = segment_path(bank, pts, DT, 0.05)
    grid, _ = reference_segment_path(bank, pts, DT, 0.05, "grid")
    assert len(segs) == 2 <= len(grid)


@pytest.mark.parametrize(
    "spec",
    [
        [(0, 0.0, 0.4, 0.25), (1, 0.2, 1.0, 4.0)],
        [(2, 0.1, 0.3, 0.251), (3, 0.0, 0.99, 3.99)],
        [(4, 0.5, 0.6, 0.26), (5, 0.0, 1.0, 4.0)],
    ],
)
def test_pieces_at_the_edges_of_the_time_scale_range(spec):
    bank = _library(6, 1601, seed=4)
    pts, cuts = _compose(bank, spec, seed=7)
    segs, _ = segment_path(bank, pts, DT, 0.05)
    grid, _ = reference_segment_path(bank, pts, DT, 0.05, "grid")
    assert _key(segs) == _key(grid)
    assert [s.primitive for s in segs] == [100 + row for row, *_ in spec]
    for seg, (*_, k) in zip(segs, spec, strict=True):
        assert 0.25 * (1 - 1e-9) <= seg.time_scale <= 4.0 * (1 + 1e-9)  # round-off only
        assert seg.time_scale == pytest.approx(k, rel=0.01)
    _check_segments(bank, pts, segs, 0.05)


def _wiggled(amp: float, period: float):
    bank = _library(6, 1601, seed=4)
    pts, _ = _compose(bank, [(0, 0.1, 0.6, 1.0), (1, 0.2, 0.7, 1.0)], seed=8)
    w = 2 * np.pi * np.arange(len(pts)) / period
    wig = amp * np.stack([np.sin(w), np.cos(1.3 * w), np.sin(0.7 * w)], axis=1)
    return bank, pts + wig


@pytest.mark.parametrize(("amp", "period"), [(0.05, 4.0), (0.06, 3.0), (0.06, 2.5)])
def test_a_fast_wiggle_keeps_the_index_equal_to_the_grid(amp, period):
    # RMS 0.061-0.073 < eps = 0.1: both pieces still match. A wiggle of 3 samples lengthens
    # the raw path's arc by far more than eps (the index cut 4 segments where the grid cuts
    # 2 before it measured arc length on the smoothed path, _smooth.py)
    bank, pts = _wiggled(amp, period)
    segs, _ = segment_path(bank, pts, DT, 0.1)
    grid, _ = reference_segment_path(bank, pts, DT, 0.1, "grid")
    assert _key(segs) == _key(grid)
    assert [s.primitive for s in segs] == [100, 101]
