"""Smoke test of benchmarks/bench_store.py on a tiny library: its baselines still insert into
today's table (they broke silently when the table gained columns), every fast path returns
what its baseline returns (the script asserts it), and the fresh bank read reports its page
faults beside the read on the open connection."""

from __future__ import annotations

import sys

import pytest
from bench_import import benchmark_modules


@pytest.mark.slow  # ~3 s alone, ~11 s under this machine's load
def test_store_benchmark_runs_small(monkeypatch, capsys):
    with benchmark_modules("bench_store") as (bench,):
        argv = ["bench_store.py", "--k", "12", "--n", "300", "--repeat", "1", "--subset", "4"]
        monkeypatch.setattr(sys, "argv", argv)
        bench.main()
    out = capsys.readouterr().out
    assert "bank for matching (points), fresh open" in out
    line = next(s for s in out.splitlines() if s.startswith("bank read, fresh open"))
    # 12 x 300 x 3 doubles: the points alone are first touched at least once
    faults = int(line.split(": ")[1].split(" minor")[0].replace(",", ""))
    assert faults > 0 and "again on the open connection" in line
