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


def test_per_path_ratios_are_baseline_over_this_tree(bench):
    assert bench._per_path([1.0, 2.0], [1.5, 1.0]) == "1.00 / 1.50 (1.50x), 2.00 / 1.00 (0.50x)"
