"""CLI library commands through CliRunner, read back through the Store; bad input exits 2."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib.cli import main
from primlib.io import read_path_csv, read_signal_csv, write_path_csv, write_signal_csv
from primlib.store import Store

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005
N = 241


def path_points(k: int = 0, n: int = N, d: int = 3) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * DT
    pts = np.column_stack([20 * np.cos(t + k), 20 * np.sin(2 * t), 3 * t])[:, :d]
    return t, pts


def write_pair(folder: Path, stem: str, k: int = 0) -> tuple[Path, Path, np.ndarray]:
    t, pts = path_points(k)
    u = np.random.default_rng(k).standard_normal((N, 3))
    write_path_csv(folder / f"{stem}.csv", t, pts)
    write_signal_csv(folder / f"{stem}.signal.csv", t, u)
    return folder / f"{stem}.csv", folder / f"{stem}.signal.csv", u


def run(db: Path, *args: str):
    return CliRunner().invoke(main, ["--db", str(db), *map(str, args)])


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """A library with the XYZ machine and one primitive, built once per module."""
    folder = tmp_path_factory.mktemp("template")
    db = folder / "lib.duckdb"
    assert run(db, "machine", "add", DATA / "xyz.json").exit_code == 0
    path, _, _ = write_pair(folder, "seed", 9)
    assert run(db, "ingest", path, "--machine", "xyz").exit_code == 0
    return db


@pytest.fixture
def db(tmp_path, template) -> Path:
    """A fresh copy of the template library (closed files copy safely)."""
    db = tmp_path / "lib.duckdb"
    shutil.copyfile(template, db)
    return db


def count(db: Path) -> int:
    with Store(db, read_only=True) as lib:
        return len(lib.primitives())


# ---------------------------------------------------------------------------- happy paths
def test_machine_add_creates_the_library_and_is_idempotent(tmp_path):
    db = tmp_path / "new.duckdb"
    res = run(db, "machine", "add", DATA / "xyz.json")
    assert res.exit_code == 0, res.output
    assert "added machine 'xyz' (dt = 0.005 s, axes x, y, z)" in res.stdout
    res = run(db, "machine", "add", DATA / "xyz.json")
    assert res.exit_code == 0 and "unchanged" in res.stdout
    assert run(db, "machine", "add", DATA / "xy-pdccilc.json").exit_code == 0
    with Store(db, read_only=True) as lib:
        assert lib.machines() == ["xy-pdccilc", "xyz"]
        assert lib.machine("xyz").to_dict() == json.loads((DATA / "xyz.json").read_text())
    listing = run(db, "machine", "list")
    assert listing.exit_code == 0
    assert [line.split()[0] for line in listing.stdout.splitlines()[2:]] == ["xy-pdccilc", "xyz"]
    rows = json.loads(run(db, "machine", "list", "--json").stdout)
    assert [(r["name"], r["dt"], r["primitives"]) for r in rows] == [
        ("xy-pdccilc", 0.005, 0),
        ("xyz", 0.005, 0),
    ]


def test_machine_add_replace(tmp_path):
    db = tmp_path / "lib.duckdb"
    run(db, "machine", "add", DATA / "xyz.json")
    d = json.loads((DATA / "xyz.json").read_text())
    d["plants"]["x"]["num"] = [1.5]
    other = tmp_path / "xyz2.json"
    other.write_text(json.dumps(d))
    res = run(db, "machine", "add", other)
    assert res.exit_code == 2 and "--replace" in res.stderr
    res = run(db, "machine", "add", other, "--replace")
    assert res.exit_code == 0 and "replaced machine 'xyz'" in res.stdout
    with Store(db, read_only=True) as lib:
        assert lib.machine("xyz").plants["x"][0].tolist() == [1.5]


def test_machine_remove(db):
    res = run(db, "machine", "remove", "xyz")
    assert res.exit_code == 2 and "has 1 primitives" in res.stderr
    assert count(db) == 1
    res = run(db, "machine", "remove", "xyz", "--with-primitives")
    assert res.exit_code == 0 and "removed machine 'xyz' and its 1 primitives" in res.stdout
    with Store(db, read_only=True) as lib:
        assert lib.machines() == [] and lib.primitives() == []


def test_ingest_with_signal_stores_what_the_files_hold(tmp_path, db):
    path, _, _ = write_pair(tmp_path, "glyph", 1)
    _, other_signal, u = write_pair(tmp_path, "other", 2)
    res = run(db, "ingest", path, "--signal", other_signal, "--machine", "xyz", "--name", "g1")
    assert res.exit_code == 0, res.output
    assert "added 1 primitive to machine 'xyz'" in res.stdout
    with Store(db, read_only=True) as lib:
        info = lib.primitives()[-1]
        assert (info.name, info.source, info.n_samples) == ("g1", str(path), N)
        _, u_file = read_signal_csv(other_signal)
        np.testing.assert_array_equal(lib.signal(info.id), u_file)
        np.testing.assert_array_equal(lib.signal(info.id), u)
        # the fitted path is within the fit tolerance (1e-4 of twice the radius) of the samples
        _, pts = path_points(1)
        size = 2.0 * np.sqrt(((pts - pts.mean(axis=0)) ** 2).sum(axis=1).max())
        assert np.abs(lib.get(info.id).points - pts).max() <= 1e-4 * size * (1 + 1e-9)


def test_ingest_many_reads_sibling_signals(tmp_path, db):
    files = [write_pair(tmp_path, f"p{k}", k) for k in range(4)]
    # as from `primlib ingest folder/*.csv`: the signal files are recognised as signals
    everything = sorted(str(x) for f in files for x in f[:2])
    res = run(db, "ingest", *everything, "-m", "xyz")
    assert res.exit_code == 0, res.output
    assert "added 4 primitives" in res.stdout
    with Store(db, read_only=True) as lib:
        infos = lib.primitives()[1:]
        assert [p.name for p in infos] == ["p0", "p1", "p2", "p3"]
        for p, (_, _, u) in zip(infos, files, strict=True):
            np.testing.assert_array_equal(lib.signal(p.id), u)


def test_ingest_learn_stores_a_learned_signal(tmp_path):
    # An empty machine: learn_signal starts cold (nothing to warm-start from), which keeps
    # this a test of the command's wiring; primlib.splice's tests cover the learning.
    db = tmp_path / "lib.duckdb"
    assert run(db, "machine", "add", DATA / "xyz.json").exit_code == 0
    t, pts = path_points(3)
    write_path_csv(tmp_path / "learn.csv", t, pts)
    res = run(db, "ingest", tmp_path / "learn.csv", "--learn", "--iterations", "2", "-m", "xyz")
    assert res.exit_code == 0, res.output
    with Store(db, read_only=True) as lib:
        info = lib.primitives()[-1]
        assert "learned by ILC, 2 iterations" in info.source
        u = lib.signal(info.id)
        assert u.shape == (N, 3) and np.isfinite(u).all() and np.abs(u).max() > 0


def test_list_show_remove(tmp_path, db, monkeypatch):
    path, _, _ = write_pair(tmp_path, "glyph", 1)
    monkeypatch.setenv("PRIMLIB_DB", str(db))  # the environment names the library
    res = CliRunner().invoke(main, ["ingest", str(path), "-m", "xyz"])
    assert res.exit_code == 0, res.output
    table = run(db, "list").stdout.splitlines()
    assert table[0].split() == [
        "id",
        "name",
        "machine",
        "duration",
        "[s]",
        "samples",
        "source",
        "added",
        "(UTC)",
    ]
    assert [line.split()[:5] for line in table[2:]] == [
        ["1", "seed", "xyz", "1.200", "241"],
        ["2", "glyph", "xyz", "1.200", "241"],
    ]
    rows = json.loads(run(db, "list", "--json", "--machine", "xyz").stdout)
    assert [(r["id"], r["name"], r["n_samples"]) for r in rows] == [(1, "seed", N), (2, "glyph", N)]
    shown = run(db, "show", "2")
    assert shown.exit_code == 0 and "primitive 2: glyph" in shown.stdout
    d = json.loads(run(db, "show", "2", "--json").stdout)
    with Store(db, read_only=True) as lib:
        p = lib.get(2)
        np.testing.assert_array_equal(d["nurbs"]["ctrlpts"], p.trajectory.ctrlpts)
        assert d["signal_rms"]["x"] == pytest.approx(np.sqrt(np.mean(p.signal[:, 0] ** 2)))
    out, path_out = tmp_path / "u.csv", tmp_path / "p.csv"
    assert run(db, "show", "2", "--signal-out", out, "--path-out", path_out).exit_code == 0
    t_out, u_out = read_signal_csv(out)
    np.testing.assert_array_equal(u_out, p.signal)
    np.testing.assert_array_equal(read_path_csv(path_out)[1], p.points)
    np.testing.assert_allclose(t_out, np.arange(N) * DT, rtol=0, atol=1e-12)
    res = run(db, "remove", "1")
    assert res.exit_code == 0 and "removed primitive 1 (seed" in res.stdout
    assert [p["id"] for p in json.loads(run(db, "list", "--json").stdout)] == [2]


# ---------------------------------------------------------------------------- bad input
def _rows(t, values):
    return "\n".join(",".join(repr(float(x)) for x in row) for row in np.column_stack([t, values]))


def _bad_path(kind: str, folder: Path) -> tuple[list[str], str]:
    """Write a bad case; return the ingest arguments and the file the error must name."""
    t, pts = path_points(5)
    u = np.zeros((N, 3))
    p, s = folder / "bad.csv", folder / "bad.signal.csv"
    write_path_csv(p, t, pts)
    write_signal_csv(s, t, u)
    good_header = "t,x,y,z\n"
    if kind == "missing column":
        p.write_text(good_header + _rows(t, pts[:, :2]))
    elif kind == "extra column":
        p.write_text(good_header + _rows(t, np.column_stack([pts, pts[:, 0]])))
    elif kind == "wrong header":
        p.write_text("t,x,q,z\n" + _rows(t, pts))
    elif kind == "non-uniform t":
        t2 = t.copy()
        t2[100:] += 0.001
        p.write_text(good_header + _rows(t2, pts))
    elif kind == "non-increasing t":
        t2 = t.copy()
        t2[50] = t2[49]
        p.write_text(good_header + _rows(t2, pts))
    elif kind in ("NaN", "inf"):
        bad = pts.copy()
        bad[7, 1] = np.nan if kind == "NaN" else np.inf
        p.write_text(good_header + _rows(t, bad))
    elif kind == "too few samples":
        p.write_text(good_header + _rows(t[:5], pts[:5]))
    elif kind == "dt differs from the machine's":
        write_path_csv(p, np.arange(N) * 0.001, pts)
    elif kind == "2-D path for 3 axes":
        write_path_csv(p, t, pts[:, :2])
    elif kind == "signal grid differs":
        write_signal_csv(s, t[:-1], u[:-1])
        return [str(p), "-m", "xyz"], str(s)
    elif kind == "signal with 2 axes":
        write_signal_csv(s, t, u[:, :2])
        return [str(p), "-m", "xyz"], str(s)
    elif kind == "signal NaN":
        s.write_text("t,ux,uy,uz\n" + _rows(t, np.where(t[:, None] > 0.5, np.nan, u)))
        return [str(p), "-m", "xyz"], str(s)
    elif kind == "no signal":
        s.unlink()
        return [str(p), "-m", "xyz"], str(p)
    elif kind == "unknown machine":
        return [str(p), "-m", "q"], "unknown machine 'q'; the library has: xyz"
    return [str(p), "-m", "xyz"], str(p)


BAD = [
    "missing column",
    "extra column",
    "wrong header",
    "non-uniform t",
    "non-increasing t",
    "NaN",
    "inf",
    "too few samples",
    "dt differs from the machine's",
    "2-D path for 3 axes",
    "signal grid differs",
    "signal with 2 axes",
    "signal NaN",
    "no signal",
    "unknown machine",
]


@pytest.mark.parametrize("kind", BAD)
def test_bad_ingest_exits_2_with_one_line_and_leaves_the_library_unchanged(tmp_path, db, kind):
    good = [write_pair(tmp_path, f"ok{k}", k)[0] for k in range(2)]
    args, named = _bad_path(kind, tmp_path)
    before = sha(db)
    # the bad file sits between good ones: none of them may be written
    res = run(db, "ingest", good[0], args[0], good[1], *args[1:])
    assert res.exit_code == 2, res.output
    lines = [line for line in res.stderr.splitlines() if line.startswith("Error:")]
    assert len(lines) == 1 and named in lines[0], res.stderr
    assert "Traceback" not in res.output
    assert sha(db) == before
    assert count(db) == 1


MACHINES_BAD = {
    "improper": {"x": {"num": [1.0, 0.0, 0.0], "den": [1.0, 1.0]}},
    "unstable": {"x": {"num": [1.0], "den": [1.0, -2.0]}},
}


@pytest.mark.parametrize("kind", sorted(MACHINES_BAD))
def test_bad_machine_json_exits_2_and_writes_nothing(tmp_path, db, kind):
    spec = {"name": "bad", "dt": 0.005, "axes": ["x"], "plants": MACHINES_BAD[kind]}
    f = tmp_path / "bad.json"
    f.write_text(json.dumps(spec))
    before = sha(db)
    res = run(db, "machine", "add", f)
    assert res.exit_code == 2, res.output
    assert res.stderr.count("\n") == 1 and "Error:" in res.stderr and "Traceback" not in res.output
    assert sha(db) == before
    fresh = tmp_path / "fresh.duckdb"
    assert run(fresh, "machine", "add", f).exit_code == 2
    assert not fresh.exists()  # nothing created either


def test_a_file_that_is_not_a_library_is_refused_unchanged(tmp_path):
    fake = tmp_path / "x.duckdb"
    fake.write_text("this is not a database\n")
    path, _, _ = write_pair(tmp_path, "g", 0)
    before = sha(fake)
    for args in (
        ["machine", "add", DATA / "xyz.json"],
        ["ingest", path, "-m", "xyz"],
        ["list"],
        ["show", "1"],
        ["remove", "1"],
    ):
        res = run(fake, *args)
        assert res.exit_code == 2, (args, res.output)
        assert f"Error: {fake} is not a primlib library" in res.stderr
    assert sha(fake) == before


def test_usage_errors_and_unknown_ids_exit_2(tmp_path, db):
    path, signal, _ = write_pair(tmp_path, "g", 0)
    before = sha(db)
    for args, text in [
        (["ingest", path, "--learn", "--signal", signal, "-m", "xyz"], "mutually exclusive"),
        (["ingest", path, path, "--signal", signal, "-m", "xyz"], "got 1 --signal for 2 paths"),
        (["ingest", path, path, "--name", "n", "-m", "xyz"], "--name names one primitive"),
        (["show", "42"], "no primitive with id 42"),
        (["remove", "42"], "no primitive with id 42"),
        (["list", "--machine", "q"], "unknown machine 'q'"),
    ]:
        res = run(db, *args)
        assert res.exit_code == 2 and text in res.stderr, (args, res.output)
    assert sha(db) == before
    res = run(tmp_path / "none.duckdb", "ingest", path, "-m", "xyz")
    assert res.exit_code == 2 and "no such library file" in res.stderr
    assert not (tmp_path / "none.duckdb").exists()


def test_help_documents_the_sibling_signal_file():
    res = CliRunner().invoke(main, ["ingest", "--help"])
    assert res.exit_code == 0
    assert "<stem>.signal.csv" in res.stdout and "--learn" in res.stdout


def test_a_busy_library_exits_2_with_one_line(tmp_path, db):
    hold = "import sys\nfrom primlib.store import Store\nlib = Store(sys.argv[1])\n"
    hold += "print('open', flush=True)\nsys.stdin.read()\nlib.close()\n"
    root = str(Path(__file__).resolve().parents[1])
    with subprocess.Popen(
        [sys.executable, "-c", hold, str(db)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": root},
    ) as holder:
        try:
            assert holder.stdout.readline().strip() == "open"
            path, _, _ = write_pair(tmp_path, "g", 0)
            for args in (["list"], ["ingest", path, "-m", "xyz"], ["remove", "1"]):
                res = run(db, *args)
                assert res.exit_code == 2, res.output
                assert res.stderr.strip() == (
                    f"Error: {db} is busy: another process has it open; try again when it finishes"
                )
        finally:
            holder.stdin.close()
            holder.wait(timeout=30)
    assert count(db) == 1


@pytest.mark.parametrize(
    ("option", "target", "message"),
    [
        ("--signal-out", "nowhere/x.csv", "folder {tmp}/nowhere does not exist"),
        ("--path-out", "nowhere/x.csv", "folder {tmp}/nowhere does not exist"),
        ("--signal-out", "x.foo", "expected a file ending in .csv"),
    ],
)
def test_show_output_to_a_missing_folder_or_format_exits_2_with_one_line(
    tmp_path, db, option, target, message
):
    res = run(db, "show", "1", option, tmp_path / target)
    assert res.exit_code == 2
    assert message.format(tmp=tmp_path) in res.stderr and res.stderr.count("\n") == 1
    assert "Traceback" not in res.output
    assert not (tmp_path / target).exists()
