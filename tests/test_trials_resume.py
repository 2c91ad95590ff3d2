"""A series killed with SIGKILL between two steps resumes and ends as an uninterrupted one.

Real processes: ``primlib trials run`` drives the example stage program; a wrapper around
the stage kills the runner (its parent) with SIGKILL after a chosen trial, while the trial
is run and nothing of it is recorded. The runner is started again and continues. The stage
seeds its noise with the input's bytes, so the same input measures the same output, and
the two libraries must hold the same trials, bit for bit.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from primlib.io import write_path_csv
from primlib.pipeline import Library
from primlib.plant import Machine
from primlib.store import TrialStore
from primlib.trials import start

ROOT = Path(__file__).resolve().parents[1]
STAGE = ROOT / "examples" / "stage"

KILLER = """
import os, signal, sys
sys.path.insert(0, {stage!r})
import stage
marker, kill_at = sys.argv[1], {{int(k) for k in sys.argv[2].split(",") if k.isdigit()}}
count = int(open(marker).read()) if os.path.exists(marker) else 0
open(marker, "w").write(str(count + 1))
rc = stage.main(sys.argv[3:])
if count in kill_at:
    os.kill(os.getppid(), signal.SIGKILL)
sys.exit(rc)
"""


def _library(db: Path, path: Path) -> None:
    stage = Machine.from_json(STAGE / "stage.json")
    plants = {
        a: ([p["K"] / stage.length_unit], [0.8 * p["M"], 0.85 * p["B"], 0.0])
        for a, p in stage.motors.items()
    }
    with Library(db) as lib:
        lib.add_machine(Machine("stage", stage.dt, stage.axes, plants))
        assert start(lib, path, "stage").series == 1


def _runner(db: Path, work: Path, marker: Path, kill_at: str, trials: int):
    cmd = (
        f"{sys.executable} {work / 'killer.py'} {marker} {kill_at} "
        "--start 40,25 {input} {output}"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    argv = [sys.executable, "-m", "primlib", "--db", str(db), "trials", "run", "1"]
    argv += ["--trial-command", cmd, "--max-trials", str(trials), "--workdir", str(work)]
    return subprocess.run(argv, capture_output=True, text=True, env=env, timeout=600)


def _trials(db: Path):
    with Library(db, read_only=True) as lib:
        return TrialStore(lib).trials(1)


@pytest.mark.slow
def test_a_series_killed_between_steps_resumes_to_the_same_result(tmp_path):
    dt, T = 0.002, 0.4
    t = np.arange(round(T / dt) + 1) * dt
    s = t / T
    s = s**3 * (10 - 15 * s + 6 * s**2)
    path = tmp_path / "path.csv"
    write_path_csv(path, t, np.c_[40 + 6 * s, 25 + 3 * np.sin(np.pi * s)])
    runs = {}
    for name, kill_at in (("straight", "none"), ("killed", "1,3")):
        work = tmp_path / name
        work.mkdir()
        (work / "killer.py").write_text(KILLER.format(stage=str(STAGE)))
        db = work / "lib.duckdb"
        _library(db, path)
        marker = work / "count"
        remaining, kills = 5, 0
        while remaining > 0:
            before = sum(not tr.pending for tr in _trials(db))
            res = _runner(db, work, marker, kill_at, remaining)
            done = sum(not tr.pending for tr in _trials(db)) - before
            if res.returncode == -signal.SIGKILL:
                kills += 1
            else:
                assert res.returncode == 0, res.stderr
                assert "stopped:" in res.stdout
            remaining -= done
        runs[name] = (_trials(db), kills)
    (a, kills_a), (b, kills_b) = runs["straight"], runs["killed"]
    assert kills_a == 0 and kills_b == 2
    assert len(a) == len(b) == 6
    for ta, tb in zip(a, b, strict=True):
        np.testing.assert_array_equal(ta.input, tb.input)
        if not ta.pending:
            np.testing.assert_array_equal(ta.measured, tb.measured)
            assert ta.rms == tb.rms and ta.digest == tb.digest
    assert a[4].rms < 0.2 * a[0].rms
