"""Each index seed moved to its best window nearby on the time-uniform grid's score
(:mod:`primlib.match._rescan`): it finds a copy the arc-length placement missed, never moves
a seed to a window that scores worse, and keeps to the primitive and the time-scale range."""

import numpy as np
import pytest

from primlib.match import BankIndex, SearchOptions, kabsch
from primlib.match._options import Candidate, PathPiece
from primlib.match._refine import prim_at
from primlib.match._rescan import SCALES, SHIFTS, rescan
from primlib.store import Bank

DT = 0.01


def _uneven(n: int = 900) -> np.ndarray:
    """A 2-D curve traced at a speed that varies threefold (a hand's, not a machine's)."""
    t = np.linspace(0.0, 1.0, n)
    s = t + 0.25 * np.sin(2 * np.pi * 3 * t) / (2 * np.pi * 3)  # arc parameter, speed 0.75-1.25
    return np.column_stack([40 * np.cos(5 * s) + 10 * s, 30 * np.sin(7 * s)])


@pytest.fixture(scope="module")
def bank():
    return BankIndex(Bank.from_samples([_uneven(), _uneven(700)[::-1] * 0.8], DT))


def _query(bank, x0: float, x1: float, n: int, angle: float = 0.7) -> PathPiece:
    """Stored piece [x0, x1] of primitive 0, n uniform-time samples, turned and moved."""
    c, s = np.cos(angle), np.sin(angle)
    pts = prim_at(bank, 0, np.linspace(x0, x1, n)) @ np.array([[c, -s], [s, c]]).T + [5.0, -3.0]
    return PathPiece(pts, (n - 1) * DT)


def _k_point_rmsd(bank, c: Candidate, path: PathPiece, k: int, rotation: str) -> float:
    """The grid's score of a window, from scratch: Kabsch on K uniform-time points."""
    p = prim_at(bank, c.prim, np.linspace(c.x0, c.x1, k))
    return kabsch(p, path.at(np.linspace(0.0, 1.0, k)), rotation=rotation).rmsd


def test_a_seed_a_few_strides_early_moves_onto_the_copy(bank):
    # the copy is [300, 600] (D = 300, stride h = D / 15 = 20); the seed starts 4 strides early
    opts = SearchOptions()
    path = _query(bank, 300.0, 600.0, 301)
    (moved,) = rescan(bank, [Candidate(0, 220.0, 520.0, 0.0)], path, 0.0, 1.0, opts)
    assert (moved.prim, moved.x0, moved.x1) == (0, pytest.approx(300.0), pytest.approx(600.0))
    assert moved.score < 1e-6 * 30  # the copy itself, to round-off of a ~30 mm curve


def test_a_seed_at_a_neighbouring_duration_moves_onto_the_copy(bank):
    # the seed is 1.1 times as long and centred 4 strides late: one scale down, 4 shifts back
    opts = SearchOptions()
    path = _query(bank, 300.0, 600.0, 301)
    (moved,) = rescan(bank, [Candidate(0, 365.0, 695.0, 0.0)], path, 0.0, 1.0, opts)
    assert moved.x0 == pytest.approx(300.0) and moved.x1 == pytest.approx(600.0)


@pytest.mark.parametrize("rotation", ["full", "none"])
def test_no_seed_moves_to_a_window_that_scores_worse_and_each_stays_in_range(bank, rotation):
    rng = np.random.default_rng(3)
    opts = SearchOptions(rotation=rotation, time_scale=(0.5, 2.0))
    path = _query(bank, 120.0, 420.0, 241, angle=0.0 if rotation == "none" else 0.7)
    steps = len(path.points) - 1  # the query's duration in stored samples (same dt)
    seeds = []
    for _ in range(40):
        prim = int(rng.integers(2))
        dur = steps * rng.uniform(0.5, 2.0)
        x0 = rng.uniform(0.0, bank.counts[prim] - 1 - dur)
        seeds.append(Candidate(prim, x0, x0 + dur, 0.0))
    moved = rescan(bank, seeds, path, 0.0, 1.0, opts)
    k = opts.grid_points
    for seed, m in zip(seeds, moved, strict=True):
        own = _k_point_rmsd(bank, seed, path, k, rotation)
        assert m.prim == seed.prim
        assert m.score == pytest.approx(_k_point_rmsd(bank, m, path, k, rotation), abs=1e-9)
        assert m.score <= own + 1e-9  # its own window is among those scored
        assert 0.0 <= m.x0 and m.x1 <= bank.counts[m.prim] - 1 + 1e-9
        assert 0.5 * steps * (1 - 1e-9) <= m.x1 - m.x0 <= 2.0 * steps * (1 + 1e-9)
        # within the reach of the module notes: SCALES durations and SHIFTS strides
        r, d = opts.scale_ratio**SCALES, seed.x1 - seed.x0
        assert d / r * (1 - 1e-9) <= m.x1 - m.x0 <= d * r * (1 + 1e-9)
        mid, half = 0.5 * (seed.x0 + seed.x1), 0.5 * (m.x1 - m.x0)
        assert abs(0.5 * (m.x0 + m.x1) - mid) <= SHIFTS * 2 * half / (k - 1) + 1e-9


def test_at_a_fixed_time_scale_only_the_start_moves(bank):
    opts = SearchOptions(time_scale=(1.0, 1.0))
    path = _query(bank, 300.0, 600.0, 301)
    (moved,) = rescan(bank, [Candidate(0, 220.0, 520.0, 0.0)], path, 0.0, 1.0, opts)
    assert moved.x1 - moved.x0 == pytest.approx(300.0)
    assert moved.x0 == pytest.approx(300.0)


def test_a_seed_at_the_edge_of_its_primitive_keeps_inside_it(bank):
    # the copy is the primitive's first 300 samples and the seed starts 2 strides late: the
    # shifts that would start before sample 0 are not taken
    opts = SearchOptions()
    path = _query(bank, 0.0, 300.0, 301)
    (moved,) = rescan(bank, [Candidate(0, 40.0, 340.0, 0.0)], path, 0.0, 1.0, opts)
    assert moved.x0 == pytest.approx(0.0) and moved.x1 == pytest.approx(300.0)
    assert rescan(bank, [], path, 0.0, 1.0, opts) == []
