"""Smoke test of the length study and the index read-vs-build row of
benchmarks/bench_match.py: short composed and novel paths, each matched in its own
process (its peak memory reported), and the index's DuckDB round trip."""

from __future__ import annotations

import numpy as np
import pytest
from bench_import import benchmark_modules

from primlib.match import BankIndex


@pytest.fixture(scope="module")
def modules():
    with benchmark_modules("_length_scaling", "_index_persist") as found:
        yield found


@pytest.mark.slow
def test_length_study_matches_composed_and_novel_paths_in_own_processes(modules):
    length, _ = modules
    composed = length.run({"kind": "composed", "samples": 600, "library": "bundled"})
    # pieces of stored primitives joined end to start: a few segments cover all of it
    assert composed["matched"] == pytest.approx(1.0)
    assert 1 <= composed["segments"] <= 6
    assert composed["cuts"][-1][0] == pytest.approx(1.0)
    # the process's own peak: the interpreter and numpy (> 20 MB), far below the 1 GB goal
    assert 20 < composed["peak_mb"] < 1024
    novel = length.run({"kind": "novel", "samples": 300, "library": "bundled"})
    assert novel["segments"] >= 1 and 0.0 <= novel["matched"] <= 1.0


def test_a_path_with_rests_holds_still_where_it_says_and_is_matched_whole(modules):
    length, _ = modules
    bank, dt = length.bank_of("bundled")
    pts = length.rest_path(600, dt, seed=0, rest=40)
    assert pts.shape == (600, 3) and np.all(np.isfinite(pts))
    still = np.all(np.diff(pts, axis=0) == 0.0, axis=1)
    assert still.sum() == 3 * 40  # 3 rests: a sample held for 40 more each
    # less the held samples, the same walk, shortened to leave the path its samples
    moving = length.novel_path(600 - 3 * 40, dt, seed=0)
    np.testing.assert_array_equal(pts[np.insert(~still, 0, True)], moving)
    with pytest.raises(ValueError, match="no motion"):
        length.rest_path(600, dt, seed=0, rest=200)
    r = length.run({"kind": "rests", "samples": 600, "rest": 40, "library": "bundled"})
    assert r["cuts"][-1][0] == pytest.approx(1.0) and r["segments"] >= 3


def test_composed_path_is_made_of_stored_pieces(modules):
    length, _ = modules
    bank, dt = length.bank_of("bundled")
    pts = length.composed_path(bank, 900, seed=3)
    assert pts.shape == (900, 3) and np.all(np.isfinite(pts))
    step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    # joined end to start: no jump larger than the fastest stored step at time scale 0.6
    fastest = float(BankIndex(bank).max_step().max())
    assert step.max() <= fastest / 0.6 * (1 + 1e-9)


def test_index_read_back_from_duckdb_equals_the_built_one(modules, tmp_path):
    _, persist = modules
    length, _ = modules
    bank, _ = length.bank_of("bundled")
    # compare() asserts every array read back equals the built one
    r = persist.compare(bank, tmp_path / "index.duckdb", repeat=1)
    assert r["build"] > 0 and r["read"] > 0 and r["mb"] > 0
    # each layout read back and timed (lists, BLOBs, plain columns); "read" the fastest
    reads = [r[f"read_{layout}"] for layout in persist.LAYOUTS]
    assert all(t > 0 for t in reads) and r["read"] == min(reads)


def test_index_build_is_timed_with_the_primlib_on_the_path(modules):
    _, persist = modules
    t = persist.build_seconds(repeat=2, kind="bundled")
    assert 0.0 < t["wall"] < 5.0 and 0.0 < t["cpu"] < 5.0
