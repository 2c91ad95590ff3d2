"""``primlib machine excite`` / ``machine identify`` through CliRunner, the result read back
through ``primlib machine add`` and the library; bad files exit 2 with one line and write
nothing."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib.cli import main
from primlib.io import read_signal_csv, write_path_csv, write_signal_csv
from primlib.plant import Machine
from primlib.store import Store

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
START = np.array([12.0, -3.0, 40.0])


def run(*args, db=None):
    pre = [] if db is None else ["--db", str(db)]
    return CliRunner().invoke(main, [*pre, *map(str, args)])


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    """u.csv from `machine excite`, y.csv the XYZ stage's absolute positions (noise-free)."""
    folder = tmp_path_factory.mktemp("ident")
    res = run("machine", "excite", "--duration", 6, "--amplitude", 1, "--axes", 3,
              "--out", folder / "u.csv")  # fmt: skip
    assert res.exit_code == 0, res.output
    t, u = read_signal_csv(folder / "u.csv")
    y = Machine.from_json(DATA / "xyz.json").simulate(u)
    write_path_csv(folder / "y.csv", t, START + y)
    return folder


@pytest.mark.slow
def test_identify_writes_a_machine_that_machine_add_reads(experiment, tmp_path):
    out, fig = tmp_path / "stage.json", tmp_path / "fit.png"
    res = run("machine", "identify", "--input", experiment / "u.csv", "--output",
              experiment / "y.csv", "--name", "stage", "--out", out,
              "--structure", "second-order", "--plot", fig)  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "held-out NRMSE" in res.output and fig.stat().st_size > 0
    db = tmp_path / "lib.duckdb"
    added = run("machine", "add", out, db=db)
    assert added.exit_code == 0, added.output
    with Store(db, read_only=True) as lib:
        m = lib.machine("stage")
    true = Machine.from_json(DATA / "xyz.json")
    for a in "xyz":
        num, den = true.plants[a]
        got_num, got_den = m.plants[a]
        # noise-free record, the fit's own simulation: recovered to the solver's tolerance
        np.testing.assert_allclose(got_num[-1], num[-1] / den[0], rtol=1e-6)
        np.testing.assert_allclose(got_den, den / den[0], rtol=1e-6, atol=1e-8)
    assert "held-out NRMSE" in json.loads(out.read_text())["note"]


def test_identify_inside_a_pid_loop_at_another_dt(tmp_path):
    true = Machine.from_json(DATA / "xy-pdccilc.json")
    res = run("machine", "excite", "--duration", 8, "--amplitude", 1, "--axes", 2,
              "--out", tmp_path / "u.csv")  # fmt: skip
    assert res.exit_code == 0, res.output
    t, u = read_signal_csv(tmp_path / "u.csv")
    write_path_csv(tmp_path / "y.csv", t, START[:2] + true.simulate(u))
    res = run("machine", "identify", "--input", tmp_path / "u.csv", "--output",
              tmp_path / "y.csv", "--name", "xy", "--out", tmp_path / "xy.json",
              "--structure", "second-order", "--pid", "3,1,0", "--dt", 0.01,
              "--json")  # fmt: skip
    assert res.exit_code == 0, res.output
    report = json.loads(res.output)
    assert report["dt"] == 0.01 and report["record_dt"] == 0.005 and report["held_out"] == 480
    assert report["axes"]["y"]["structure"] == "second-order"
    assert report["axes"]["y"]["nrmse"] < 1e-6 and report["out"] == str(tmp_path / "xy.json")
    m = Machine.from_json(tmp_path / "xy.json")
    assert m.dt == 0.01 and m.feedback["y"] == {"kp": 3.0, "ki": 1.0, "kd": 0.0, "tf": 0.0}
    np.testing.assert_allclose(m.plants["y"][1], [1.0, 2.76, 2.127], rtol=1e-6)


def _bad_files(folder: Path, kind: str) -> tuple[Path, Path]:
    t = np.arange(50) * 0.005
    u = np.random.default_rng(0).standard_normal((50, 2))
    y = np.cumsum(u, axis=0)
    write_signal_csv(folder / "u.csv", t, u)
    if kind == "grid":
        write_path_csv(folder / "y.csv", t * 2, y)
    elif kind == "length":
        write_path_csv(folder / "y.csv", t[:40], y[:40])
    elif kind == "columns":
        write_path_csv(folder / "y.csv", t, np.column_stack([y, y[:, 0]]))
    elif kind == "nan":
        write_path_csv(folder / "y.csv", t, y)
        lines = (folder / "y.csv").read_text().splitlines()
        lines[7] = "0.03,nan,1.0"
        (folder / "y.csv").write_text("\n".join(lines) + "\n")
    else:
        write_path_csv(folder / "y.csv", t, y)
    return folder / "u.csv", folder / "y.csv"


