"""Smoke test of benchmarks/bench_trials.py: its quick run executes and its checks hold."""

from __future__ import annotations

import pytest
from bench_import import benchmark_modules


@pytest.mark.slow
def test_bench_trials_quick_runs(capsys):
    with benchmark_modules("bench_trials") as (bench,):
        out = bench.main(["--quick"])
    text = capsys.readouterr().out
    assert "1. noise" in text and "2. moved glyph" in text and "3. one step" in text
    # the warm start of the moved glyph comes from the finished series and beats the inverse
    assert out["kind"] == "warm" and out["warm"] < out["inverse"]
