"""Search and segmentation on synthetic libraries (arrays only, no store)."""

import math
import time

import numpy as np
import pytest
from _reference_search import ScanSearch, reference_segment_path
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from primlib import InputError, NoMatchError
from primlib.match import BankIndex, SearchOptions, segment_path
from primlib.match._index_search import IndexSearch
from primlib.match._interp import cubic_at
from primlib.match._options import PathPiece
from primlib.store import Bank

DT = 0.01


def _library(k: int, n: int, d: int = 3, seed: int = 0) -> BankIndex:
    """k smooth random curves (sums of 6 harmonics), n samples each, ~50 units wide."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)[:, None, None]
    f = np.arange(1, 7)[None, :, None]
    pieces = []
    for _ in range(k):
        amp = rng.normal(size=(1, 6, d)) * 50 / f**1.5
        ph = rng.uniform(0, 2 * np.pi, size=(1, 6, d))
        pieces.append((amp * np.sin(2 * np.pi * f * t + ph)).sum(axis=1))
    return BankIndex(Bank.from_samples(pieces, DT, ids=np.arange(100, 100 + k)))


def _rotation(d: int, rng, mode: str = "full") -> np.ndarray:
    if d == 2 or mode == "z":
        th = rng.uniform(-np.pi, np.pi)
        r2 = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        if d == 2:
            return r2
        r = np.eye(3)
        r[:2, :2] = r2
        return r
    return Rotation.random(random_state=int(rng.integers(2**31))).as_matrix()


def _spline(points: np.ndarray) -> CubicSpline:
    """An interpolant independent of the matcher's (not-a-knot cubic spline)."""
    return CubicSpline(np.linspace(0, 1, len(points)), points, axis=0)


def _compose(bank: BankIndex, spec, seed: int = 1, mode: str = "full"):
    """Path from pieces (primitive row, v0, v1, time scale k): rotated, joined end to start."""
    rng = np.random.default_rng(seed)
    d = bank.dim
    out, last, cuts = [], np.zeros(d), [0]
    for i, v0, v1, k in spec:
        n_p = bank.counts[i]
        n_out = int(round((v1 - v0) * (n_p - 1) / k)) + 1
        piece = _spline(bank.points_of(i))(np.linspace(v0, v1, n_out))
        piece = piece @ _rotation(d, rng, mode).T
        piece += last - piece[0]
        last = piece[-1]
        out.append(piece if not out else piece[1:])
        cuts.append(cuts[-1] + n_out - 1)
    pts = np.concatenate(out)
    return pts, np.array(cuts) / (len(pts) - 1)


def _check_segments(bank, pts, segs, eps, mode="full"):
    """Each declared transform reproduces its segment within eps, checked independently."""
    assert segs[0].start == 0.0 and segs[-1].end == 1.0
    for s0, s1 in zip(segs[:-1], segs[1:], strict=True):
        assert s0.end == s1.start
    n = len(pts) - 1
    for seg in segs:
        if seg.primitive is None:
            continue
        row = int(np.flatnonzero(bank.ids == seg.primitive)[0])
        # the segment's own path samples (cuts lie on samples) against the primitive at the
        # corresponding uniform times, through a spline of its samples
        i0, i1 = round(seg.start * n), round(seg.end * n)
        assert seg.start * n == pytest.approx(i0) and seg.end * n == pytest.approx(i1)
        a = pts[i0 : i1 + 1]
        s = np.linspace(seg.primitive_start, seg.primitive_end, len(a))
        b = _spline(bank.points_of(row))(s)
        dev = np.sqrt(np.mean(np.sum((a - (b @ seg.rotation.T + seg.translation)) ** 2, 1)))
        # tolerance: eps plus the RMS gap between the spline and the matcher's cubic
        # interpolant of the same samples (the only thing the two evaluations do differently)
        x = s * (bank.counts[row] - 1)
        gap = b - cubic_at(bank.points, bank.offsets[row], bank.counts[row], x)
        assert dev <= eps + np.sqrt(np.mean(np.sum(gap**2, 1))) + 1e-12
        assert seg.rmsd < eps
        np.testing.assert_allclose(np.linalg.det(seg.rotation), 1.0, atol=1e-9)
        if mode == "z":
            np.testing.assert_allclose(seg.rotation[2], [0, 0, 1], atol=1e-12)
        dur_p = (seg.primitive_end - seg.primitive_start) * (bank.counts[row] - 1) * bank.dt
        dur_s = (seg.end - seg.start) * (len(pts) - 1) * DT
        assert seg.time_scale == pytest.approx(dur_p / dur_s)
        assert 0.25 - 1e-9 <= seg.time_scale <= 4.0 + 1e-9


