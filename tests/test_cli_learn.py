"""``primlib learn``: warm start -> ILC -> (ingest), through CliRunner, read back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from path_helpers import DT
from path_helpers import arc as _arc
from path_helpers import line as _line

from primlib.cli import main
from primlib.io import write_path_csv, write_signal_csv
from primlib.nurbs import Trajectory
from primlib.plant import Machine, invert
from primlib.store import Store

ROOT = Path(__file__).resolve().parents[1]
XYZ = ROOT / "data" / "machines" / "xyz.json"


def _machine_and_path(tmp_path, machine_json, stem, pts):
    """A fresh library holding one machine, and a path CSV of ``pts`` on its dt grid."""
    runner = CliRunner()
    db = tmp_path / f"{stem}.duckdb"
    assert (
        runner.invoke(main, ["--db", str(db), "machine", "add", str(machine_json)]).exit_code == 0
    )
    f = tmp_path / f"{stem}.csv"
    write_path_csv(f, np.arange(pts.shape[0]) * DT, pts)
    return runner, db, f


@pytest.fixture()
def setup(tmp_path):
    """A library file with two primitives, and a new path: the arc at 0.8x speed, then the
    line rotated 90 degrees about z, at rest at the junction."""
    m = Machine.from_json(XYZ)
    db = tmp_path / "lib.duckdb"
    runner = CliRunner()
    assert runner.invoke(main, ["--db", str(db), "machine", "add", str(XYZ)]).exit_code == 0
    files = []
    for stem, pts in (("arc", _arc(1.0)), ("line", _line(1.0))):
        t = np.arange(pts.shape[0]) * DT
        f = tmp_path / f"{stem}.csv"
        write_path_csv(f, t, pts)
        ref = Trajectory.from_csv(f).sample(DT)
        write_signal_csv(tmp_path / f"{stem}.signal.csv", t, invert(m, ref - ref[0]))
        files.append(str(f))
    res = runner.invoke(main, ["--db", str(db), "ingest", *files, "--machine", "xyz"])
    assert res.exit_code == 0, res.output
    a = _arc(1.25)
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    b = _line(1.0) @ rz.T
    path = np.vstack([a, (b + a[-1] - b[0])[1:]])
    new = tmp_path / "new.csv"
    write_path_csv(new, np.arange(path.shape[0]) * DT, path)
    return runner, db, new


def test_learn_warm_beats_cold_and_ingests(setup, tmp_path):
    runner, db, new = setup
    warm = runner.invoke(
        main,
        [
            "--db",
            str(db),
            "learn",
            str(new),
            "--machine",
            "xyz",
            "--iterations",
            "3",
            "--eps",
            "0.01",
            "--json",
        ],
    )
    assert warm.exit_code == 0, warm.output
    w = json.loads(warm.output)
    assert w["start"] == "warm"
    assert len(w["iterations"]) >= 2
    cold = runner.invoke(
        main,
        [
            "--db",
            str(db),
            "learn",
            str(new),
            "--machine",
            "xyz",
            "--iterations",
            "3",
            "--cold",
            "--json",
        ],
    )
    c = json.loads(cold.output)
    assert c["start"] == "cold" and c["warm_start"] is None
    # on the nominal model the warm start is the stored inputs, exactly transformed: its
    # first trial is orders of magnitude better than starting from zero
    assert w["iterations"][0]["rms"] < c["iterations"][0]["rms"] / 100
    assert w["iterations"][0]["contour_rms"] is not None
    with Store(db, read_only=True) as lib:
        assert len(lib.primitives("xyz")) == 2  # nothing stored without --ingest

    res = runner.invoke(
        main,
        [
            "--db",
            str(db),
            "learn",
            str(new),
            "--machine",
            "xyz",
            "--iterations",
            "4",
            "--eps",
            "0.01",
            "--ingest",
            "--name",
            "arc-then-line",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "iteration" in res.output and "stored primitive" in res.output
    with Store(db, read_only=True) as lib:
        infos = lib.primitives("xyz")
        assert [i.name for i in infos][-1] == "arc-then-line"
        prim = lib.get(infos[-1].id)
        m = lib.machine("xyz")
    y = m.simulate(prim.signal)
    err = np.sqrt(np.mean((y - (prim.points - prim.points[0])) ** 2))
    assert err < 1e-3  # the converged input, read back, tracks the stored path


def test_learn_plot_writes_a_figure(setup, tmp_path):
    runner, db, new = setup
    fig = tmp_path / "warm.png"
    res = runner.invoke(
        main,
        [
            "--db",
            str(db),
            "learn",
            str(new),
            "--machine",
            "xyz",
            "--iterations",
            "2",
            "--eps",
            "0.01",
            "--plot",
            str(fig),
        ],
    )
    assert res.exit_code == 0, res.output
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--machine", "nope"], "nope"),
        (["--machine", "xyz", "--eps", "0"], "--eps: expected a match tolerance > 0, got 0"),
        (["--machine", "xyz", "--tol", "-1"], "--tol: expected a tolerance > 0, got -1"),
        (["--machine", "xyz", "--band", "-1"], "--band: expected a width >= 0 s, got -1"),
    ],
)
def test_learn_bad_input_exits_2_and_writes_nothing(setup, args, message):
    runner, db, new = setup
    before = db.read_bytes()
    res = runner.invoke(main, ["--db", str(db), "learn", str(new), *args, "--ingest"])
    assert res.exit_code == 2
    assert message in res.output
    assert db.read_bytes() == before


def test_learn_missing_file_exits_2(setup, tmp_path):
    runner, db, _ = setup
    res = runner.invoke(
        main, ["--db", str(db), "learn", str(tmp_path / "none.csv"), "--machine", "xyz"]
    )
    assert res.exit_code == 2
    assert "none.csv: expected a path CSV file, got no such file" in res.output


def test_example_builds_the_library_and_learns(tmp_path):
    runner = CliRunner()
    db = tmp_path / "example.duckdb"
    fig = tmp_path / "warm.png"
    example = [
        "--db",
        str(db),
        "example",
        "--data",
        str(ROOT / "data"),
        "--path",
        "corner-and-arc",
        "--iterations",
        "1",
        "--plot",
        str(fig),
    ]
    res = runner.invoke(main, example)
    assert res.exit_code == 0, res.output
    assert "warm start from" in res.output
    assert fig.read_bytes()[:4] == b"\x89PNG"
    with Store(db, read_only=True) as lib:
        stems = sorted(
            p.stem
            for p in (ROOT / "data" / "library").glob("*.csv")
            if not p.name.endswith(".signal.csv")
        )
        assert sorted(i.name for i in lib.primitives("xyz")) == stems
        # bundled signals were learned on the XYZ model: each tracks its path
        m = lib.machine("xyz")
        for info in lib.primitives("xyz"):
            p = lib.get(info.id)
            err = np.sqrt(np.mean((m.simulate(p.signal) - (p.points - p.points[0])) ** 2))
            assert err < 1e-3, info.name
    # a second run of the same command reuses the library (no duplicates)
    res = runner.invoke(main, example)
    assert res.exit_code == 0, res.output
    with Store(db, read_only=True) as lib:
        assert len(lib.primitives("xyz")) == len(stems)


def test_example_without_data_exits_2(tmp_path):
    res = CliRunner().invoke(
        main, ["--db", str(tmp_path / "e.duckdb"), "example", "--data", str(tmp_path)]
    )
    assert res.exit_code == 2
    assert "expected the example data" in res.output


def test_learn_without_primitives_starts_cold(tmp_path):
    runner, db, f = _machine_and_path(tmp_path, XYZ, "arc", _arc(1.0))
    res = runner.invoke(
        main, ["--db", str(db), "learn", str(f), "--machine", "xyz", "-n", "2", "--json"]
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["start"] == "cold"
    assert any("no warm start" in note for note in out["notes"])


XY = ROOT / "data" / "machines" / "xy-pdccilc.json"


@pytest.mark.parametrize("law", ["pdccilc", "tdilc"])
def test_learn_master_slave_law_on_the_two_axis_stage(tmp_path, law):
    runner, db, f = _machine_and_path(tmp_path, XY, "arc2", _arc(2.0)[:, :2])
    args = ["--db", str(db), "learn", str(f), "--machine", "xy-pdccilc", "--cold"]
    res = runner.invoke(main, [*args, "--law", law, "-n", "3", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    its = out["iterations"]
    assert len(its) == 4 and out["start"] == "cold"
    # the master-slave result's own contour measure is reported per trial, and learns
    contour = [it["contour_rms"] for it in its]
    assert all(c is not None and np.isfinite(c) for c in contour)
    assert contour[-1] < contour[0]
    assert its[-1]["rms"] < its[0]["rms"]
    assert len(its[0]["rms_axes"]) == 2


def test_learn_master_slave_law_on_three_axes_exits_2(setup):
    runner, db, new = setup
    res = runner.invoke(
        main, ["--db", str(db), "learn", str(new), "--machine", "xyz", "--law", "pdccilc"]
    )
    assert res.exit_code == 2
    msg = "--law: expected a two-axis machine for the master-slave law 'pdccilc', got machine"
    assert msg in res.output
    assert "3 axes (x,y,z)" in res.output


def test_learn_long_path_checks_convergence_without_a_dense_svd(tmp_path):
    # 25 s at 5 ms: n = 5001; the lifted check is iterative (no 5000 x 5000 SVD, no ARPACK)
    runner, db, f = _machine_and_path(tmp_path, XYZ, "long", _arc(25.0))
    res = runner.invoke(
        main, ["--db", str(db), "learn", str(f), "--machine", "xyz", "--cold", "-n", "2", "--json"]
    )
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert len(out["iterations"]) == 3
    assert out["iterations"][-1]["rms"] < 1e-2 * out["iterations"][0]["rms"]


# ---------------------------------------------------------------------------- issue 12
def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize(
    ("plot", "message"),
    [
        ("nowhere/x.png", "folder {tmp}/nowhere does not exist"),
        ("x.foo", "expected a file ending in .png"),
    ],
)
def test_learn_plot_to_a_missing_folder_or_unknown_format_exits_2_before_learning(
    setup, tmp_path, plot, message
):
    runner, db, new = setup
    before = _sha(db)
    args = ["--db", str(db), "learn", str(new), "-m", "xyz", "--ingest", "--plot"]
    res = runner.invoke(main, [*args, str(tmp_path / plot)])
    assert res.exit_code == 2
    assert message.format(tmp=tmp_path) in res.stderr and res.stderr.count("\n") == 1
    assert "iteration" not in res.stdout  # nothing was learned
    assert _sha(db) == before


def test_learn_law_outside_the_fixed_set_is_refused_by_its_choice(setup):
    runner, db, new = setup
    res = runner.invoke(main, ["--db", str(db), "learn", str(new), "-m", "xyz", "--law", "pdx"])
    assert res.exit_code == 2
    assert "Invalid value for '--law': 'pdx' is not one of" in res.stderr
    assert "'norm-optimal'" in res.stderr and "'pdccilc'" in res.stderr


def test_learn_labels_row_0_as_the_start_and_numbers_segments_from_1(setup):
    runner, db, new = setup
    res = runner.invoke(main, ["--db", str(db), "learn", str(new), "-m", "xyz", "-n", "2"])
    assert res.exit_code == 0, res.output
    lines = res.stdout.splitlines()
    segs = [ln.strip() for ln in lines if ln.strip().startswith("segment ")]
    assert [s.split(":")[0] for s in segs] == ["segment 1", "segment 2"]
    rows = [ln for ln in lines if ln.strip()[:1].isdigit()]
    assert len(rows) == 3
    assert rows[0].rstrip().endswith("(warm start, before learning)")
    assert not rows[1].rstrip().endswith(")")
    cold = runner.invoke(
        main, ["--db", str(db), "learn", str(new), "-m", "xyz", "-n", "1", "--cold"]
    )
    first = [ln for ln in cold.stdout.splitlines() if ln.strip()[:1].isdigit()][0]
    assert first.rstrip().endswith("(zero input)")


@pytest.mark.parametrize("name", ["", "a\nb"])
def test_learn_ingest_with_an_empty_or_multi_line_name_is_refused_before_learning(setup, name):
    runner, db, new = setup
    before = _sha(db)
    args = ["--db", str(db), "learn", str(new), "-m", "xyz", "--ingest", "--name", name]
    res = runner.invoke(main, args)
    assert res.exit_code == 2 and "--name: expected the primitive's name" in res.stderr
    assert _sha(db) == before


@pytest.mark.slow
def test_learn_ingest_leaves_the_library_readable_while_it_learns(tmp_path):
    import os
    import subprocess
    import sys
    import time

    from primlib import LibraryBusyError

    runner, db, f = _machine_and_path(tmp_path, XYZ, "long", _arc(20.0))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    cmd = [sys.executable, "-m", "primlib", "--db", str(db), "learn", str(f), "-m", "xyz"]
    proc = subprocess.Popen(
        [*cmd, "--ingest", "-n", "40", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    # A writer on the other side would lock out every reader from the moment it opened
    # the file; while it only reads (learning), opening for reading succeeds throughout.
    opened = busy = 0
    while proc.poll() is None:
        try:
            Store(db, read_only=True).close()
            opened += 1
        except LibraryBusyError:
            busy += 1
        time.sleep(0.05)
    out, err = proc.communicate()
    assert proc.returncode == 0, err
    assert opened >= 20 and busy <= max(3, opened // 10), (opened, busy)
    assert json.loads(out)["ingested"] is not None


def test_example_on_a_library_whose_xyz_machine_differs_is_refused_unchanged(tmp_path):
    spec = json.loads(XYZ.read_text())
    spec["plants"]["x"]["num"] = [2.0]
    other = tmp_path / "other.json"
    other.write_text(json.dumps(spec))
    db = tmp_path / "e.duckdb"
    runner = CliRunner()
    assert runner.invoke(main, ["--db", str(db), "machine", "add", str(other)]).exit_code == 0
    before = _sha(db)
    res = runner.invoke(
        main,
        [
            "--db",
            str(db),
            "example",
            "--data",
            str(ROOT / "data"),
            "--plot",
            str(tmp_path / "w.png"),
        ],
    )
    assert res.exit_code == 2
    assert "machine 'xyz' there has another model than the example's" in res.stderr
    assert res.stderr.count("\n") == 1
    assert _sha(db) == before


def test_example_with_an_unknown_path_names_the_example_paths(tmp_path):
    db = tmp_path / "e.duckdb"
    res = CliRunner().invoke(
        main, ["--db", str(db), "example", "--data", str(ROOT / "data"), "--path", "nope"]
    )
    assert res.exit_code == 2
    assert "--path: expected one of the example paths in" in res.stderr
    assert "glyph-chain" in res.stderr and "got 'nope'" in res.stderr
    assert "run from a primlib clone" not in res.stderr
    assert not db.exists()
