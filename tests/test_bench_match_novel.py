"""Smoke test of benchmarks/bench_match_novel.py: one short novel path matched by the
worker, and the report printing it beside a baseline (here the same run)."""

from __future__ import annotations

import pytest
from bench_import import benchmark_modules


@pytest.fixture(scope="module")
def bench():
    with benchmark_modules("bench_match_novel") as (module,):
        yield module


def test_worker_matches_a_short_novel_path_and_the_report_compares_path_by_path(bench, capsys):
    spec = {"library": "bundled", "samples": 300, "paths": 1, "cases": ["time scale 1-1"]}
    out = bench.worker(spec)
    r = out["time scale 1-1"]
    assert len(r["cpu"]) == len(r["times"]) == len(r["segments"]) == 1
    assert r["segments"][0][-1][0] == pytest.approx(1.0)  # the cuts cover the path
    assert 0.0 <= r["fraction"][0] <= 1.0
    bench._report(spec, out, out)
    text = capsys.readouterr().out
    assert "(same cuts and primitives)" in text
    assert f"- time scale 1-1: {r['cpu'][0]:.2f} / {r['cpu'][0]:.2f} (1.00x)" in text


def test_a_warm_call_is_timed_after_a_first_on_the_same_index(bench, capsys):
    spec = {"library": "bundled", "samples": 300, "paths": 1, "cases": ["default"],
            "warm": True}  # fmt: skip
    warm = bench.worker(spec)["default"]
    cold = bench.worker(dict(spec, warm=False))["default"]
    assert warm["segments"] == cold["segments"]  # the same answer, the index kept
    bench._report(spec, {"default": warm}, None)
    assert "(warm call: the second on one index, seconds)" in capsys.readouterr().out


def test_per_path_ratios_are_baseline_over_this_tree(bench):
    assert bench._per_path([1.0, 2.0], [1.5, 1.0]) == "1.00 / 1.50 (1.50x), 2.00 / 1.00 (0.50x)"


def test_per_search_costs_divide_each_path_by_its_whole_searches(bench, capsys):
    """CPU per whole search is each path's CPU over its probes, and a restricted case's
    ratio is the default's cost per search over its own (> 1: the search is cheaper)."""
    spec = {"cases": ["default", "rotation none"]}
    new = {"default": {"cpu": [1.0, 0.6], "probes": [50, 30]},
           "rotation none": {"cpu": [1.2, 0.2], "probes": [100, 40]}}  # fmt: skip
    bench._per_search(spec, new)
    text = capsys.readouterr().out
    assert "- default: 50 / 20.0, 30 / 20.0" in text
    assert "- rotation none: 100 / 12.0, 40 / 5.0" in text
    assert "1.67x, 4.00x" in text


def test_per_search_is_left_out_for_a_revision_that_does_not_count_searches(bench, capsys):
    bench._per_search({"cases": ["default"]}, {"default": {"cpu": [1.0]}})
    assert capsys.readouterr().out == ""


def test_needed_divides_the_default_by_the_searches_and_places_it_among_them(bench, capsys):
    """The need is the default's CPU over the restricted case's whole searches (0.1 s over
    10 searches: 10 ms); beside it the searches' 10th percentile and median (2, 4, ..., 20
    ms: 3.8 and 11.0 by linear interpolation), the share at or under the need (5 of 10), and
    10 searches at 3.8 / 11.0 ms over the default's 0.1 s: 0.38x / 1.10x."""
    spec = {"cases": ["default", "rotation none"]}
    each = [0.002 * (i + 1) for i in range(10)]
    new = {"default": {"cpu": [0.1], "search_cpu": [[0.05, 0.05]]},
           "rotation none": {"cpu": [0.11], "search_cpu": [each]}}  # fmt: skip
    bench._needed(spec, new)
    assert "- rotation none: 10.0 ms: 3.8 / 11.0 ms, 50 %; 0.38x / 1.10x" in capsys.readouterr().out
    del new["rotation none"]["search_cpu"]  # a revision whose searches are not timed
    bench._needed(spec, new)
    assert capsys.readouterr().out == ""


