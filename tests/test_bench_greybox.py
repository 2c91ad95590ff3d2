"""Smoke test of benchmarks/bench_greybox.py on a small stage library (no baseline revision):
the two fits timed in a fresh process."""

from __future__ import annotations

import pytest
from bench_import import bench_output


@pytest.mark.slow  # a stage library of 3 loops learned by ILC, the models fitted (~10 s)
def test_greybox_benchmark_runs_small(monkeypatch, capsys):
    args = ["--primitives", "3", "--samples", "401", "--rounds", "1", "--no-baseline"]
    out = bench_output("bench_greybox", args, monkeypatch, capsys)
    assert "library: 3 loops of 401 samples learned on the stage" in out
    rows = {line[:44].strip(): float(line[44:].split()[0]) for line in out.splitlines()[2:]}
    assert 0 < rows["fit_greybox, linear terms and not"] < rows["machine fit (every model)"]
