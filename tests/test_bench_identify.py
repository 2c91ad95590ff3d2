"""Smoke test of benchmarks/bench_identify.py: its quick case (the XYZ stage, a 4 s record
with 1 % output noise) meets the held-out NRMSE goal and ILC designed on the identified
model converges on the true machine."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_identify.py"


@pytest.mark.slow
def test_quick_case_meets_the_goals(capsys):
    spec = importlib.util.spec_from_file_location("bench_identify", BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "held-out NRMSE <= 5 % met" in out and "converges yes" in out
