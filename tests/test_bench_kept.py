"""Smoke test of benchmarks/bench_kept.py on a tiny stage library: it runs ``primlib match
--out`` with the models fitted and then kept, and asserts that both wrote the same warm
start (the script's own assertion)."""

from __future__ import annotations

import sys

import pytest
from bench_import import benchmark_modules


@pytest.mark.slow  # two fresh processes, one fitting ~1 s of models
def test_kept_benchmark_runs_small(monkeypatch, capsys):
    with benchmark_modules("bench_kept") as (bench,):
        argv = ["bench_kept.py", "--rounds", "1", "--primitives", "2", "--samples", "301"]
        monkeypatch.setattr(sys, "argv", argv)
        bench.main()
    out = capsys.readouterr().out
    assert "models fitted (the baseline): median" in out
    assert "the same warm start, byte for byte" in out
