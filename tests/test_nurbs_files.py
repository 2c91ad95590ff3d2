"""Path files as the CLI reads them (primlib.nurbs._files), and the values refused at the door.

Regression tests of issue 12: huge values, constant paths and geomdl JSON paths.
"""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib import InputError
from primlib.cli import main
from primlib.defaults import FIT_RTOL, MAX_ABS_VALUE
from primlib.io import read_path_csv, read_signal_csv, write_path_csv, write_signal_csv
from primlib.nurbs import Trajectory, is_json_path, read_path, read_path_samples

ROOT = Path(__file__).resolve().parents[1]
XYZ = ROOT / "data" / "machines" / "xyz.json"
DT = 0.001  # xyz.json


def _line(n=41):
    t = np.arange(n) * DT
    s = t / t[-1]
    return t, np.c_[10 * s**2 * (3 - 2 * s), 5 * s, 0 * s]


def test_path_csv_with_1e308_is_refused_naming_the_line(tmp_path):
    t, p = _line()
    f = tmp_path / "p.csv"
    write_path_csv(f, t, p)
    lines = f.read_text().splitlines()
    lines[5] = lines[5].split(",")[0] + ",1e308,0,0"
    f.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"p.csv, line 6: expected a magnitude at most 1e\+09"):
        read_path_csv(f)


def test_signal_csv_with_1e308_is_refused_naming_the_line(tmp_path):
    t, _ = _line()
    u = np.zeros((len(t), 3))
    f = tmp_path / "u.csv"
    write_signal_csv(f, t, u)
    lines = f.read_text().splitlines()
    lines[3] = lines[3].split(",")[0] + ",0,-1e308,0"
    f.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"u.csv, line 4: .* column 3 \(uy\), got -1e\+308"):
        read_signal_csv(f)
    lines[3] = lines[3].split(",")[0] + ",0,1e400,0"  # parses to inf
    f.write_text("\n".join(lines))
    with pytest.raises(InputError, match=r"line 4: expected a finite number in column 3"):
        read_signal_csv(f)


@pytest.mark.parametrize("value", [1e308, -2e9, 1e50])
def test_from_samples_refuses_values_beyond_max_abs_value(value):
    _, p = _line()
    p[7, 1] = value
    with pytest.raises(InputError, match="points: expected values of magnitude at most 1e"):
        Trajectory.from_samples(p, DT)
    p[7, 1] = MAX_ABS_VALUE  # the limit itself is accepted
    Trajectory.from_samples(p, DT)


def test_geomdl_json_with_1e308_is_refused(tmp_path):
    _, p = _line()
    tr = Trajectory.from_samples(p, DT)
    f = tmp_path / "p.json"
    tr.to_json(f)
    doc = json.loads(f.read_text())
    doc["shape"]["data"][0]["control_points"]["points"][2][0] = 1e308
    f.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"p.json: ctrlpts: expected values of magnitude"):
        Trajectory.from_json(f)


def test_constant_path_is_refused_by_the_readers_of_ingest_match_learn(tmp_path):
    t, _ = _line()
    f = tmp_path / "still.csv"
    write_path_csv(f, t, np.tile([3.0, 4.0, 5.0], (len(t), 1)))
    read_path_csv(f)  # the format is fine ...
    msg = "still.csv: expected a path that moves"
    with pytest.raises(InputError, match=msg):  # ... but it cannot be matched or learned
        read_path(f)
    with pytest.raises(InputError, match=msg):
        read_path_samples(f, DT)
    # rounding-level motion at a large offset does not count as moving either
    p = np.tile([1e6, 0.0, 0.0], (len(t), 1))
    p[5, 0] += np.spacing(1e6)
    write_path_csv(f, t, p)
    with pytest.raises(InputError, match=msg):
        read_path(f)
    Trajectory.from_samples(p, DT)  # a Trajectory may hold a constant curve for other uses


def test_json_path_is_read_by_suffix_or_content(tmp_path):
    t, p = _line()
    tr = Trajectory.from_samples(p, DT)
    f = tmp_path / "p.json"
    tr.to_json(f)
    g = tmp_path / "p.curve"  # no suffix: recognised by its content
    shutil.copy(f, g)
    assert is_json_path(f) and is_json_path(g) and not is_json_path(tmp_path / "x.csv")
    for src in (f, g):
        got = read_path(src)
        np.testing.assert_allclose(got.ctrlpts, tr.ctrlpts, rtol=0, atol=0)
        ts, ps = read_path_samples(src, DT)
        np.testing.assert_allclose(ts, t, atol=1e-15)
        np.testing.assert_allclose(ps, tr.sample(DT), atol=1e-12)
    with pytest.raises(InputError, match=r"p.json: dt: expected a step that divides"):
        read_path_samples(f, 0.0007)


def _hash(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """A library with the xyz machine and one primitive ingested from a geomdl JSON path."""
    tmp = tmp_path_factory.mktemp("json")
    db = tmp / "lib.duckdb"
    runner = CliRunner()
    res = runner.invoke(main, ["--db", str(db), "machine", "add", str(XYZ)])
    assert res.exit_code == 0, res.output
    src = ROOT / "data" / "library" / "arc-quarter.csv"
    tr = Trajectory.from_csv(src)
    js = tmp / "arc.json"
    tr.to_json(js)
    shutil.copy(src.with_name("arc-quarter.signal.csv"), tmp / "arc.signal.csv")
    res = runner.invoke(main, ["--db", str(db), "ingest", str(js), "--machine", "xyz"])
    assert res.exit_code == 0, res.output
    return {"db": db, "tmp": tmp, "json": js, "tr": tr}


def test_cli_ingest_and_match_accept_a_geomdl_json_path(library):
    # issue 12: the README promised geomdl JSON paths, the CLI said "expected path header"
    db, js = library["db"], library["json"]
    res = CliRunner().invoke(main, ["--db", str(db), "list", "--json"])
    assert res.exit_code == 0, res.output
    assert "arc" in res.output
    res = CliRunner().invoke(
        main, ["--db", str(db), "match", str(js), "--machine", "xyz", "--json"]
    )
    assert res.exit_code == 0, res.output
    segs = json.loads(res.stdout)["segments"]
    # the stored primitive was refitted from the curve's samples: within the fit tolerance
    assert len(segs) == 1 and segs[0]["rmsd"] < FIT_RTOL * library["tr"].extent


def test_cli_refuses_constant_and_huge_paths_with_exit_2_and_unchanged_library(library):
    db, tmp = library["db"], library["tmp"]
    t, _ = _line()
    still = tmp / "still.csv"
    write_path_csv(still, t, np.tile([1.0, 2.0, 3.0], (len(t), 1)))
    write_signal_csv(tmp / "still.signal.csv", t, np.zeros((len(t), 3)))
    huge = tmp / "huge.csv"
    _, p = _line()
    write_path_csv(huge, t, p)
    lines = huge.read_text().splitlines()
    lines[3] = lines[3].split(",")[0] + ",1e308,0,0"
    huge.write_text("\n".join(lines))
    shutil.copy(tmp / "still.signal.csv", tmp / "huge.signal.csv")
    before = _hash(db)
    for f, msg in ((still, "expected a path that moves"), (huge, "expected a magnitude")):
        for cmd in (["ingest", str(f), "--machine", "xyz"], ["match", str(f), "-m", "xyz"]):
            if cmd[0] == "match":
                cmd[-2] = "--machine"
            res = CliRunner().invoke(main, ["--db", str(db), *cmd])
            assert res.exit_code == 2, (cmd, res.output)
            assert msg in res.output and len(res.output.strip().splitlines()) == 1
    assert _hash(db) == before
