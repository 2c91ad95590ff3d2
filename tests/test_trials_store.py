"""The series and trials tables: migration, round trip, the step counter, finishing."""

from __future__ import annotations

import duckdb
import numpy as np
import pytest

from primlib import LibraryBusyError
from primlib._errors import InputError, NotFoundError
from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import MIGRATIONS, TrialStore, _schema
from primlib.store import Store as Library

DT = 0.002


def _machine() -> Machine:
    plants = {"x": ([12000.0], [0.2, 24.0, 0.0]), "y": ([12000.0], [0.26, 33.0, 0.0])}
    return Machine("stage", DT, ["x", "y"], plants)


def _path(n: int = 101) -> Trajectory:
    s = np.linspace(0, 1, n)
    return Trajectory.from_samples(np.c_[10 + 5 * s, 20 + 3 * np.sin(np.pi * s)], DT)


def _series(lib):
    traj = _path()
    pts = traj.sample(DT)
    store = TrialStore(lib)
    rng = np.random.default_rng(0)
    u0 = rng.standard_normal(pts.shape)
    sid = store.create(traj, pts, u0, machine="stage", start="cold", options={"law": "p"})
    return store, sid, pts, u0


def _metrics(d=2):
    return {"rms": 0.5, "rms_axes": np.full(d, 0.3), "contour_rms": 0.2, "noise_floor": None}


def test_the_trials_migration_is_recorded_and_an_old_library_gains_the_tables(tmp_path):
    db = tmp_path / "old.duckdb"
    con = duckdb.connect(str(db))
    _schema.migrate(con, 0, MIGRATIONS[:2])
    con.close()
    with Library(db) as lib:
        versions = [v for v, _, _ in lib.migrations()]
        trials_step = next(v for v, d, _ in MIGRATIONS if d.startswith("trial series"))
        assert trials_step in versions and versions == list(range(1, versions[-1] + 1))
        lib.add_machine(_machine())
        store, sid, _, _ = _series(lib)
        assert store.ids() == [sid]


def test_a_series_round_trips_its_path_input_and_measurements(tmp_path):
    with Library(tmp_path / "l.duckdb") as lib:
        lib.add_machine(_machine())
        store, sid, pts, u0 = _series(lib)
        y = pts + 0.01
        store.record_step(sid, 0, y, "d0", _metrics(), u0 * 0.5)
    with Library(tmp_path / "l.duckdb", read_only=True) as lib:
        store = TrialStore(lib)
        rec = store.series(sid)
        assert (rec.state, rec.steps, rec.start) == ("running", 1, "cold")
        assert rec.options == {"law": "p"}
        np.testing.assert_array_equal(rec.points, pts)
        np.testing.assert_array_equal(rec.origin, pts[0])
        np.testing.assert_allclose(rec.trajectory.sample(DT), pts, atol=1e-12)
        t0, t1 = store.trials(sid)
        np.testing.assert_array_equal(t0.input, u0)
        np.testing.assert_array_equal(t0.measured, y)
        np.testing.assert_array_equal(t1.input, u0 * 0.5)
        assert not t0.pending and t1.pending and t0.digest == "d0" and t0.rms == 0.5
        assert t0.noise_floor is None and t0.recorded is not None


def test_a_step_with_a_stale_counter_is_refused_and_records_nothing(tmp_path):
    with Library(tmp_path / "l.duckdb") as lib:
        lib.add_machine(_machine())
        store, sid, pts, u0 = _series(lib)
        store.record_step(sid, 0, pts, "d0", _metrics(), u0)
        with pytest.raises(LibraryBusyError, match=f"trial series {sid} was stepped by another"):
            store.record_step(sid, 0, pts + 1, "d1", _metrics(), u0)
        assert len(store.trials(sid)) == 2 and store.series(sid).steps == 1
        with pytest.raises(NotFoundError, match="no trial series with id 99"):
            store.record_step(99, 0, pts, "d", _metrics(), u0)


def test_a_finished_series_takes_no_more_steps(tmp_path):
    with Library(tmp_path / "l.duckdb") as lib:
        lib.add_machine(_machine())
        store, sid, pts, u0 = _series(lib)
        store.record_step(sid, 0, pts, "d0", _metrics(), u0)
        store.mark_finished(sid, 7)
        assert store.series(sid).state == "finished" and store.for_primitive(7) == sid
        with pytest.raises(InputError, match=f"trial series {sid} is finished"):
            store.record_step(sid, 1, pts, "d1", _metrics(), u0)


def test_a_second_process_cannot_open_the_library_while_one_writes(tmp_path):
    db = tmp_path / "l.duckdb"
    with Library(db) as lib:
        lib.add_machine(_machine())
        import subprocess
        import sys

        code = (
            "import sys; from primlib.store import Store as Library\n"
            "try:\n    Library(sys.argv[1])\nexcept Exception as e:\n"
            "    print(type(e).__name__); sys.exit(3)\n"
        )
        import os

        env = {**os.environ, "PYTHONPATH": os.getcwd()}
        out = subprocess.run(
            [sys.executable, "-c", code, str(db)], capture_output=True, text=True, env=env
        )
        assert out.returncode == 3 and out.stdout.strip() == "LibraryBusyError"
