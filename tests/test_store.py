"""Store: DuckDB round trips, all-or-nothing batches, bank, lookups, errors, busy files."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import duckdb
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from primlib import InputError, LibraryBusyError, NotALibraryError, NotFoundError
from primlib.defaults import MAX_ABS_VALUE
from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import MIGRATIONS, SCHEMA_VERSION, Bank, Store, _schema

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


def xyz() -> Machine:
    return Machine.from_json(DATA / "xyz.json")


def xy() -> Machine:
    return Machine.from_json(DATA / "xy-pdccilc.json")


def curve(seed: int, d: int = 3, steps: int = 240, m: int = 7, rational: bool = False):
    """A random clamped cubic NURBS of duration steps * DT (cheap: no fitting)."""
    rng = np.random.default_rng(seed)
    p = 3
    interior = np.sort(rng.uniform(0.05, 0.95, m - p - 1))
    knots = np.concatenate([np.zeros(p + 1), interior, np.ones(p + 1)])
    ctrl = rng.uniform(-50, 50, (m, d))
    w = rng.uniform(0.5, 2.0, m) if rational else np.ones(m)
    return Trajectory.from_definition(p, knots, ctrl, w, steps * DT)


def signal_for(path, seed: int = 0) -> np.ndarray:
    n = round(path.duration / DT) + 1
    return np.random.default_rng(seed).standard_normal((n, path.dim))


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def lib():
    with Store() as library:
        library.add_machine(xyz())
        yield library


# ---------------------------------------------------------------------------- round trips
@settings(max_examples=12, deadline=None)
@given(
    seeds=st.lists(st.integers(0, 2**31), min_size=1, max_size=4, unique=True),
    steps=st.integers(8, 120),
    d=st.sampled_from([2, 3]),
    data=st.data(),
)
def test_round_trip_returns_equal_arrays(seeds, steps, d, data):
    # Bit-exact: DuckDB DOUBLE[] and the Arrow buffers carry float64 unchanged, including
    # the largest magnitudes accepted, subnormals and signed zeros.
    machine = xyz() if d == 3 else xy()
    paths = [curve(s, d=d, steps=steps, rational=bool(s % 2)) for s in seeds]
    floats = st.floats(-MAX_ABS_VALUE, MAX_ABS_VALUE, allow_nan=False, width=64)
    us = [data.draw(hnp.arrays(np.float64, (steps + 1, d), elements=floats)) for _ in paths]
    with Store() as lib:
        lib.add_machine(machine)
        ids = lib.add_many(
            [(p, u, f"p{i}", None) for i, (p, u) in enumerate(zip(paths, us, strict=True))],
            machine.name,
        )
        bank = lib.bank(machine.name)
        for i, (pid, p, u) in enumerate(zip(ids, paths, us, strict=True)):
            np.testing.assert_array_equal(lib.signal(pid), u)
            got = lib.get(pid)
            np.testing.assert_array_equal(got.signal, u)
            np.testing.assert_array_equal(got.points, p.sample(DT))
            np.testing.assert_array_equal(got.trajectory.ctrlpts, p.ctrlpts)
            np.testing.assert_array_equal(got.trajectory.weights, p.weights)
            np.testing.assert_array_equal(got.trajectory.knots, p.knots)
            assert got.trajectory.duration == p.duration
            assert bank.ids[i] == pid and bank.names[i] == f"p{i}"
            np.testing.assert_array_equal(bank.signal_of(i), u)
            np.testing.assert_array_equal(bank.points_of(i), p.sample(DT))
            np.testing.assert_array_equal(bank.trajectory(i).sample(DT), p.sample(DT))


def test_file_round_trip_survives_reopening(tmp_path):
    db = tmp_path / "lib.duckdb"
    paths = [curve(s, steps=200 + 40 * s) for s in range(3)]
    us = [signal_for(p, s) for s, p in enumerate(paths)]
    with Store(db) as lib:
        lib.add_machine(xyz())
        ids = lib.add_many(
            [(p, u, f"g{i}", "test") for i, (p, u) in enumerate(zip(paths, us, strict=True))], "xyz"
        )
    with Store(db, read_only=True) as lib:
        assert [p.id for p in lib.primitives()] == ids
        assert lib.machine("xyz") == xyz()
        bank = lib.bank("xyz")
        np.testing.assert_array_equal(bank.n_samples, [201, 241, 281])
        np.testing.assert_array_equal(bank.signals, np.concatenate(us))
        np.testing.assert_array_equal(bank.points, np.concatenate([p.sample(DT) for p in paths]))
        info = lib.info(ids[1])
        assert (info.name, info.source, info.n_samples, info.dim) == ("g1", "test", 241, 3)
        assert info.duration == pytest.approx(1.2, abs=1e-12) and info.dt == DT
        assert info.added.tzinfo is not None


def test_bank_is_per_machine_and_empty_for_a_machine_without_primitives(lib):
    lib.add_machine(xy())
    assert len(lib.bank("xy-pdccilc")) == 0
    assert lib.bank("xy-pdccilc").points.shape == (0, 2)
    a = lib.add(curve(1), signal_for(curve(1)), machine="xyz")
    b = lib.add(curve(2, d=2), signal_for(curve(2, d=2)), machine="xy-pdccilc")
    bank = lib.bank("xyz")
    assert isinstance(bank, Bank) and list(bank.ids) == [a] and bank.dim == 3
    assert list(lib.bank("xy-pdccilc").ids) == [b]
    assert bank.index(a) == 0
    with pytest.raises(KeyError):
        bank.index(b)
    assert [p.id for p in lib.primitives(machine="xy-pdccilc")] == [b]


def test_bank_orders_by_id_after_removals(lib):
    ids = lib.add_many([(curve(s), signal_for(curve(s), s)) for s in range(5)], "xyz")
    lib.remove(ids[2])
    bank = lib.bank("xyz")
    assert list(bank.ids) == [ids[0], ids[1], ids[3], ids[4]]
    np.testing.assert_array_equal(bank.signal_of(2), signal_for(curve(3), 3))
    np.testing.assert_array_equal(np.diff(bank.offsets), [241] * 4)


def test_bank_is_cached_until_the_machine_s_primitives_change(lib):
    a, b = lib.add_many([(curve(s), signal_for(curve(s), s)) for s in range(2)], "xyz")
    bank = lib.bank("xyz")
    assert lib.bank("xyz") is bank
    assert not bank.points.flags.writeable and not bank.signals.flags.writeable
    lib.remove(a)
    c = lib.add(curve(5), signal_for(curve(5), 5), machine="xyz")
    again = lib.bank("xyz")
    assert again is not bank and list(again.ids) == [b, c]
    np.testing.assert_array_equal(again.signal_of(1), signal_for(curve(5), 5))
    lib.remove(c)  # same count as before the add, smaller largest id
    assert list(lib.bank("xyz").ids) == [b]


def test_bank_signals_are_read_on_first_use_and_stay_aligned(tmp_path):
    db = tmp_path / "lib.duckdb"
    lib = Store(db)
    lib.add_machine(xyz())
    a, b, c = lib.add_many([(curve(s), signal_for(curve(s), s)) for s in range(3)], "xyz")
    bank = lib.bank("xyz")
    lib.add(curve(7), signal_for(curve(7), 7), machine="xyz")  # newer rows are ignored
    np.testing.assert_array_equal(
        bank.signals, np.concatenate([signal_for(curve(s), s) for s in range(3)])
    )
    stale = lib.bank("xyz")
    lib.remove(b)
    with pytest.raises(InputError, match=rf"primitive {b} was removed after this bank was read"):
        _ = stale.signals
    late = lib.bank("xyz")
    lib.close()
    with pytest.raises(InputError, match=r"lib.duckdb was closed before this bank's signals"):
        _ = late.signals
    np.testing.assert_array_equal(bank.signal_of(2), signal_for(curve(2), 2))  # kept


@settings(max_examples=10, deadline=None)
@given(ops=st.lists(st.tuples(st.booleans(), st.integers(0, 3)), min_size=1, max_size=8))
def test_bank_matches_the_stored_set_after_any_adds_and_removes(ops):
    # The bank cache keys on (count, largest id); any sequence of adds and removes must
    # give the bank a fresh read would give.
    with Store() as lib:
        lib.add_machine(xyz())
        stored: dict[int, np.ndarray] = {}
        for step, (add, k) in enumerate(ops):
            if add or not stored:
                paths = [curve(step * 4 + j, steps=10) for j in range(k + 1)]
                batch = [(p, signal_for(p, step * 4 + j)) for j, p in enumerate(paths)]
                for pid, (_, u) in zip(lib.add_many(batch, "xyz"), batch, strict=True):
                    stored[pid] = u
            else:
                pid = sorted(stored)[k % len(stored)]
                lib.remove(pid)
                del stored[pid]
            bank = lib.bank("xyz")
            assert list(bank.ids) == sorted(stored)
            for i, pid in enumerate(bank.ids):
                np.testing.assert_array_equal(bank.signal_of(i), stored[int(pid)])


# ---------------------------------------------------------------------------- transactions
def test_add_many_checks_everything_first_so_a_bad_item_writes_nothing(lib):
    good = [(curve(s), signal_for(curve(s)), f"g{s}", None) for s in range(4)]
    bad = list(good)
    bad[2] = (curve(2), signal_for(curve(2))[:-1], "short", None)
    with pytest.raises(
        InputError, match=r"item 2 \('short'\): expected a signal of shape \(241, 3\)"
    ):
        lib.add_many(bad, "xyz")
    assert lib.primitives() == []
    assert lib.add_many(good, "xyz") == [1, 2, 3, 4]  # no id was burnt by the failure


def test_add_many_rolls_back_when_the_insert_itself_fails(lib):
    # A row planted under the id the sequence hands out next makes the one INSERT fail in
    # the middle of the batch; the transaction must leave nothing of it.
    first = lib.add(curve(0), signal_for(curve(0)), machine="xyz")
    lib._con.execute(
        "INSERT INTO primitives SELECT * REPLACE (id + 2 AS id) FROM primitives WHERE id = $i",
        {"i": first},
    )
    before = [p.id for p in lib.primitives()]
    with pytest.raises(duckdb.ConstraintException):
        lib.add_many([(curve(s), signal_for(curve(s))) for s in range(1, 5)], "xyz")
    assert [p.id for p in lib.primitives()] == before
    assert len(lib.bank("xyz")) == 2


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (
            lambda: (curve(0), signal_for(curve(0)), "q"),
            NotFoundError,
            r"unknown machine 'q'; the library has: xyz",
        ),
        (
            lambda: (curve(0, d=2), signal_for(curve(0, d=2)), "xyz"),
            InputError,
            r"expected a 3-D path .* got a 2-D path",
        ),
        (
            lambda: (curve(0), signal_for(curve(0))[:, :2], "xyz"),
            InputError,
            r"expected a signal of shape \(241, 3\).*got \(241, 2\)",
        ),
        (
            lambda: (curve(0), np.full((241, 3), np.nan), "xyz"),
            InputError,
            r"expected a finite signal, got NaN or inf",
        ),
        (
            lambda: (curve(0), np.full((241, 3), np.inf), "xyz"),
            InputError,
            r"expected a finite signal",
        ),
        (
            lambda: (curve(0, steps=1), np.zeros((2, 3)), "xyz"),
            InputError,
            r"at least 8 samples on the grid of machine 'xyz' \(T >= 7 dt = 0.035 s\), got 2",
        ),
        (
            lambda: (
                Trajectory.from_definition(3, [0, 0, 0, 0, 1, 1, 1, 1], np.eye(4, 3), None, 1.2013),
                np.zeros((241, 3)),
                "xyz",
            ),
            InputError,
            r"whole number of steps of machine 'xyz' \(dt = 0.005 s\), got T = 1.2013 s",
        ),
        (
            lambda: (np.zeros((241, 3)), np.zeros((241, 3)), "xyz"),
            InputError,
            r"expected a Trajectory, got ndarray",
        ),
        (lambda: (curve(0), "abc", "xyz"), InputError, r"expected a numeric signal array"),
    ],
)
def test_add_rejects_bad_input_and_writes_nothing(lib, make, error, message):
    path, u, machine = make()
    with pytest.raises(error, match=message):
        lib.add(path, u, machine=machine)
    assert lib.primitives() == []


def test_add_rejects_a_path_fitted_at_another_dt(lib):
    t = np.arange(1201) * 0.001
    path = Trajectory.from_samples(np.column_stack([np.cos(t), np.sin(t), t]), dt=0.001)
    with pytest.raises(
        InputError, match=r"sampled at the dt of machine 'xyz' \(0.005 s\), got dt = 0.001 s"
    ):
        lib.add(path, np.zeros((241, 3)), machine="xyz")


def test_add_rejects_a_name_that_is_not_a_string(lib):
    with pytest.raises(InputError, match=r"primitive: expected name to be a string, got 3"):
        lib.add(curve(0), signal_for(curve(0)), machine="xyz", name=3)


# ---------------------------------------------------------------------------- lookups
def test_get_signal_info_and_remove_report_unknown_ids(lib):
    pid = lib.add(curve(0), signal_for(curve(0)), machine="xyz", name="a")
    for call in (lib.get, lib.signal, lib.info, lib.remove):
        with pytest.raises(
            NotFoundError, match=r"no primitive with id 99 in the in-memory library"
        ):
            call(99)
    with pytest.raises(InputError, match=r"id: expected an integer primitive id, got '1'"):
        lib.get("1")
    lib.remove(pid)
    with pytest.raises(NotFoundError, match=rf"no primitive with id {pid}"):
        lib.get(pid)
    assert lib.add(curve(1), signal_for(curve(1)), machine="xyz") == pid + 1  # never reused


def test_machines_add_replace_and_lookup(lib):
    assert lib.machines() == ["xyz"]
    assert lib.add_machine(xyz()) == "unchanged"
    with pytest.raises(NotFoundError, match=r"unknown machine 'q'; the library has: xyz"):
        lib.machine("q")
    d = xyz().to_dict()
    d["plants"]["x"]["num"] = [1.1]
    with pytest.raises(InputError, match=r"machine 'xyz' is already in the in-memory library"):
        lib.add_machine(d)
    assert lib.add_machine(d, replace=True) == "replaced"
    assert lib.machine("xyz").plants["x"][0].tolist() == [1.1]
    lib.add(curve(0), signal_for(curve(0)), machine="xyz")
    d["dt"] = 0.001
    with pytest.raises(
        InputError, match=r"has 1 primitives stored at dt = 0.005 s .* got dt = 0.001 s"
    ):
        lib.add_machine(d, replace=True)
    assert lib.machine("xyz").dt == DT
    summary = lib.machine_summaries()
    assert [(s["name"], s["primitives"], s["axes"]) for s in summary] == [
        ("xyz", 1, ["x", "y", "z"])
    ]


def test_remove_machine_keeps_primitives_unless_told(lib):
    lib.add_machine(xy())
    pid = lib.add(curve(0), signal_for(curve(0)), machine="xyz")
    with pytest.raises(InputError, match=r"machine 'xyz' has 1 primitives; remove them with it"):
        lib.remove_machine("xyz")
    assert lib.info(pid).machine == "xyz"
    assert lib.remove_machine("xy-pdccilc") == 0
    assert lib.remove_machine("xyz", primitives=True) == 1
    assert lib.machines() == [] and lib.primitives() == []
    with pytest.raises(NotFoundError, match=r"unknown machine 'xyz'; the library has: no machines"):
        lib.remove_machine("xyz")


def test_machine_json_is_validated_by_machine(lib):
    d = xyz().to_dict()
    d["plants"]["x"]["den"] = [1.0, -1.0]  # unstable pole at s = 1
    with pytest.raises(InputError):
        lib.add_machine(d)
    assert lib.machines() == ["xyz"]


def test_read_only_and_closed_libraries_refuse_writes(tmp_path):
    db = tmp_path / "lib.duckdb"
    with Store(db) as lib:
        lib.add_machine(xyz())
    with Store(db, read_only=True) as lib:
        with pytest.raises(InputError, match=r"is open read-only"):
            lib.add(curve(0), signal_for(curve(0)), machine="xyz")
    lib.close()  # twice is harmless
    with pytest.raises(InputError, match=r"lib.duckdb is closed"):
        lib.primitives()
    with pytest.raises(InputError, match=r"in-memory library cannot be read-only"):
        Store(read_only=True)


# ---------------------------------------------------------------------------- schema
def test_a_new_library_records_every_migration_in_order(tmp_path):
    with Store(tmp_path / "lib.duckdb") as lib:
        log = lib.migrations()
        assert lib.schema_version == SCHEMA_VERSION == MIGRATIONS[-1][0]
    assert [v for v, _, _ in log] == [m[0] for m in MIGRATIONS]
    assert [d for _, d, _ in log] == [m[1] for m in MIGRATIONS]
    times = [t for _, _, t in log]
    assert times == sorted(times)


def test_an_older_library_is_migrated_on_open_and_the_step_recorded(tmp_path):
    db = tmp_path / "old.duckdb"
    con = duckdb.connect(str(db))
    assert _schema.migrate(con, 0, MIGRATIONS[:1]) == [1]
    con.execute(
        "INSERT INTO machines VALUES ('m', 'lti', 0.005, ['x','y'], '{}', now()::TIMESTAMP)"
    )
    con.close()
    with Store(db) as lib:
        assert lib.schema_version == SCHEMA_VERSION
        assert [v for v, _, _ in lib.migrations()] == list(range(1, SCHEMA_VERSION + 1))
        assert lib.machines() == ["m"]  # data kept across the upgrade


def test_migrations_apply_in_order_and_a_failing_step_rolls_back_alone(tmp_path):
    con = duckdb.connect(str(tmp_path / "x.duckdb"))
    v = SCHEMA_VERSION
    steps = [
        *MIGRATIONS,
        (v + 1, "add a column", "ALTER TABLE machines ADD COLUMN note VARCHAR"),
        (v + 2, "callable step", lambda c: c.execute("CREATE TABLE extra (x INTEGER)")),
        (v + 3, "broken", "CREATE TABLE extra2 (x INTEGER); SELECT * FROM no_such_table"),
    ]
    with pytest.raises(duckdb.CatalogException):
        _schema.migrate(con, 0, steps)
    versions = [r[0] for r in con.sql("SELECT version FROM migrations ORDER BY 1").fetchall()]
    assert versions == list(range(1, v + 3))
    got = con.sql("SELECT value FROM meta WHERE key = 'schema_version'").fetchall()
    assert got == [(str(v + 2),)]
    tables = {r[0] for r in con.sql("SELECT table_name FROM duckdb_tables()").fetchall()}
    assert "extra" in tables and "extra2" not in tables
    with pytest.raises(ValueError, match=r"numbered 1, 2, \.\.\. in order, got \[1, 3\]"):
        _schema.migrate(con, 0, [MIGRATIONS[0], (3, "gap", "SELECT 1")])
    con.close()


def test_a_library_of_a_newer_schema_is_refused(tmp_path):
    db = tmp_path / "new.duckdb"
    Store(db).close()
    con = duckdb.connect(str(db))
    con.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    con.close()
    with pytest.raises(
        NotALibraryError,
        match=rf"schema version 99, newer than this primlib reads \({SCHEMA_VERSION}\); upgrade",
    ):
        Store(db)


# ---------------------------------------------------------------------------- not a library
def test_files_that_are_not_libraries_are_refused_and_left_alone(tmp_path):
    text = tmp_path / "x.duckdb"
    text.write_text("t,x,y\n0,1,2\n")
    empty = tmp_path / "empty.duckdb"
    empty.write_bytes(b"")
    foreign = tmp_path / "foreign.duckdb"
    con = duckdb.connect(str(foreign))
    con.execute("CREATE TABLE orders (id INTEGER)")
    con.close()
    for f in (text, empty, foreign):
        before = sha(f)
        with pytest.raises(NotALibraryError, match=rf"{f.name} is not a primlib library"):
            Store(f)
        assert sha(f) == before
    con = duckdb.connect(str(foreign), read_only=True)
    assert [r[0] for r in con.sql("SELECT table_name FROM duckdb_tables()").fetchall()] == [
        "orders"
    ]
    con.close()
    with pytest.raises(InputError, match=r"expected a library file, got a directory"):
        Store(tmp_path)
    with pytest.raises(InputError, match=r"missing.duckdb: no such library file"):
        Store(tmp_path / "missing.duckdb", create=False)
    with pytest.raises(InputError, match=r"folder .*nowhere does not exist"):
        Store(tmp_path / "nowhere" / "lib.duckdb")


def test_an_empty_duckdb_database_becomes_a_library(tmp_path):
    db = tmp_path / "blank.duckdb"
    duckdb.connect(str(db)).close()
    with pytest.raises(NotALibraryError, match=r"an empty DuckDB database, opened read-only"):
        Store(db, read_only=True)
    with Store(db) as lib:
        assert lib.schema_version == SCHEMA_VERSION


# ---------------------------------------------------------------------------- busy
HOLDER = textwrap.dedent(
    """
    import sys
    from primlib.store import Store
    lib = Store(sys.argv[1])
    print("open", flush=True)
    sys.stdin.read()
    lib.close()
    """
)


def test_a_second_process_gets_a_busy_error_not_a_traceback(tmp_path):
    db = tmp_path / "lib.duckdb"
    with Store(db) as lib:
        lib.add_machine(xyz())
    root = str(Path(__file__).resolve().parents[1])
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(db)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": root},
    )
    try:
        assert holder.stdout.readline().strip() == "open"
        busy = r"lib.duckdb is busy: another process has it open; try again when it finishes"
        with pytest.raises(LibraryBusyError, match=busy):
            Store(db)
        with pytest.raises(LibraryBusyError, match=busy):
            Store(db, read_only=True)
    finally:
        holder.stdin.close()
        holder.wait(timeout=30)
        holder.stdout.close()
    assert holder.returncode == 0
    with Store(db) as lib:  # free again once the other process is done
        assert lib.machines() == ["xyz"]