@pytest.mark.parametrize(
    ("kind", "extra", "match"),
    [
        ("grid", [], r"y.csv: expected the time grid of .*u.csv \(dt = 0.005 s\), got dt = 0.01 s"),
        ("length", [], r"y.csv: expected as many samples as .*u.csv \(50\), got 40"),
        ("columns", [], r"y.csv: expected 2 position columns like the input .*u.csv, got 3"),
        ("nan", [], r"y.csv, line 8: expected a finite number in column 2 \(x\), got nan"),
        ("ok", ["--pid", "3,1"], r"--pid 3,1: expected KP,KI,KD\[,TF\] or AXIS=KP,KI,KD"),
        ("ok", ["--pid", "q=3,1,0"], r"--pid q=3,1,0: expected an axis among x, y, got 'q'"),
        ("ok", ["--dt", "-1"], r"--dt: expected a sample time > 0 s, got -1"),
        ("ok", ["--holdout", "0.9"], r"expected at least 20 samples to fit"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, kind, extra, match):
    u, y = _bad_files(tmp_path, kind)
    out = tmp_path / "m.json"
    res = run("machine", "identify", "--input", u, "--output", y, "--name", "m", "--out", out,
              *extra)  # fmt: skip
    assert res.exit_code == 2, res.output
    assert len(res.output.strip().splitlines()) == 1
    assert re.search(match, res.output), res.output
    assert not out.exists()


def test_identify_refuses_an_output_that_is_an_input(tmp_path):
    u, y = _bad_files(tmp_path, "ok")
    res = run("machine", "identify", "--input", u, "--output", y, "--name", "m", "--out", u)
    assert res.exit_code == 2 and "--out" in res.output


def test_excite_prbs_within_the_rate_and_velocity_limits(tmp_path):
    res = run("machine", "excite", "--duration", 5, "--amplitude", 2, "--axes", 3, "--kind",
              "prbs", "--max-rate", 100, "--out", tmp_path / "p.csv", "--seed", 3)  # fmt: skip
    assert res.exit_code == 0, res.output
    t, u = read_signal_csv(tmp_path / "p.csv")
    assert u.shape == (1000, 3) and np.max(np.abs(u)) <= 2.0
    assert np.max(np.abs(np.diff(u, axis=0))) / 0.005 <= 100.0 * (1 + 1e-9)
    m = DATA / "xyz.json"
    res = run("machine", "excite", "--duration", 5, "--amplitude", 50, "--axes", 3,
              "--max-velocity", 10, "--machine", m, "--out", tmp_path / "v.csv")  # fmt: skip
    assert res.exit_code == 0, res.output
    _, u = read_signal_csv(tmp_path / "v.csv")
    vel = np.max(np.abs(np.diff(Machine.from_json(m).simulate(u), axis=0))) / 0.005
    np.testing.assert_allclose(vel, 10.0, rtol=1e-9)
    res = run("machine", "excite", "--duration", 5, "--amplitude", 1, "--axes", 2,
              "--max-velocity", 10, "--out", tmp_path / "w.csv")  # fmt: skip
    assert res.exit_code == 2 and "--max-velocity: expected --machine" in res.output
    assert not (tmp_path / "w.csv").exists()


def test_a_reference_needs_a_pid(tmp_path):
    u, y = _bad_files(tmp_path, "ok")
    res = run("machine", "identify", "--input", u, "--output", y, "--name", "m",
              "--out", tmp_path / "m.json", "--reference", y)  # fmt: skip
    assert res.exit_code == 2 and "--reference: expected --pid" in res.output
    assert not (tmp_path / "m.json").exists()


def test_a_model_that_misses_the_held_out_part_is_flagged(tmp_path):
    # positions unrelated to the input: no linear model follows them
    rng = np.random.default_rng(5)
    t = np.arange(200) * 0.005
    write_signal_csv(tmp_path / "u.csv", t, rng.standard_normal((200, 2)))
    write_path_csv(tmp_path / "y.csv", t, np.cumsum(rng.standard_normal((200, 2)), axis=0))
    res = run("machine", "identify", "--input", tmp_path / "u.csv", "--output",
              tmp_path / "y.csv", "--name", "m", "--out", tmp_path / "m.json",
              "--structure", "integrator")  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "warning: held-out NRMSE above 5 % on x, y" in res.output
