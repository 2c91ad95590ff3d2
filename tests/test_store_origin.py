"""Where a primitive ran (issue 9): the ``origin`` column, its migration and its refusals."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import duckdb
import numpy as np
import pytest
from click.testing import CliRunner

from primlib import InputError, NotALibraryError
from primlib.cli import main
from primlib.io import write_path_csv, write_signal_csv
from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.plant import Machine
from primlib.store import SCHEMA_VERSION, Store
from primlib.trials import TrialSeries, pending, start, step

ROOT = Path(__file__).resolve().parents[1]
XYZ = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
DT = XYZ.dt


def item(k: int):
    s = np.linspace(0.0, 1.0, 101)
    pts = np.column_stack([10 * np.cos(s + k), 10 * np.sin(s + k), s])
    u = np.random.default_rng(k).standard_normal((101, 3))
    return Trajectory.from_samples(pts, DT), u


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_origin_round_trips_through_a_library_file(tmp_path):
    db = tmp_path / "lib.duckdb"
    origin = (120.5, -3.25, 40.0)
    with Store(db) as s:
        s.add_machine(XYZ)
        a = s.add(*item(0), machine="xyz", name="placed", origin=np.array(origin))
        b = s.add(*item(1), machine="xyz", name="unknown")
        c, d = s.add_many([(*item(2), "c", None, [1.0, 2.0, 3.0]), (*item(3), "d")], "xyz")
    with Store(db, read_only=True) as s:
        assert s.info(a).origin == origin and s.info(b).origin is None
        assert s.get(a).origin == origin and s.get(c).origin == (1.0, 2.0, 3.0)
        assert [p.origin for p in s.primitives("xyz")] == [origin, None, (1.0, 2.0, 3.0), None]
        assert s.info(a).to_dict()["origin"] == list(origin)
        assert s.info(d).to_dict()["origin"] is None
        bank = s.bank("xyz")
        assert bank.origins.shape == (4, 3) and not bank.origins.flags.writeable
        np.testing.assert_array_equal(bank.origins[[0, 2]], [origin, (1.0, 2.0, 3.0)])
        assert np.all(np.isnan(bank.origins[[1, 3]]))


@pytest.mark.parametrize(
    ("origin", "match"),
    [
        ([1.0, 2.0], r"primitive 'bad': expected an origin of 3 coordinates \(axes x, y, z\)"),
        ([1.0, 2.0, 3.0, 4.0], "primitive 'bad': expected an origin of 3 coordinates"),
        ([1.0, float("nan"), 3.0], "primitive 'bad': expected a finite origin, got NaN or inf"),
        ([1.0, 2.0, float("inf")], "primitive 'bad': expected a finite origin, got NaN or inf"),
        ("here", "primitive 'bad': expected an origin of 3 coordinates"),
        ([1e300, 0.0, 0.0], "primitive 'bad': expected origin values within"),
    ],
)
def test_a_bad_origin_is_refused_and_the_file_is_unchanged(tmp_path, origin, match):
    db = tmp_path / "lib.duckdb"
    with Store(db) as s:
        s.add_machine(XYZ)
        s.add(*item(0), machine="xyz", name="good")
    before = _digest(db)
    with Store(db) as s:
        with pytest.raises(InputError, match=match):
            s.add(*item(1), machine="xyz", name="bad", origin=origin)
        with pytest.raises(InputError, match=r"item 1 \('bad'\): expected"):
            s.add_many([(*item(2), "fine", None, None), (*item(1), "bad", None, origin)], "xyz")
        assert [p.name for p in s.primitives()] == ["good"]
    assert _digest(db) == before


def test_a_version_4_library_migrates_its_primitives_to_an_unknown_origin(tmp_path):
    db = tmp_path / "v4.duckdb"
    with Store(db) as s:
        s.add_machine(XYZ)
        pid = s.add(*item(5), machine="xyz", name="old")
        points = s.get(pid).points
    # what the file looked like before migration 5
    con = duckdb.connect(str(db))
    con.execute("ALTER TABLE primitives DROP COLUMN origin")
    con.execute("ALTER TABLE primitives DROP COLUMN error_rms")  # migration 6
    con.execute("DROP TABLE fitted_models")  # migration 7
    con.execute("DELETE FROM migrations WHERE version > 4")
    con.execute("UPDATE meta SET value = '4' WHERE key = 'schema_version'")
    con.close()
    with pytest.raises(NotALibraryError, match="schema version 4, older than this primlib"):
        Store(db, read_only=True)  # a reader does not upgrade
    with Store(db) as s:
        assert s.schema_version == SCHEMA_VERSION >= 5
        version, description, _ = s.migrations()[4]
        assert version == 5 and description.startswith("primitives: origin")
        old = s.get(pid)
        assert old.origin is None and old.name == "old"
        np.testing.assert_array_equal(old.points, points)
        assert np.all(np.isnan(s.bank("xyz").origins))
        new = s.add(*item(6), machine="xyz", origin=[0.0, 1.0, 2.0])
        assert s.info(new).origin == (0.0, 1.0, 2.0)


def test_ingest_origin_show_and_list(tmp_path):
    db = tmp_path / "lib.duckdb"
    with Store(db) as s:
        s.add_machine(XYZ)
    files = []
    for k in (0, 1):
        traj, u = item(k)
        t = np.arange(101) * DT
        write_path_csv(tmp_path / f"p{k}.csv", t, traj.sample(DT))
        write_signal_csv(tmp_path / f"p{k}.signal.csv", t, u)
        files.append(str(tmp_path / f"p{k}.csv"))
    run = CliRunner().invoke
    args = ["--db", str(db), "ingest", *files, "-m", "xyz"]
    before = _digest(db)
    res = run(main, [*args, "--origin", "1,2"])
    assert res.exit_code == 2 and "got 1 --origin for 2 paths" in res.output
    res = run(main, [*args, "--origin", "1,2", "--origin", "3,4"])
    assert res.exit_code == 2 and "expected an origin of 3 coordinates" in res.output
    res = run(main, [*args, "--origin", "1,2,x", "--origin", "3,4,5"])
    assert res.exit_code == 2 and "expected comma-separated numbers X,Y[,Z], got '1,2,x'" in (
        res.output
    )
    res = run(main, [*args, "--origin", "1,2,nan", "--origin", "3,4,5"])
    assert res.exit_code == 2 and "expected a finite origin" in res.output
    assert _digest(db) == before
    res = run(main, [*args, "--origin", "10,20,30.5", "--origin", "-1,0,2"])
    assert res.exit_code == 0, res.output
    with Store(db, read_only=True) as s:
        assert [p.origin for p in s.primitives()] == [(10.0, 20.0, 30.5), (-1.0, 0.0, 2.0)]
    listed = json.loads(run(main, ["--db", str(db), "list", "--json"]).output)
    assert [p["origin"] for p in listed] == [[10.0, 20.0, 30.5], [-1.0, 0.0, 2.0]]
    shown = json.loads(run(main, ["--db", str(db), "show", "1", "--json"]).output)
    assert shown["origin"] == [10.0, 20.0, 30.5]
    text = run(main, ["--db", str(db), "show", "2"]).output
    assert "origin     (-1, 0, 2) (where it ran)" in text
    run(main, ["--db", str(db), "ingest", str(tmp_path / "p0.csv"), "-m", "xyz", "--name", "q",
               "--allow-duplicates"])  # fmt: skip
    assert "origin     unknown" in run(main, ["--db", str(db), "show", "3"]).output


def test_finishing_a_trial_series_records_where_it_ran():
    with Library() as lib:
        lib.add_machine(XYZ)
        traj, _ = item(7)
        moved = Trajectory.from_samples(traj.sample(DT) + [50.0, -20.0, 5.0], DT)
        sid = start(lib, moved, "xyz", first="cold").series
        _, _, u = pending(lib, sid)
        origin = moved.at([0.0])[0]
        step(lib, sid, XYZ.simulate(u) + origin)
        pid = TrialSeries(lib, sid).finish(force=True)
        np.testing.assert_allclose(lib.info(pid).origin, origin, rtol=0, atol=0)
        np.testing.assert_array_equal(lib.bank("xyz").origins[0], origin)