def test_search_clock_times_each_whole_search_and_puts_the_method_back(bench):
    """One CPU time per whole search the segmentation counts, and the segmenter's own method
    back after the block."""
    import numpy as np

    from primlib.match import BankIndex, default_eps, segment_path
    from primlib.match._segment import _Segmenter

    bank, dt = bench._library("bundled")
    path = bench._walk(np.random.default_rng(7), 300, dt, 8)
    pts = path.at(np.linspace(0.0, 1.0, 300))
    before = _Segmenter.probe
    with bench._search_clock() as clock:
        _, info = segment_path(BankIndex(bank), pts, dt, default_eps(path))
    assert len(clock) == info["probes"] > 0
    assert all(c >= 0.0 for c in clock)
    assert _Segmenter.probe is before


def test_noisy_paths_add_seeded_noise_and_scale_eps_by_its_rms(bench):
    """The noise is white with σ the given fraction of the largest extent (sample std within
    10 %: ~4 standard errors for 3,000 draws), the same draw for a path's every case, and
    eps is the given multiple of its RMS σ√3."""
    import numpy as np

    pts = np.column_stack([np.linspace(0.0, 50.0, 1000), np.zeros(1000), np.zeros(1000)])
    a, eps_a = bench._noisy(pts, 0.001, 0, 2.0)
    b, eps_b = bench._noisy(pts, 0.001, 0, 0.5)
    assert np.array_equal(a, b)  # the same path for both tolerances
    assert np.std(a - pts) == pytest.approx(0.05, rel=0.1)
    assert eps_a == pytest.approx(2.0 * 0.05 * np.sqrt(3)) and eps_a == pytest.approx(4 * eps_b)
    assert not np.array_equal(a, bench._noisy(pts, 0.001, 1, 2.0)[0])  # another path, another draw


def test_noise_times_each_case_matched_and_unmatched_and_prints_their_ratio(bench, capsys):
    cases = [f"time scale 1-1, {at}" for at in bench.NOISE_EPS]
    spec = {"library": "bundled", "samples": 300, "paths": 1, "noise": 0.001, "cases": cases}
    out = bench.worker(spec)
    matched, unmatched = (out[c] for c in cases)
    # at twice the noise the path matches; at half of it much less does (the noise alone
    # leaves more than eps to any smooth stored piece)
    assert matched["fraction"][0] > 0.5 > unmatched["fraction"][0]
    bench._report(spec, out, None)
    ratio = unmatched["cpu"][0] / matched["cpu"][0]
    text = capsys.readouterr().out
    assert "white noise σ = 0.001 of the extent" in text
    assert f"- time scale 1-1, this tree: {ratio:.2f}x (median {ratio:.2f}x" in text


def test_long_paths_print_each_paths_time_over_the_shorter_paths_of_the_same_seed(bench, capsys):
    """``--long``: CPU at 10x the samples over CPU at the shorter length, seed by seed, for
    this tree and (when run) the baseline; the median and the worst of them."""
    spec = {"library": "random-1000", "samples": 24000, "short": 2400, "cases": ["default"]}
    long = ({"default": {"cpu": [6.0, 9.0, 2.0]}}, None)
    short = ({"default": {"cpu": [1.0, 1.0, 0.5]}}, None)
    bench._scaling(spec, long, short)
    text = capsys.readouterr().out
    assert "Length x10 (2,400 -> 24,000 samples)" in text
    assert "- default, this tree: x6.0, x9.0, x4.0 (median x6.0, worst x9.0)" in text
    assert "baseline" not in text.split("\n", 2)[2]
    bench._scaling(spec, (long[0], long[0]), (short[0], {"default": {"cpu": [2.0, 3.0, 1.0]}}))
    assert (
        "- default, baseline: x3.0, x3.0, x2.0 (median x3.0, worst x3.0)" in capsys.readouterr().out
    )


def test_long_runs_each_library_again_at_ten_times_the_samples(bench, monkeypatch, capsys):
    """``--long --big``: the bundled library's and the 1,000 primitives' paths again at 10x
    (the default case alone), each followed by its scaling lines."""
    runs = []

    def fake_worker(script, spec_json, tree):
        import json

        spec = json.loads(spec_json)
        runs.append((spec["library"], spec["samples"], tuple(spec["cases"])))
        cpu = 0.1 * spec["samples"] / 2400  # ten times longer: ten times the time
        one = {"times": [0.1], "cpu": [cpu], "segments": [[(1.0, None)]], "fraction": [0.0],
               "probes": [1]}  # fmt: skip
        return {c: one for c in spec["cases"]} | {"samples": spec["samples"]}

    monkeypatch.setattr(bench, "run_worker", fake_worker)
    monkeypatch.setattr("sys.argv", ["bench", "--long", "--big", "--paths", "1", "--no-baseline",
                                     "--cases", "default"])  # fmt: skip
    bench.main()
    one = ("default",)
    assert runs == [("bundled", 2400, one), ("random-1000", 2400, one), ("bundled", 24000, one),
                    ("random-1000", 24000, one)]  # fmt: skip
    assert capsys.readouterr().out.count("(median x10.0, worst x10.0)") == 2