@pytest.mark.parametrize(("d", "mode"), [(3, "full"), (2, "full"), (3, "z")])
def test_pieces_come_back_as_at_most_pieces_plus_one(d, mode):
    bank = _library(12, 300, d=d, seed=d)
    spec = [(3, 0.1, 0.45, 1.6), (7, 0.3, 0.7, 0.7), (11, 0.0, 0.3, 1.0), (0, 0.5, 0.9, 2.5)]
    pts, cuts = _compose(bank, spec, seed=5, mode=mode)
    eps = 0.05
    segs, info = segment_path(bank, pts, DT, eps, rotation=mode)
    assert len(segs) <= len(spec) + 1
    assert all(s.primitive is not None for s in segs)
    _check_segments(bank, pts, segs, eps, mode)
    # the pieces are exact copies joined at corners: the cuts land on the joins
    np.testing.assert_allclose([s.end for s in segs], cuts[1:], atol=1.5 / (len(pts) - 1))
    assert [int(np.flatnonzero(bank.ids == s.primitive)[0]) for s in segs] == [i for i, *_ in spec]
    assert info["probes"] > 0 and info["scored"] <= info["windows"]


def test_same_segmentation_as_exhaustive_grid_and_per_candidate_loop():
    bank = _library(3, 120, seed=11)
    spec = [(1, 0.1, 0.6, 1.3), (2, 0.2, 0.7, 0.8)]
    pts, _ = _compose(bank, spec, seed=2)
    eps = 0.05
    opts = SearchOptions(seeds=2)
    out = {
        s: reference_segment_path(bank, pts, DT, eps, s, options=opts, time_scale=(0.5, 2.0))[0]
        for s in ("scan", "grid", "loop")
    }
    out["index"] = segment_path(bank, pts, DT, eps, options=opts, time_scale=(0.5, 2.0))[0]
    key = {s: [(g.end, g.primitive) for g in segs] for s, segs in out.items()}
    assert key["index"] == key["scan"] == key["grid"] == key["loop"]
    for a, b in zip(out["grid"], out["loop"], strict=True):
        assert a.rmsd == pytest.approx(b.rmsd, abs=1e-9)


def test_a_stretch_nothing_matches_is_reported_not_dropped():
    bank = _library(6, 300, seed=3)
    pts, cuts = _compose(bank, [(2, 0.1, 0.5, 1.0)], seed=4)
    rng = np.random.default_rng(9)
    # a zig-zag no smooth primitive reproduces, then a second stored piece
    zig = pts[-1] + np.cumsum(rng.choice([-3.0, 3.0], size=(60, 3)), axis=0)
    tail, _ = _compose(bank, [(4, 0.2, 0.6, 1.0)], seed=6)
    tail += zig[-1] - tail[0]
    full = np.concatenate([pts, zig, tail[1:]])
    eps = 0.05
    segs, _ = segment_path(bank, full, DT, eps)
    kinds = [s.primitive is None for s in segs]
    assert any(kinds)
    assert not kinds[0] and not kinds[-1]
    unmatched = [s for s in segs if s.primitive is None]
    assert len(unmatched) == 1  # neighbouring unmatched stretches merge
    n = len(full) - 1
    # the zig-zag (samples len(pts)-1 .. len(pts)+60) lies inside the unmatched stretch
    assert unmatched[0].start <= (len(pts) + 1) / n and unmatched[0].end >= (len(pts) + 59) / n
    assert np.isnan(unmatched[0].rmsd) and unmatched[0].time_scale != unmatched[0].time_scale
    _check_segments(bank, full, segs, eps)


def test_before_the_first_match_a_failed_start_is_followed_by_the_shortest_probe(
    monkeypatch,
):
    from primlib.match import _segment

    bank = _library(6, 300, seed=3)
    rng = np.random.default_rng(9)
    zig = np.cumsum(rng.choice([-3.0, 3.0], size=(80, 3)), axis=0)
    tail, _ = _compose(bank, [(4, 0.2, 0.6, 1.0)], seed=6)
    full = np.concatenate([zig, tail[1:] + zig[-1] - tail[0]])
    starts: list[tuple[int, int, bool]] = []  # (start, first probe's samples, matched)
    first_probe: dict[int, int] = {}
    probe, longest = _segment._Segmenter.probe, _segment._Segmenter.longest_prefix

    def logged_probe(self, a, b):
        ia = round(a * (self.path.n - 1))
        first_probe.setdefault(ia, round((b - a) * (self.path.n - 1)) + 1)
        return probe(self, a, b)

    def logged_longest(self, ia, sig, guess):
        out = longest(self, ia, sig, guess)
        starts.append((ia, first_probe.get(ia, 0), out is not None))
        return out

    monkeypatch.setattr(_segment._Segmenter, "probe", logged_probe)
    monkeypatch.setattr(_segment._Segmenter, "longest_prefix", logged_longest)
    segs, _ = segment_path(bank, full, DT, 0.05)
    assert segs[0].primitive is None and segs[-1].primitive is not None
    after_failure = [s for prev, s in zip(starts, starts[1:], strict=False) if not prev[2]]
    assert len(after_failure) >= 3  # the zig-zag takes several starts to cross
    # the first start probes the whole path; after a failed start (no match yet), the
    # shortest piece: the whole remainder and its halves would fail again
    assert starts[0][1] == len(full)
    assert all(samples == _segment._MIN_SAMPLES for _, samples, _ in after_failure)


