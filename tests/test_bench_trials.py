"""Smoke test of benchmarks/bench_trials.py: its quick run executes and its checks hold."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_bench_trials_quick_runs(capsys):
    spec = importlib.util.spec_from_file_location(
        "bench_trials", ROOT / "benchmarks" / "bench_trials.py"
    )
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    out = bench.main(["--quick"])
    text = capsys.readouterr().out
    assert "1. noise" in text and "2. moved glyph" in text and "3. one step" in text
    # the warm start of the moved glyph comes from the finished series and beats the inverse
    assert out["kind"] == "warm" and out["warm"] < out["inverse"]