def test_as_stored_paths_match_whole_in_every_restricted_case(bench):
    """``--as-stored``: 5 stored stretches, not turned, at time scale 1, joined end to start;
    every restriction holds of them, so each case matches the whole path in at most 5
    segments (a stretch may also match across a junction, never worse)."""
    cases = ["default", "rotation none", "time scale 1-1"]
    spec = {"library": "bundled", "samples": 600, "paths": 1, "cases": cases, "as_stored": True}
    out = bench.worker(spec)
    for case in cases:
        r = out[case]
        assert r["fraction"][0] == pytest.approx(1.0)
        assert 1 <= len(r["segments"][0]) <= 5
        assert all(p is not None for _, p in r["segments"][0])


def test_as_stored_paths_are_the_stored_samples_moved(bench):
    """Each piece is a stored stretch's own samples translated: every step of the path is a
    stored step, to the path fit's tolerance (positions within 1e-4 of the path's extent,
    so steps within twice that), and the path has the samples asked for."""
    import numpy as np
    from scipy.spatial import cKDTree

    bank, dt = bench._library("bundled")
    stored = cKDTree(np.diff(bank.points, axis=0))
    for seed in range(3):
        path = bench._as_stored(bank, np.random.default_rng(seed), 600, dt)
        n = int(round(path.duration / dt)) + 1
        assert n == 600
        pts = path.at(np.linspace(0.0, 1.0, n))
        steps = np.diff(pts, axis=0)
        near, _ = stored.query(steps)  # the distance to the nearest stored step
        assert np.max(near) <= 2e-4 * float(np.ptp(pts, axis=0).max())


def test_over_default_divides_each_restricted_path_by_the_default_on_it(bench, capsys):
    spec = {"cases": ["default", "rotation none"]}
    two, one = [(0.5, 1), (1.0, 2)], [(1.0, 3)]
    new = {"default": {"cpu": [1.0, 2.0], "segments": [two, one]},
           "rotation none": {"cpu": [0.5, 3.0], "segments": [one, two]}}  # fmt: skip
    bench._over_default(spec, new)
    text = capsys.readouterr().out
    assert "- rotation none: 0.50x, 1.50x (median 1.00x, worst 1.50x)" in text
    assert "segments against the default's: 1/2, 2/1" in text
    bench._over_default({"cases": ["rotation none"]}, new)  # no default: nothing to divide by
    assert capsys.readouterr().out == ""


def test_rests_hold_the_path_still_and_keep_its_motion(bench):
    import numpy as np

    pts = np.column_stack([np.arange(40.0), np.zeros(40), np.zeros(40)])
    held = bench._with_rests(pts, rests=3, length=5)
    assert held.shape == (55, 3)
    steps = np.diff(held[:, 0])
    assert np.count_nonzero(steps == 0.0) == 15  # 3 rests of 5 samples, each repeating one
    assert np.all(steps >= 0.0)  # in order
    assert np.array_equal(np.unique(held[:, 0]), pts[:, 0])  # no sample lost or made up


def test_rests_time_each_case_with_and_without_them_and_print_their_ratio(bench, capsys):
    cases = [f"default, {at}" for at in bench.RESTS]
    spec = {"library": "bundled", "samples": 300, "paths": 1, "rests": True, "cases": cases}
    out = bench.worker(spec)
    still, moving = (out[c] for c in cases)
    for r in (still, moving):
        assert r["segments"][0][-1][0] == pytest.approx(1.0)
    bench._report(spec, out, None)
    ratio = still["cpu"][0] / moving["cpu"][0]
    text = capsys.readouterr().out
    assert "and with 3 rests of 200 samples" in text
    assert f"- default, this tree: {ratio:.2f}x (median {ratio:.2f}x" in text
