"""Smoke test of benchmarks/bench_realism.py: a tiny run of one setting goes end to end and
its figures mean what they say (the full study is the benchmark's, not the suite's)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_realism  # noqa: E402


def _tiny(setting: str) -> dict:
    """One path per kind (and one novel path), two trials per start, a library of 3
    primitives of 3 trials."""
    return bench_realism.main(
        ["--settings", setting, "--paths", "1", "--trials", "2", "--library-trials", "3",
         "--primitives", "3", "--novel", "1"]
    )  # fmt: skip


@pytest.mark.slow
def test_a_tiny_run_measures_every_start_on_every_kind():
    out = _tiny("ripple 2 %")
    (res,) = out["results"]
    assert res["setting"] == "ripple 2 %"
    for kind in bench_realism.KINDS:
        (row,) = res["rows"][kind]
        first = row["first"]
        assert set(first) == set(bench_realism.STARTS)
        assert all(np.isfinite(v) and v >= 0 for v in first.values())
        # cold does not move an integrating machine: its error is the path's own size
        assert first["cold"] > 10 * first["nominal"] > 0
        assert row["floor"] >= bench_realism.FLOOR_MIN
        assert set(row["choices"]) <= {"stored", "model", "blend"}
        # without noise or a disturbance an input's own error is its first trial's
        assert row["own"] == pytest.approx({s: first[s] for s in row["own"]}, rel=1e-9)
        assert row["bound"] is None and row["draws"] is None  # nothing trial-varying
    # in place, the library's own signal is what the machine needed there
    in_place = res["rows"]["in place"][0]["first"]
    assert in_place["warm"] < in_place["nominal"] / 10
    # a path the library does not hold: every input measured whole and past its start
    (novel,) = res["novel"]
    for part in ("whole", "after"):
        assert set(novel[part]) == set(bench_realism.NOVEL_STARTS)
        assert all(np.isfinite(v) and v >= 0 for v in novel[part].values())
    # the stored signals do no harm beside the model fitted to the same library
    assert novel["after"]["warm"] <= 1.1 * novel["after"]["model-only"]
    assert 0.0 <= novel["matched"] <= 1.0 and novel["segments"] >= 1 and novel["seconds"] > 0


def test_novel_paths_where_the_warm_start_does_harm_fail_the_check():
    def row(warm, model, after_warm, after_model):
        return {
            "whole": {"warm": warm, "model-only": model, "refined": 1.0, "nominal": 2.0},
            "after": {"warm": after_warm, "model-only": after_model, "refined": 1.0,
                      "nominal": 2.0},
            "segments": 3,
            "matched": 0.5,
            "seconds": 1.0,
        }  # fmt: skip

    lines, fails = bench_realism._novel_lines("x", [row(1.0, 1.0, 0.1, 0.1)] * 2)
    assert fails == [] and len(lines) == 3 and "worst 1.000" in lines[0]
    # whole within 1.1x, but past the start 1.2x on one path: the start hid it
    _, fails = bench_realism._novel_lines("x", [row(1.0, 1.0, 0.1, 0.1), row(1.0, 1.0, 0.12, 0.1)])
    assert len(fails) == 1 and "after" in fails[0] and "1.200x" in fails[0]
    assert bench_realism._novel_lines("x", []) == ([], [])


def test_settings_are_named_and_all_together_can_be_asked_for_alone():
    names = bench_realism._setting_names
    assert names("all") == list(bench_realism.SETTINGS)
    assert names("all together") == ["all"]
    assert names("friction 2 %, all together") == ["friction 2 %", "all"]
    with pytest.raises(SystemExit, match="unknown"):
        names("friction 3 %")


@pytest.mark.slow
def test_under_a_disturbance_the_first_trial_bound_is_an_input_better_than_every_start():
    out = _tiny("disturbance")
    for kind in bench_realism.KINDS:
        (row,) = out["results"][0]["rows"][kind]
        bound = row["bound"]
        # ILC on the calm machine from the start of least own error keeps its best trial:
        # never worse than that start, and it leaves the disturbance's draws in its first trials
        assert bound["own"] <= min(row["own"].values()) * (1 + 1e-9)
        assert np.isfinite(bound["draws"]) and bound["draws"] > bound["own"]
        # each start's first trial over draws of its own; the bound under the same draws
        # below the nominal inverse's (a model 8 % off, a 12 ms lag it does not know)
        assert set(row["draws"]) == set(bench_realism.STARTS)
        assert bound["own"] < bound["draws"] < row["draws"]["nominal"]
        # its own series counts its trials to 2x the starts' floor like theirs
        assert bound["trials"] >= 1
        assert bound["trials"] == float("inf") or bound["trials"] == int(bound["trials"])


def test_a_trials_check_the_bound_cannot_meet_says_so():
    rows = [{"bound": {"trials": t}} for t in (2.0, 2.0, 1.0)]
    assert "unreachable" in bench_realism._unreachable_trials(rows, 1.0)
    assert "needs 2" in bench_realism._unreachable_trials(rows, 1.0)
    assert bench_realism._unreachable_trials(rows, 2.0) == ""
    assert bench_realism._unreachable_trials([{"bound": None}], 1.0) == ""


def test_a_path_where_the_mix_did_harm_is_named_with_its_record_against_its_own_error():
    # stop 37's all-together library (seed 0): arc-climb's stored input recorded at 0.0397
    # mm, leaving 0.0993 by itself; its in-place warm start 0.0718 against model-only 0.0493
    climb = {"stem": "arc-climb", "recorded": 0.0397, "own": 0.0993}
    rows = [
        {"own": {"warm": 0.0174, "model-only": 0.0184}, "reused": dict(climb, stem="helix")},
        {"own": {"warm": 0.0718, "model-only": 0.0493}, "reused": climb},
        {"own": {"warm": 0.0122, "model-only": 0.0120}, "reused": None},  # within 1.05x
        {"own": {"warm": 0.2, "model-only": 0.1}, "reused": None},  # a path of no primitive
    ]
    lines = bench_realism._harmed(rows)
    assert len(lines) == 2
    assert "path 1 (arc-climb:" in lines[0] and "0.40x" in lines[0]
    assert "0.0718" in lines[0] and "0.0493" in lines[0]
    assert "path 3:" in lines[1] and "recorded" not in lines[1]


@pytest.mark.slow
def test_a_kept_library_gives_the_same_figures_and_is_left_as_it_was(tmp_path):
    import hashlib

    args = ["--settings", "friction 2 %", "--paths", "1", "--trials", "2", "--library-trials",
            "2", "--primitives", "2"]  # fmt: skip
    first = bench_realism.main([*args, "--save-libraries", str(tmp_path)])
    db = tmp_path / "friction-2-seed0.duckdb"
    assert db.is_file() and (tmp_path / "friction-2-seed0.json").is_file()
    digest = hashlib.sha256(db.read_bytes()).hexdigest()
    again = bench_realism.main([*args, "--reuse-libraries", str(tmp_path)])
    # the new paths are drawn from the state the learning left and run on the same
    # library: the same figures to the bit, and the kept file untouched
    (a,), (b,) = first["results"], again["results"]
    assert b["reused"] and not a["reused"]
    assert json.dumps(a["rows"], default=float) == json.dumps(b["rows"], default=float)
    assert a["stored_error"] == b["stored_error"]
    assert hashlib.sha256(db.read_bytes()).hexdigest() == digest
    # another setting, or other learning options: said, not silently learned or mixed
    with pytest.raises(SystemExit, match="no library of setting 'ripple 2 %'"):
        bench_realism.main([*args[2:], "--settings", "ripple 2 %", "--reuse-libraries",
                            str(tmp_path)])  # fmt: skip
    with pytest.raises(SystemExit, match="was learned with"):
        bench_realism.main([*args[:-1], "3", "--reuse-libraries", str(tmp_path)])


def test_a_learning_that_stops_half_way_leaves_no_old_placements_beside_it(tmp_path, monkeypatch):
    info = tmp_path / "friction-2-seed0.json"
    info.write_text("{}")  # an earlier run's

    def stops(*args, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(bench_realism, "learn_library", stops)
    with pytest.raises(KeyboardInterrupt):
        bench_realism.main(["--settings", "friction 2 %", "--save-libraries", str(tmp_path)])
    assert not info.exists()
    with pytest.raises(SystemExit, match="no library of setting"):
        bench_realism.main(["--settings", "friction 2 %", "--reuse-libraries", str(tmp_path)])