def test_the_best_primitive_is_chosen_among_the_failed_search_s_seeds_without_a_new_search():
    from primlib.match._options import Candidate, SearchStats
    from primlib.match._segment import _Segmenter

    class Recorder:
        stats = SearchStats()
        calls: list[tuple[float, float]] = []

        def seeds(self, path, a, b, eps):
            self.calls.append((a, b))
            return []

    bank = _library(2, 120, seed=1)
    n = 50
    path = PathPiece(bank.points_of(0)[:n], (n - 1) * DT)
    seg = _Segmenter(Recorder(), bank, path, 0.05, SearchOptions())
    seg.sig = 1
    ia = 5  # 5 * (1 / 49) != 5 / 49: every end is seg._t's, so a start compares exactly
    seeds = [Candidate(1, 10.0, 40.0, 0.0)]
    seg.failed = (seg._t(ia), seg._t(31), seeds, seeds)
    near = seg._seeds_near(seg._t(ia), seg._t(30))  # one sample shorter, as segment() asks
    assert Recorder.calls == []
    assert near[0].x1 - near[0].x0 == pytest.approx(30.0 * 25 / 26)
    seg._seeds_near(seg._t(ia), seg._t(28))  # two samples shorter than the failed search: new
    assert len(Recorder.calls) == 1


def test_time_scale_outside_range_is_not_matched():
    bank = _library(3, 300, seed=4)
    pts, _ = _compose(bank, [(1, 0.1, 0.2, 1.0)], seed=1)
    segs, _ = segment_path(bank, pts, DT, 0.01)
    # 0.1 of 299 sample steps stored, played over round(29.9) = 30 steps
    assert len(segs) == 1 and segs[0].time_scale == pytest.approx(29.9 / 30, rel=3e-3)
    # the same piece played 6 times slower than stored: out of 0.25-4 unless allowed
    slow = _spline(pts)(np.linspace(0, 1, 6 * (len(pts) - 1) + 1))
    segs_slow, _ = segment_path(bank, slow, DT, 0.01, time_scale=(1 / 8, 8))
    assert len(segs_slow) == 1
    assert segs_slow[0].time_scale == pytest.approx(29.9 / 30 / 6, rel=3e-3)
    segs_ranged, _ = segment_path(bank, slow, DT, 0.01)
    assert len(segs_ranged) > 1
    assert all(s.time_scale >= 0.25 - 1e-9 for s in segs_ranged if s.primitive is not None)
    _check_segments(bank, slow, segs_ranged, 0.01)


def test_arc_index_pruning_keeps_the_exact_top_seeds():
    bank = _library(8, 300, seed=8)
    pts, _ = _compose(bank, [(5, 0.2, 0.5, 1.2)], seed=3)
    path = PathPiece(pts, (len(pts) - 1) * DT)
    opts = SearchOptions(seeds=3)
    pruned = IndexSearch(bank, opts)
    seeds = pruned.seeds(path, 0.0, 1.0, eps=0.05)
    # without the bounds every window is scored: the same seeds
    full = ScanSearch(bank, opts)
    full_seeds = full.seeds(path, 0.0, 1.0, eps=0.05)
    assert pruned.stats.scored < full.stats.scored  # (all but those out of time scale)
    assert seeds[0].prim == 5
    assert seeds == full_seeds


def test_bad_input():
    bank = _library(2, 100)
    pts = bank.points_of(0)[:50]
    with pytest.raises(InputError, match="eps: expected a tolerance > 0, got 0"):
        segment_path(bank, pts, DT, 0.0)
    with pytest.raises(InputError, match="eps: expected a tolerance > 0, got -1"):
        segment_path(bank, pts, DT, -1)
    with pytest.raises(InputError, match="expected 3-D points .* got 2-D"):
        segment_path(bank, pts[:, :2], DT, 0.1)
    with pytest.raises(InputError, match="rotation: expected one of full, z, none"):
        segment_path(bank, pts, DT, 0.1, rotation="xy")
    for low, high in ((2.0, 1.0), (0.0, 1.0), (1.0, math.inf), (math.nan, 1.0)):
        with pytest.raises(InputError, match=r"time_scale: expected finite bounds 0 < low <= high"):
            segment_path(bank, pts, DT, 0.1, time_scale=(low, high))
    with pytest.raises(InputError, match="finite samples"):
        segment_path(bank, np.full((10, 3), np.nan), DT, 0.1)
    empty = Bank.from_samples([], DT)
    with pytest.raises(NoMatchError, match="no primitive stored"):
        segment_path(empty, pts, DT, 0.1)


