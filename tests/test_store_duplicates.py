"""Duplicate primitives (issue 12): same machine, path and signal are stored once."""

from __future__ import annotations

from pathlib import Path

import duckdb
import numpy as np
import pytest

from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import MIGRATIONS, SCHEMA_VERSION, Store, content_hash, migrate

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


def item(k: int, name: str | None = None):
    s = np.linspace(0.0, 1.0, 101)
    pts = np.column_stack([10 * np.cos(s + k), 10 * np.sin(s + k), s])
    u = np.random.default_rng(k).standard_normal((101, 3))
    return Trajectory.from_samples(pts, DT), u, name or f"p{k}", "test"


@pytest.fixture
def store():
    with Store() as s:
        s.add_machine(Machine.from_json(DATA / "xyz.json"))
        yield s


def test_re_adding_the_same_primitive_is_skipped_and_says_which(store):
    first = store.add_batch([item(0), item(1)], "xyz")
    assert first.duplicates == () and first.added == 2
    again = store.add_batch([item(1, "renamed"), item(2)], "xyz")
    assert again.duplicates == (0,) and again.added == 1
    assert again.ids[0] == first.ids[1]
    assert len(store.primitives("xyz")) == 3


def test_the_same_file_twice_in_one_batch_is_stored_once(store):
    res = store.add_batch([item(0), item(3), item(0)], "xyz")
    assert res.duplicates == (2,) and res.ids[2] == res.ids[0]
    assert [p.name for p in store.primitives("xyz")] == ["p0", "p3"]


def test_allow_duplicates_keeps_them(store):
    res = store.add_batch([item(0), item(0)], "xyz", allow_duplicates=True)
    assert res.duplicates == () and len(set(res.ids)) == 2
    assert len(store.primitives("xyz")) == 2


def test_add_returns_the_existing_id_for_an_identical_primitive(store):
    pid = store.add(*item(4)[:2], machine="xyz", name="a")
    assert store.add(*item(4)[:2], machine="xyz", name="b") == pid
    assert len(store.primitives("xyz")) == 1


def test_the_same_path_with_another_signal_is_not_a_duplicate(store):
    traj, u, _, _ = item(5)
    store.add(traj, u, machine="xyz")
    store.add(traj, u + 1e-12, machine="xyz")
    assert len(store.primitives("xyz")) == 2


def test_a_version_2_library_migrates_and_its_primitives_get_their_hash(tmp_path):
    # a library written before the content hash existed: migrations 1-2 only, one primitive
    db = tmp_path / "v2.duckdb"
    with Store(db) as s:
        s.add_machine(Machine.from_json(DATA / "xyz.json"))
        pid = s.add(*item(6)[:2], machine="xyz", name="old")
        points, signal = s.get(pid).points, s.get(pid).signal
    con = duckdb.connect(str(db))
    con.execute("ALTER TABLE primitives DROP COLUMN content_hash")
    # and what later migrations made (the trial series, migration 4; the origin, 5; the
    # error_rms, 6)
    con.execute("DROP TABLE trials; DROP TABLE series; DROP SEQUENCE series_ids")
    con.execute("ALTER TABLE primitives DROP COLUMN origin")
    con.execute("ALTER TABLE primitives DROP COLUMN error_rms")
    con.execute("DROP TABLE fitted_models")  # migration 7
    con.execute("DELETE FROM migrations WHERE version > 2")
    con.execute("UPDATE meta SET value = '2' WHERE key = 'schema_version'")
    con.close()
    with Store(db) as s:
        assert s.schema_version == SCHEMA_VERSION
        assert [v for v, _, _ in s.migrations()][-1] == SCHEMA_VERSION
        stored = s._db().sql("SELECT content_hash FROM primitives").fetchall()
        assert stored == [(content_hash("xyz", points, signal),)]
        # and re-ingesting it after the upgrade is recognised
        assert s.add(*item(6)[:2], machine="xyz", name="again") == pid


def test_migration_3_on_an_empty_table_and_its_place_in_the_list(tmp_path):
    con = duckdb.connect(str(tmp_path / "x.duckdb"))
    assert migrate(con, 0, MIGRATIONS[:3]) == [1, 2, 3]
    cols = [r[0] for r in con.sql("DESCRIBE primitives").fetchall()]
    assert "content_hash" in cols
    con.close()
