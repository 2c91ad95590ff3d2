"""``primlib trials``: a series through the command line, read back through the library."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib.cli import main
from primlib.io import read_signal_csv, write_path_csv
from primlib.pipeline import Library
from primlib.plant import Machine
from primlib.store import TrialStore

ROOT = Path(__file__).resolve().parents[1]
STAGE = ROOT / "examples" / "stage"
SIGMA = 0.01


def _stage() -> Machine:
    return Machine.from_json(STAGE / "stage.json")


def _datasheet(stage: Machine) -> Machine:
    # the stage's linear part with the data sheet's mass (20 % light) and damping (15 % low)
    plants = {
        a: ([p["K"] / stage.length_unit], [0.8 * p["M"], 0.85 * p["B"], 0.0])
        for a, p in stage.motors.items()
    }
    return Machine("stage", stage.dt, stage.axes, plants)


def _path(tmp_path: Path, start=(40.0, 25.0), duration: float = 0.6) -> Path:
    dt = 0.002
    t = np.arange(round(duration / dt) + 1) * dt
    s = t / duration
    s = s**3 * (10 - 15 * s + 6 * s**2)
    pts = np.c_[8 * s + 3 * np.sin(2 * np.pi * s), 4 * (1 - np.cos(2 * np.pi * s))]
    f = tmp_path / "path.csv"
    write_path_csv(f, t, pts + np.asarray(start))
    return f


def _run(db: Path, *args) -> object:
    return CliRunner().invoke(main, ["--db", str(db), *[str(a) for a in args]])


@pytest.fixture
def setup(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # default input files land here
    db = tmp_path / "lib.duckdb"
    stage = _stage()
    with Library(db) as lib:
        lib.add_machine(_datasheet(stage))
    return db, stage, _path(tmp_path)


def _measure(stage, u_file: Path, out: Path, start, seed: int) -> np.ndarray:
    t, u = read_signal_csv(u_file)
    y = stage.simulate(u, start=start) + start
    y = y + SIGMA * np.random.default_rng(seed).standard_normal(y.shape)
    write_path_csv(out, t, y)
    return y


def test_a_series_runs_through_the_cli_and_the_library_keeps_it(setup, tmp_path):
    db, stage, path = setup
    start = np.array([40.0, 25.0])
    res = _run(db, "trials", "start", path, "--machine", "stage", "--out", tmp_path / "u0.csv")
    assert res.exit_code == 0, res.output
    assert "started trial series 1 (inverse start)" in res.stdout
    assert "nothing in the library matches" in res.stderr
    u_file = tmp_path / "u0.csv"
    for k in range(4):
        y_file = tmp_path / f"y{k}.csv"
        _measure(stage, u_file, y_file, start, seed=k)
        u_file = tmp_path / f"u{k + 1}.csv"
        res = _run(db, "trials", "step", 1, "--measured", y_file, "--out", u_file)
        assert res.exit_code == 0, res.output
        assert res.stdout.startswith(f"trial {k}: rms ")
    status = json.loads(_run(db, "trials", "status", 1, "--json").stdout)
    assert [t["trial"] for t in status["trials"]] == [0, 1, 2, 3, 4]
    assert status["trials"][-1]["pending"] and status["verdict"] in ("learning", "converged")
    rms = [t["rms"] for t in status["trials"][:4]]
    assert rms[3] < 0.2 * rms[0]  # learning from the model inverse's error
    res = _run(db, "trials", "finish", 1, "--force", "--name", "loop")
    assert res.exit_code == 0, res.output
    with Library(db, read_only=True) as lib:
        (info,) = lib.primitives("stage")
        assert info.name == "loop" and info.source.startswith("trial series 1: 4 trials")
        assert "started at (40, 25)" in info.source
        rec = TrialStore(lib).series(1)
        assert rec.state == "finished" and rec.primitive == info.id
        trials = TrialStore(lib).trials(1)
        np.testing.assert_array_equal(lib.signal(info.id), trials[3].input)
        _, u3 = read_signal_csv(tmp_path / "u3.csv")
        np.testing.assert_array_equal(trials[3].input, u3)
        assert sum(not t.pending for t in trials) == 4
    res = _run(db, "trials", "step", 1, "--measured", tmp_path / "y0.csv")
    assert res.exit_code == 2 and "trial series 1 is finished" in res.stderr


def _bad_files(tmp_path: Path, good: np.ndarray, t: np.ndarray):
    rows = []
    f = tmp_path / "dt.csv"
    write_path_csv(f, t * 2, good)
    rows.append((f, "expected samples every dt = 0.002 s"))
    f = tmp_path / "3d.csv"
    write_path_csv(f, t, np.c_[good, good[:, 0]])
    rows.append((f, "expected measured positions on 2 axes, got 3"))
    f = tmp_path / "short.csv"
    write_path_csv(f, t[:-5], good[:-5])
    rows.append((f, "expected a trial of 301 samples"))
    f = tmp_path / "nan.csv"
    lines = (tmp_path / "y0.csv").read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + ",nan,1.0"
    f.write_text("\n".join(lines) + "\n")
    rows.append((f, "nan.csv.*(NaN|nan)"))
    f = tmp_path / "away.csv"
    write_path_csv(f, t, good + 5.0)
    rows.append((f, r"expected the stage to start at the path's first point \[40.0, 25.0\]"))
    rows.append((tmp_path / "y0.csv", "the same measured output as trial 0"))
    rows.append((tmp_path / "missing.csv", "no such path file"))
    return rows


def test_bad_measured_files_are_refused_in_one_line_and_nothing_is_recorded(setup, tmp_path):
    db, stage, path = setup
    assert (
        _run(db, "trials", "start", path, "-m", "stage", "--out", tmp_path / "u0.csv").exit_code
        == 0
    )
    good = _measure(stage, tmp_path / "u0.csv", tmp_path / "y0.csv", np.array([40.0, 25.0]), 0)
    assert _run(db, "trials", "step", 1, "--measured", tmp_path / "y0.csv").exit_code == 0
    t = np.arange(good.shape[0]) * 0.002
    import re

    for f, pattern in _bad_files(tmp_path, good, t):
        res = _run(db, "trials", "step", 1, "--measured", f, "--out", tmp_path / "next.csv")
        assert res.exit_code == 2, (f, res.output)
        assert len(res.stderr.strip().splitlines()) == 1
        assert re.search(pattern, res.stderr), (pattern, res.stderr)
        assert not (tmp_path / "next.csv").exists()
    with Library(db, read_only=True) as lib:
        assert TrialStore(lib).series(1).steps == 1


def test_start_refuses_bad_options_before_writing(setup, tmp_path):
    db, _, path = setup
    res = _run(db, "trials", "start", path, "-m", "nope")
    assert res.exit_code == 2 and "unknown machine 'nope'" in res.stderr
    res = _run(db, "trials", "start", path, "-m", "stage", "--out", tmp_path / "no" / "u.csv")
    assert res.exit_code == 2 and "does not exist" in res.stderr
    res = _run(db, "trials", "start", path, "-m", "stage", "--margin", "-1")
    assert res.exit_code == 2 and "margin: expected a number in (0, 10)" in res.stderr
    with Library(db, read_only=True) as lib:
        assert TrialStore(lib).ids() == []


def _cmd(code: str) -> str:
    return f'{sys.executable} -c "{code}" {{input}} {{output}}'


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "timeout", "message"),
    [
        (_cmd("import sys; sys.exit(3)"), None, "trial 1: the trial command exited with status 3"),
        (_cmd("pass"), None, "trial 1: the trial command wrote no output file"),
        (
            _cmd("import sys; open(sys.argv[2], 'w').write('t,x,y\\n0,1,2\\n')"),
            None,
            "trial 1: the trial command wrote a malformed output",
        ),
        (
            _cmd("import time; time.sleep(30)"),
            1.0,
            "trial 1: the trial command timed out after 1 s",
        ),
    ],
)
def test_a_failing_trial_command_stops_the_run_and_loses_no_trial(
    setup, tmp_path, command, timeout, message
):
    db, stage, path = setup
    assert (
        _run(db, "trials", "start", path, "-m", "stage", "--out", tmp_path / "u0.csv").exit_code
        == 0
    )
    _measure(stage, tmp_path / "u0.csv", tmp_path / "y0.csv", np.array([40.0, 25.0]), 0)
    assert _run(db, "trials", "step", 1, "--measured", tmp_path / "y0.csv").exit_code == 0
    args = ["trials", "run", 1, "--trial-command", command, "--workdir", tmp_path]
    if timeout:
        args += ["--timeout", timeout]
    res = _run(db, *args)
    assert res.exit_code == 1 and message in res.stderr, res.output
    with Library(db, read_only=True) as lib:
        trials = TrialStore(lib).trials(1)
        assert len(trials) == 2 and not trials[0].pending and trials[1].pending


@pytest.mark.slow
def test_run_drives_the_example_stage_program(setup, tmp_path, monkeypatch):
    db, _, path = setup
    assert (
        _run(db, "trials", "start", path, "-m", "stage", "--out", tmp_path / "u0.csv").exit_code
        == 0
    )
    cmd = f"{sys.executable} {STAGE / 'stage.py'} --start 40,25 {{input}} {{output}}"
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    res = _run(
        db, "trials", "run", 1, "--trial-command", cmd, "--max-trials", 3, "--workdir", tmp_path
    )
    assert res.exit_code == 0, res.output
    assert "stopped: max-trials after 3 trial(s)" in res.stdout
    assert (tmp_path / "series1-trial2-measured.csv").is_file()
    with Library(db, read_only=True) as lib:
        trials = TrialStore(lib).trials(1)
        assert [t.pending for t in trials] == [False, False, False, True]
        assert trials[2].rms < 0.3 * trials[0].rms