def test_a_constant_path_is_refused_at_once():
    # issue 12: a zero-extent path got eps 3.5e-18 and took 14 s and 500 MB
    bank = _library(2, 100)
    t0 = time.perf_counter()
    with pytest.raises(InputError, match=r"path: the path does not move \(largest distance"):
        segment_path(bank, np.full((5000, 3), 2.0), DT, 3.5e-18)
    assert time.perf_counter() - t0 < 1.0  # no search ran (generous: a check of 5,000 rows)
    with pytest.raises(InputError, match=r"path: expected coordinates within ±1e\+09"):
        segment_path(bank, bank.points_of(0) * 1e300, DT, 0.1)


@pytest.mark.parametrize("noise_first", [True, False])
def test_the_lowest_rmsd_primitive_matching_the_prefix_wins(noise_first):
    """Two stored copies of the path, one exact and one with noise of 0.6 eps: both match
    the whole path; the exact one is reported, whichever the search meets first."""
    from primlib.store import Bank

    rng = np.random.default_rng(11)
    t = np.linspace(0, 1, 300)[:, None]
    exact = np.hstack([40 * np.cos(3 * t), 30 * np.sin(5 * t), 10 * t])
    eps = 0.05
    noisy = exact + rng.normal(size=exact.shape) * 0.6 * eps / np.sqrt(3)
    pieces = [noisy, exact] if noise_first else [exact, noisy]
    bank = Bank.from_samples(pieces, dt=0.01)
    rot = Rotation.from_euler("xyz", [0.3, -0.2, 0.5]).as_matrix()
    segs, _ = segment_path(bank, exact @ rot.T + 7.0, 0.01, eps)
    assert len(segs) == 1
    assert segs[0].primitive == (1 if noise_first else 0)
    assert segs[0].rmsd < 1e-3 * eps


def test_a_match_found_on_a_worse_primitive_is_replaced_by_the_best():
    """The segment takes the lowest-RMSD primitive of its prefix, not the probe's first hit."""
    from primlib.match._options import Candidate, PathPiece
    from primlib.match._segment import _Found, _Segmenter, resolve_options
    from primlib.store import Bank

    rng = np.random.default_rng(12)
    t = np.linspace(0, 1, 300)[:, None]
    exact = np.hstack([40 * np.cos(3 * t), 30 * np.sin(5 * t), 10 * t])
    eps = 0.05
    noisy = exact + rng.normal(size=exact.shape) * 0.6 * eps / np.sqrt(3)
    index = BankIndex(Bank.from_samples([noisy, exact], dt=0.01))
    opts = resolve_options("full", None, None)
    seg = _Segmenter(IndexSearch(index, opts), index, PathPiece(exact, 2.99), eps, opts)
    first_hit = _Found(Candidate(0, 0.0, 299.0, 0.0), 0.6 * eps)
    out = seg.segment(0.0, 1.0, first_hit)
    assert out.primitive == 1 and out.rmsd < 1e-3 * eps


def test_splits_follow_a_power_law_through_the_bracket():
    """The split where r = c·L^p through both ends reaches eps, strictly inside the bracket;
    through the failure alone (p = 2) when the match's RMSD is unknown; the midpoint when
    the failure's is."""
    from primlib.match._segment import _gallop, _split

    r = lambda n: 1e-4 * n**2  # noqa: E731 - reaches eps = 1 at 100 samples
    assert _split(50, 200, r(50), r(200), 1.0) == 100
    assert _split(50, 200, r(50), r(200) ** 1.5, 1.0) < 100  # a steeper law: sooner
    assert _split(50, 200, float("nan"), r(200), 1.0) == 100
    assert _split(50, 200, r(50), float("inf"), 1.0) == 125
    assert _split(99, 101, 0.1, 50.0, 1.0) == 100  # never on an end
    assert _split(99, 101, 0.999, 1.001, 1.0) == 100
    # the gallop: to where r ~ L^2 reaches eps, +10 %, between 1/8 and 2x longer
    assert _gallop(100, r(50), 1.0) == 200
    assert _gallop(100, 0.64, 1.0) == 138  # 100 * 1.1 / 0.8 = 137.5
    assert _gallop(100, 0.999, 1.0) == 113
