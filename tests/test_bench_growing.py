"""Smoke test of benchmarks/bench_growing.py on a small library (no baseline revision): a
warm start of new paths and one after an ingest, timed, with the first-trial error."""

from __future__ import annotations

import pytest
from bench_import import bench_output


@pytest.mark.slow  # a fresh process fitting the models of 26 primitives (~5 s)
def test_growing_benchmark_runs_small(monkeypatch, capsys):
    args = ["--primitives", "26", "--paths", "1", "--ingests", "1", "--no-baseline"]
    out = bench_output("bench_growing", args, monkeypatch, capsys)
    assert "library: 26 XYZ motions" in out
    cells = [(line[:38].strip(), line[38:].split()[:1]) for line in out.splitlines()]
    rows = {label: float(v[0]) for label, v in cells if label and v and _number(v[0])}
    # 27 primitives: the models of the first 24 serve on (:func:`model_count`), so neither a
    # new path nor a new primitive fits them again: a fraction of the first warm start's time
    first = rows["first warm start (fits the models)"]
    assert rows["a new path's warm start"] < first / 3
    assert rows["a warm start after an ingest"] < first / 3
    assert 0 < rows["new paths: error past 100 samples"] < 0.01  # mm; the paths are ~100 mm


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
