"""The smoothed query of the arc-length index (primlib/match/_smooth.py): the noise estimate,
the bound on the deviation from the samples, and what it buys (arc lengths of a noisy query
and its clean copy agree; the index finds the copy)."""

import math
import time

import numpy as np
import pytest
from _reference_search import reference_segment_path
from hypothesis import given, settings
from hypothesis import strategies as st
from test_match_segment import DT, _library

from primlib.match import BankIndex, segment_path
from primlib.match._index_search import IndexSearch
from primlib.match._options import PathPiece, SearchOptions
from primlib.match._smooth import gaussian_smooth, noise_sigma, smooth_bank, smooth_path, wiggly
from primlib.store import Bank


def _curve(n: int, d: int, seed: int = 0) -> np.ndarray:
    """A smooth curve ~50 units wide, n samples (a few harmonics)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)[:, None, None]
    f = np.arange(1, 4)[None, :, None]
    amp = rng.normal(size=(1, 3, d)) * 20.0 / f
    return (amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 6, (1, 3, d)))).sum(axis=1)


def _arc(x: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(x, axis=0), axis=1).sum())


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return math.sqrt(float(np.mean(np.sum((a - b) ** 2, axis=1))))


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("sigma", [0.01, 0.1, 1.0])
def test_noise_estimate_recovers_white_noise(d, sigma):
    # MAD of 3,000 third differences: its relative standard error is ~1.1/sqrt(3000 d),
    # under 3 %; the clean curve's own third differences are ~1e-6 here
    rng = np.random.default_rng(1)
    clean = _curve(3000, d)
    est = noise_sigma(clean + rng.normal(scale=sigma, size=clean.shape))
    assert est == pytest.approx(sigma, rel=0.1)
    assert noise_sigma(clean) < 1e-4


@pytest.mark.parametrize("width", [0.7, 3.0, 40.0])
def test_a_straight_line_at_constant_speed_is_left_as_it_is(width):
    # the point reflection at each end continues the line; a symmetric kernel keeps it
    line = np.linspace(0.0, 1.0, 200)[:, None] * np.array([[3.0, -1.0, 2.0]]) + 5.0
    np.testing.assert_allclose(gaussian_smooth(line, width), line, atol=1e-12)


def test_a_clean_path_is_not_smoothed():
    pp = PathPiece(_curve(800, 3), 4.0)
    sm = smooth_path(pp, eps=0.05)
    assert sm.width == 0.0 and sm.path is pp and sm.deviation(0.1, 0.7) == 0.0


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**16),
    level=st.sampled_from([0.003, 0.03, 0.3]),
    eps_ratio=st.floats(0.2, 5.0),
    a=st.floats(0.0, 0.9),
    length=st.floats(0.02, 1.0),
)
def test_deviation_is_bounded_by_the_target_and_eps(seed, level, eps_ratio, a, length):
    # the whole path's RMS deviation is at most the target min(1.1 sigma_hat sqrt(d), eps);
    # each piece's deviation is the RMS over its own samples, as computed directly
    rng = np.random.default_rng(seed)
    clean = _curve(int(rng.integers(40, 1500)), 3, seed)
    q = clean + rng.normal(scale=level, size=clean.shape)
    eps = eps_ratio * level * math.sqrt(3)
    sm = smooth_path(PathPiece(q, 1.0), eps)
    s = sm.path.points
    assert _rms(s, q) <= sm.target * (1 + 1e-12) + 1e-15
    assert sm.target <= eps
    b = min(a + length, 1.0)
    n = len(q) - 1
    i0, i1 = math.floor(a * n + 1e-9), math.ceil(b * n - 1e-9)
    assert sm.deviation(a, b) == pytest.approx(_rms(s[i0 : i1 + 1], q[i0 : i1 + 1]), abs=1e-12)


@pytest.mark.parametrize("level", [0.001, 0.01])
@pytest.mark.parametrize("n", [300, 1200])
def test_smoothed_arc_length_agrees_with_the_clean_copy(level, n):
    # white noise of sigma = level x extent inflates the raw arc length by 3-400 %; at
    # eps = 2 x noise RMS the smoothed path's arc length is within 3 % of the clean one's,
    # and at least 3 times closer than the raw one's
    rng = np.random.default_rng(2)
    clean = _curve(n, 3, seed=5)
    sigma = level * float(np.ptp(clean, axis=0).max())
    q = clean + rng.normal(scale=sigma, size=clean.shape)
    sm = smooth_path(PathPiece(q, 1.0), 2.0 * sigma * math.sqrt(3))
    raw, smooth = _arc(q) - _arc(clean), abs(_arc(sm.path.points) - _arc(clean))
    assert raw > 0.02 * _arc(clean)
    assert smooth < min(0.03 * _arc(clean), raw / 3)
    assert _rms(sm.path.points, clean) < _rms(q, clean)


@pytest.mark.parametrize("level", [0.001, 0.01])
def test_the_index_finds_a_noisy_time_scaled_copy(level):
    # a piece of primitive 2, time-scaled x1.6 (the query is slower), noise of level x
    # extent: the stored piece is within eps of the query, so within eps + smoothing of the
    # smoothed piece the index searches: it must be among the seeds, at the right time scale
    bank = _library(6, 1201, seed=4)
    rng = np.random.default_rng(3)
    src = bank.points_of(2)
    n_out = int(round(0.6 * 1200 * 1.6)) + 1
    x = np.linspace(0.2 * 1200, 0.8 * 1200, n_out)
    clean = np.stack([np.interp(x, np.arange(1201), src[:, j]) for j in range(3)], axis=1)
    sigma = level * float(np.ptp(clean, axis=0).max())
    q = clean + rng.normal(scale=sigma, size=clean.shape)
    eps = 2.0 * sigma * math.sqrt(3)
    search = IndexSearch(bank, SearchOptions())
    pp = PathPiece(q, (n_out - 1) * DT)
    aq = search.arc_query(pp, 0.0, 1.0, eps)
    assert 0.0 < aq.smoothing <= eps
    seeds = search.seeds(pp, 0.0, 1.0, eps)
    hits = [c for c in seeds if c.prim == 2]
    assert hits
    # a seed only has to start the refinement in the right basin: 2 % of the primitive
    assert hits[0].x0 == pytest.approx(240.0, abs=24.0)
    assert (hits[0].x1 - hits[0].x0) / (n_out - 1) == pytest.approx(1 / 1.6, rel=0.05)
    segs, _ = segment_path(bank, q, DT, eps)
    assert [s.primitive for s in segs] == [102]
    assert segs[0].time_scale == pytest.approx(1 / 1.6, rel=0.01)


def test_a_clean_bank_is_not_smoothed():
    bank = _library(5, 801, seed=1)
    pts, dev = smooth_bank(bank.points, bank.offsets)
    assert pts is bank.points and not np.any(dev)
    assert not bank.arc_index().smoothed
    assert bank.arc_index().window_deviation(0, 10, 5) is None


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**16), levels=st.lists(st.sampled_from([0.0, 1e-3, 1e-2, 0.1]),
       min_size=1, max_size=5))  # fmt: skip
def test_the_screen_keeps_every_primitive_smooth_path_smooths(seed, levels):
    # each primitive comes out exactly as smooth_path with no eps would make it: the screen
    # only skips primitives it proves it would leave as they are
    rng = np.random.default_rng(seed)
    pieces = []
    for i, level in enumerate(levels):
        c = _curve(int(rng.integers(20, 1500)), 3, seed + i)
        pieces.append(c + rng.normal(scale=level * 40.0, size=c.shape))
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in pieces])])
    pts, dev = smooth_bank(np.concatenate(pieces), offsets)
    for i, p in enumerate(pieces):
        sm = smooth_path(PathPiece(p, 1.0), math.inf)
        np.testing.assert_array_equal(pts[offsets[i] : offsets[i + 1]], sm.path.points)
        want = np.linalg.norm(sm.path.points - p, axis=1)
        np.testing.assert_allclose(dev[offsets[i] : offsets[i + 1]], want, atol=1e-12)


@pytest.mark.parametrize("level", [0.001, 0.01])
def test_a_clean_query_matches_its_noisy_stored_copy(level):
    # primitive 2 stored with noise: the index measures its arc on the smoothed samples and
    # widens each window's gate by its deviation, so the clean piece finds it as the grid does
    clean = _library(6, 1201, seed=4)
    rng = np.random.default_rng(6)
    pieces = [clean.points_of(i) for i in range(6)]
    sigma = level * float(np.ptp(pieces[2], axis=0).max())
    pieces[2] = pieces[2] + rng.normal(scale=sigma, size=pieces[2].shape)
    bank = BankIndex(Bank.from_samples(pieces, DT, ids=np.arange(100, 106)))
    assert bank.arc_index().smoothed
    q = clean.points_of(2)[300:1000:2]  # time scale 2
    eps = 2.0 * sigma * math.sqrt(3)
    segs, _ = segment_path(bank, q, DT, eps)
    grid, _ = reference_segment_path(bank, q, DT, eps, "grid")
    assert [s.primitive for s in segs] == [s.primitive for s in grid] == [102]
    # any time scale within eps is a match: at 1 % noise eps is 3.5 % of the extent
    assert segs[0].time_scale == pytest.approx(2.0, rel=0.05)


@pytest.mark.parametrize("width", [10.0, 16.0, 40.0, 300.0])
def test_wide_kernels_through_the_fft_equal_the_direct_sum(width):
    # above 129 taps the filter runs through the FFT; the sum it computes is the same
    rng = np.random.default_rng(4)
    q = _curve(1000, 3) + rng.normal(scale=0.3, size=(1000, 3))
    half = min(math.ceil(4 * width), 999)
    x = np.arange(-half, half + 1)
    kern = np.exp(-0.5 * (x / width) ** 2)
    kern /= kern.sum()
    ext = np.concatenate([2 * q[0] - q[half:0:-1], q, 2 * q[-1] - q[-2 : -half - 2 : -1]])
    direct = np.stack([np.convolve(ext[:, j], kern, mode="valid") for j in range(3)], axis=1)
    np.testing.assert_allclose(gaussian_smooth(q, width), direct, rtol=0, atol=1e-11)


def test_a_long_noisy_line_is_smoothed_in_bounded_time():
    # the residual on a straight line never reaches the noise target: the width runs to
    # n/4; through the FFT that costs O(n log n) per try (direct: 100,000 x 200,000 taps)
    rng = np.random.default_rng(5)
    n = 100_000
    line = np.linspace(0.0, 1.0, n)[:, None] * np.array([[100.0, 50.0, -20.0]])
    q = line + rng.normal(scale=0.05, size=line.shape)
    t0 = time.perf_counter()
    sm = smooth_path(PathPiece(q, 500.0), eps=0.2)
    assert time.perf_counter() - t0 < 20.0
    assert sm.width == pytest.approx((n - 1) / 4.0)
    # closer to the line than the samples (0.087 RMS); the ends pivot on noisy end samples
    assert _rms(sm.path.points, line) < 0.5 * _rms(q, line)


@pytest.mark.parametrize("periods", [60, 100])
def test_a_smooth_wiggle_is_wiggly_and_a_smooth_curve_is_not(periods):
    # chords of 16 samples across a wiggle of 8-13 samples miss most of its arc; a smooth
    # curve (3 harmonics on 800 samples) turns by < 0.2 rad over a chord: < 0.2 % shorter
    clean = _curve(800, 3)
    t = np.linspace(0.0, 1.0, 800)[:, None]
    wig = np.hstack([np.sin(2 * np.pi * periods * t), np.cos(2 * np.pi * periods * t), 0 * t])
    assert not wiggly(clean, 0.0, 1.0) and not wiggly(clean, 0.2, 0.5)
    assert wiggly(clean + 0.4 * wig, 0.0, 1.0) and wiggly(clean + 0.4 * wig, 0.2, 0.5)
    assert not wiggly(clean + 0.4 * wig, 0.2, 0.25)  # too short for 4 chords: not judged


def test_a_wiggly_copy_of_a_stored_piece_is_one_segment_as_from_the_grid():
    # a stored piece bent by a smooth wiggle of RMS 0.5 eps, 80 periods: the raw arc is
    # 1.2x the stored one's; the index measures it on the path smoothed within eps
    bank = _library(6, 1201, seed=4)
    q = bank.points_of(3)[100:1100].copy()
    t = np.linspace(0.0, 1.0, len(q))[:, None]
    wig = np.hstack([np.sin(160 * np.pi * t), np.cos(160 * np.pi * t), 0 * t])
    eps = 0.02 * float(np.ptp(q, axis=0).max())
    q += 0.5 * eps * wig
    assert _arc(q) > 1.2 * _arc(bank.points_of(3)[100:1100])
    segs, _ = segment_path(bank, q, DT, eps)
    grid, _ = reference_segment_path(bank, q, DT, eps, "grid")
    assert [s.primitive for s in segs] == [s.primitive for s in grid] == [103]
