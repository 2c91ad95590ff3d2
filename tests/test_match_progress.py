"""Progress of a long match: ``match_path(progress=...)`` reports the path covered and the
segments found after each cut, and the CLI's stderr reporter stays silent on a quick run."""

from pathlib import Path

import numpy as np

import primlib as pl
from primlib.cli._progress import stderr_progress
from primlib.match import match_path
from primlib.plant import Machine

ROOT = Path(__file__).resolve().parents[1]


def test_match_reports_the_path_covered_after_each_cut():
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    lib = pl.Library()
    lib.add_machine(machine)
    for name in ("circle", "zigzag-wave", "line-diagonal"):
        p = pl.Trajectory.from_csv(ROOT / "data" / "library" / f"{name}.csv")
        lib.add(p, np.zeros_like(p.sample(machine.dt)), machine="xyz", name=name)
    path = pl.Trajectory.from_csv(ROOT / "data" / "paths" / "corner-and-arc.csv")
    calls = []
    mt = match_path(
        lib.bank("xyz"), path, eps=0.05, min_segment=0.0,
        progress=lambda d, t, s: calls.append((d, t, s)),
    )  # fmt: skip
    n = int(round(path.duration / machine.dt))
    assert calls and all(t == n for _, t, _ in calls)
    done = [d for d, _, _ in calls]
    assert done == sorted(done) and done[-1] == n and done[0] > 0
    assert len(calls) >= len(mt.segments)  # one call per cut at least
    found = [s for _, _, s in calls]
    assert found == sorted(found) and found[0] >= 1 and found[-1] == len(mt.segments)


def test_stderr_progress_waits_then_prints(capsys):
    quiet = stderr_progress("match", after=60.0)
    quiet(5, 10)
    quiet(10, 10)
    assert capsys.readouterr().err == ""
    loud = stderr_progress("match", after=0.0, every=60.0)
    loud(5, 10)
    loud(6, 10)  # within `every` of the last line: skipped
    loud(10, 10)  # the end always prints
    assert capsys.readouterr().err == "match: 5/10\nmatch: 10/10\n"


def test_stderr_progress_draws_a_bar_and_the_segments_found(capsys):
    report = stderr_progress("match", bar=10, found="segments")
    report(0, 12, 0)
    report(6, 12, 3)
    report(12, 12, 7)
    assert capsys.readouterr().err.splitlines() == [
        "match: [..........] 0/12 (0 %), 0 segments",
        "match: [#####.....] 6/12 (50 %), 3 segments",
        "match: [##########] 12/12 (100 %), 7 segments",
    ]


def test_learn_reports_its_match_progress():
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    lib = pl.Library()
    lib.add_machine(machine)
    for name in ("circle", "line-diagonal"):
        p = pl.Trajectory.from_csv(ROOT / "data" / "library" / f"{name}.csv")
        lib.add(p, np.zeros_like(p.sample(machine.dt)), machine="xyz", name=name)
    path = pl.Trajectory.from_csv(ROOT / "data" / "paths" / "corner-and-arc.csv")
    calls = []
    run = lib.starter.learn(
        path, "xyz", iterations=1, contour=False, progress=lambda *c: calls.append(c)
    )
    n = int(round(path.duration / machine.dt))
    assert run.start == "warm" and calls[-1][:2] == (n, n)
