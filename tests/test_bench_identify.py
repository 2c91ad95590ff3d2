"""Smoke test of benchmarks/bench_identify.py: its quick case (the XYZ stage, a 4 s record
with 1 % output noise) meets the held-out NRMSE goal and ILC designed on the identified
model converges on the true machine."""

from __future__ import annotations

import pytest
from bench_import import benchmark_modules


@pytest.mark.slow
def test_quick_case_meets_the_goals(capsys):
    with benchmark_modules("bench_identify") as (bench,):
        assert bench.main(["--quick"]) == 0
    out = capsys.readouterr().out
    assert "held-out NRMSE <= 5 % met" in out and "converges yes" in out
