"""Smoke test of benchmarks/bench_match_noisy.py: a few noisy stored pieces of the bundled
library at 0.1 % and 1 % noise, and one path of three joined pieces, as in the benchmark."""

from __future__ import annotations

import numpy as np
import pytest
from bench_import import benchmark_modules


def _bench():
    with benchmark_modules("bench_match_noisy") as (bench,):
        return bench


@pytest.mark.slow
def test_index_answers_noisy_pieces_like_the_grid(capsys):
    bench = _bench()
    bank = bench.library("bundled")
    res = bench.single_table(bank, 5)
    for level in bench.NOISE:
        assert res[level]["answered"] == {"grid": 5, "index": 5}
        assert res[level]["differ"] == {"cuts": 0, "worse": 0, "better": 0}
    assert "| 1 % | index | 5/5 |" in capsys.readouterr().out


@pytest.mark.slow
def test_junctions_are_reported_against_the_grid(capsys):
    bench = _bench()
    res = bench.junction_table(bench.library("bundled"), 1)
    assert set(res) == set(bench.NOISE)
    assert "| 0.1 % | grid |" in capsys.readouterr().out


@pytest.mark.slow
def test_queries_below_their_noise_come_out_unmatched_at_about_a_match_s_cost(capsys):
    # eps a quarter of the matched one: half the noise's own RMSD, so no stored piece is
    # within it; the path is mostly unmatched, by both searches
    bench = _bench()
    res = bench.unmatched_table(bench.library("bundled"), 3)
    for level in bench.NOISE:
        assert res[level]["index"]["matched"] < 0.5 and res[level]["grid"]["matched"] < 0.5
        assert res[level]["ratio"] > 0
    assert "| 1 % | index |" in capsys.readouterr().out


def test_the_unmatched_table_can_leave_the_grid_out(capsys):
    bench = _bench()
    res = bench.unmatched_table(bench.library("bundled"), 2, searches=("index",))
    for level in bench.NOISE:
        assert "grid" not in res[level] and res[level]["index"]["matched"] < 0.5
    out = capsys.readouterr().out
    assert "| 0.1 % | index |" in out and "| grid |" not in out


def test_copies_of_the_bundled_library_make_a_bank_past_the_table(capsys):
    # 17 copies of the 7,834 bundled samples: past the table's 131,072, so the roughness
    # bound comes from the differences; the copies are the bundled primitives turned and moved
    from primlib.match._rough import BANK_MAX
    from primlib.match._rough_diff import DiffRoughness

    bench = _bench()
    small, bank = bench.library("bundled"), bench.copies_library(17)
    assert bank.k == 17 * small.k and bank.points.shape[0] > BANK_MAX
    assert isinstance(bank.roughness(), DiffRoughness)
    for j in (0, small.k - 1, 16 * small.k + 3):
        a, b = small.points_of(j % small.k), bank.points_of(j)
        assert np.allclose(np.diff(np.linalg.norm(a - a[0], axis=1)),
                           np.diff(np.linalg.norm(b - b[0], axis=1)), atol=1e-9)  # fmt: skip
    res = bench.unmatched_table(bank, 1, searches=("index",))
    assert all(res[level]["index"]["matched"] < 0.5 for level in bench.NOISE)
    assert "| 1 % | index |" in capsys.readouterr().out
