"""Smoke test of benchmarks/bench_seed_search.py: the index searches of one short novel path
against the bundled library, recorded and answered again by the worker; a moved seed end is
told apart."""

from __future__ import annotations

import json
import pickle

import pytest
from bench_import import benchmark_modules


@pytest.fixture(scope="module")
def bench():
    # benchmarks/ stays on the path while the test runs: the benchmark imports
    # bench_match_novel as the script does
    with benchmark_modules("bench_seed_search") as (module,):
        yield module


@pytest.mark.slow
def test_recorded_queries_are_answered_again(bench, tmp_path):
    asked = bench.record("bundled", 1, samples=600)
    assert asked and all(0.0 <= q["a"] < q["b"] <= 1.0 and q["eps"] > 0 for q in asked)
    with open(tmp_path / "q.pkl", "wb") as f:
        pickle.dump(asked, f)
    out = bench.worker({"library": "bundled", "queries": str(tmp_path / "q.pkl")})
    assert len(out["seeds"]) == len(asked) and out["first"] > 0 and out["warm"] > 0
    assert any(out["seeds"]) and bench._same(out["seeds"], out["seeds"]) == 0
    json.dumps(out)  # what the worker prints
    # a moved end is told apart
    i = next(i for i, s in enumerate(out["seeds"]) if s)
    moved = [list(s) for s in out["seeds"]]
    p, x0, x1 = moved[i][0]
    moved[i][0] = (p, x0, x1 + 1e-3)
    assert bench._same(moved, out["seeds"]) == 1
