"""Smoke test of the composed-path case of benchmarks/bench_match.py (``_composed.py``, the
worker ``bench_match.py --composed`` runs with this tree and a baseline revision)."""

from __future__ import annotations

from pathlib import Path

import pytest
from bench_import import benchmark_modules

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def composed():
    with benchmark_modules("_composed") as (module,):
        yield module


def test_worker_times_the_composed_path_and_recovers_its_pieces(composed):
    out = composed.worker({"k": 8, "first": 1, "warm": 1, "root": str(ROOT)})
    assert out["first"] > 0 and out["warm"] > 0
    # 5 pieces of the first 5 primitives (ids 1-5 in a fresh library file)
    assert [p for _, p in out["segments"]] == [1, 2, 3, 4, 5]
    assert out["segments"][-1][0] == 1.0
    # CPU seconds beside the wall times (the first call's include DuckDB's reader threads)
    assert out["first_cpu"] > 0 and out["warm_cpu"] > 0
