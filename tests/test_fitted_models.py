"""The models a warm start fits, kept in the library file and read back by the next process:
the same warm start to the bit, refitted when the primitives or the code change, never a
stale or unreadable row used, and the commands that read with the file open read-only keep
what they fitted with one short write."""

from __future__ import annotations

import io

import duckdb
import numpy as np
import pytest
from click.testing import CliRunner
from stage_helpers import STAGE, add_loop, loop, nominal

import primlib.pipeline._fitted as fitted_mod
import primlib.pipeline._starter as starter_mod
from primlib import LibraryBusyError
from primlib.cli import main
from primlib.greybox import GreyBox
from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.pipeline._fitted import bank_signature, decode, encode
from primlib.store._fitted import fitted_rows, keep_fitted

ORIGINS = [(40.0, 25.0), (75.0, 10.0), (10.0, 60.0), (30.0, 40.0)]
# short loops: each fit of the three models takes ~2 s here (1,001 samples: ~9 s)
SHAPES = [
    (401, 12.0, 1.0, 0.3),
    (401, 8.0, 1.5, 1.7),
    (401, 15.0, 0.75, 2.9),
    (301, 10.0, 1.0, 1.0),
]


def _add(lib, k: int) -> None:
    n, size, turns, phase = SHAPES[k]
    add_loop(lib, loop(n, size, turns, phase), ORIGINS[k], f"loop-{k}")


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """Three primitives learned on the example stage (friction, ripple), no models kept."""
    db = tmp_path_factory.mktemp("fitted") / "lib.duckdb"
    with Library(db) as lib:
        lib.add_machine(nominal())
        for k in range(3):
            _add(lib, k)
    return db.read_bytes()


@pytest.fixture
def db(source, tmp_path):
    path = tmp_path / "lib.duckdb"
    path.write_bytes(source)
    return path


@pytest.fixture(scope="module")
def kept_source(source, new_path, tmp_path_factory):
    """The same library with the models kept by one warm start of ``new_path``, and that
    warm start (fitted afresh)."""
    path = tmp_path_factory.mktemp("kept") / "lib.duckdb"
    path.write_bytes(source)
    ws, kept, rows = _warm(path, new_path, read_only=False)
    return path.read_bytes(), ws, kept.fitted, rows


@pytest.fixture
def kept_db(kept_source, tmp_path):
    path = tmp_path / "kept.duckdb"
    path.write_bytes(kept_source[0])
    return path


@pytest.fixture(scope="module")
def new_path():
    """A path of the stage's that none of the primitives is (rotated and moved)."""
    pts = loop(601, 9.0, 1.2, 0.8)
    a = np.deg2rad(30.0)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    new = (pts - pts[0]) @ R.T + np.array([60.0, 30.0])
    return Trajectory.from_samples(new, STAGE.dt), new[0]


def _warm(db, path, read_only):
    traj, origin = path
    with Library(db, read_only=read_only) as lib:
        ws = lib.warm_start(traj, "stage", origin=origin)
        return ws, lib.starter.kept, fitted_rows(lib, "stage")


def test_a_kept_model_gives_the_fresh_fit_s_warm_start_to_the_bit(kept_source, kept_db, new_path):
    _, fresh, fitted, rows = kept_source
    # the nominal grey-box, the refined model, the grey-box beside it: each fitted once, kept
    assert fitted == 3
    assert sorted(r[1] for r in rows) == ["greybox", "greybox", "refined"]
    again, kept, _ = _warm(kept_db, new_path, read_only=True)
    assert (kept.fitted, kept.read) == (0, 3) and not kept.pending
    assert np.array_equal(again.u, fresh.u) and np.array_equal(again.model_u, fresh.model_u)
    assert again.sources == fresh.sources and again.predicted == fresh.predicted


def test_a_new_primitive_refits_and_drops_the_old_set_s_rows(kept_source, kept_db, new_path):
    db, before = kept_db, kept_source[3]
    with Library(db) as lib:
        _add(lib, 3)
        ids = [int(i) for i in lib.bank("stage").ids]
    _, kept, after = _warm(db, new_path, read_only=False)
    assert kept.fitted == 3  # four primitives: fitted anew
    assert len(after) == 3 and not {r[2] for r in after} & {r[2] for r in before}
    with duckdb.connect(str(db), read_only=True) as con:
        banks = {b for (b,) in con.sql("SELECT bank FROM fitted_models").fetchall()}
    assert banks == {bank_signature(ids)}


def test_another_primlib_s_rows_are_not_read_and_are_dropped(kept_db, monkeypatch):
    with Library(kept_db) as lib:
        m = lib.machine("stage")
        ids = [int(i) for i in lib.bank("stage").ids]
        key = fitted_mod.fit_key("greybox", m, ids, linear=True)
        monkeypatch.setattr(fitted_mod, "code_version", lambda: "another-primlib")
        assert fitted_mod.fit_key("greybox", m, ids, linear=True) != key
        # a row kept by this primlib drops the other primlib's, of the same primitives
        keep_fitted(lib, "stage", bank_signature(ids), "another-primlib", [("k", "greybox", b"x")])
        assert [r[2] for r in fitted_rows(lib)] == ["k"]


def test_an_unreadable_row_is_fitted_again_and_replaced(kept_source, kept_db, new_path):
    db, fresh = kept_db, kept_source[1]
    with duckdb.connect(str(db)) as con:
        con.execute("UPDATE fitted_models SET payload = 'not a model'::BLOB WHERE kind = 'refined'")
    ws, kept, _ = _warm(db, new_path, read_only=False)
    assert (kept.fitted, kept.read) == (1, 2)
    assert np.array_equal(ws.u, fresh.u)
    _, kept2, _ = _warm(db, new_path, read_only=True)
    assert (kept2.fitted, kept2.read) == (0, 3)


def test_the_codec_round_trips_and_refuses_pickles(kept_db):
    with Library(kept_db, read_only=True) as lib:
        model, gb, note = lib.starter.fit_models("stage")
    assert "refined" in note
    for obj in (model, gb):
        back = decode(encode(obj))
        assert type(back) is type(obj)
        assert back.machine.to_dict() == obj.machine.to_dict()
        for name, v in vars(obj).items():
            w = getattr(back, name)
            if isinstance(v, np.ndarray):
                assert w.dtype == v.dtype and np.array_equal(w, v, equal_nan=True), name
            elif name != "machine":
                assert w == v, name
    assert isinstance(gb, GreyBox)
    buf = io.BytesIO()
    np.savez(buf, __header__=np.array([{"type": "GreyBox"}], dtype=object))
    with pytest.raises(ValueError, match="not a fitted model"):
        decode(buf.getvalue())
    with pytest.raises(ValueError, match="not a fitted model"):
        decode(b"\x00" * 40)


def test_removing_the_machine_removes_its_models(kept_db):
    with Library(kept_db) as lib:
        assert len(fitted_rows(lib)) == 3
        lib.remove_machine("stage", primitives=True)
        assert fitted_rows(lib) == []


def test_a_duplicate_key_from_a_concurrent_keeper_is_a_busy_library(kept_db, monkeypatch):
    # two server readers keeping one model at once: besides the conflict at commit, DuckDB
    # can refuse the insert itself with a duplicate key (1 in ~300 in a two-thread stress of
    # keep_fitted, scratch, stop 46), which reached a client as an internal error
    with Library(kept_db) as lib:
        before = fitted_rows(lib)
        con = lib._writable()

        class Refusing:  # the connection, whose inserts meet the other keeper's row
            def execute(self, sql, *args):
                if sql.startswith("INSERT"):
                    raise duckdb.ConstraintException('Duplicate key "key: k" violates primary key')
                return con.execute(sql, *args)

            def __getattr__(self, name):
                return getattr(con, name)

        monkeypatch.setattr(lib, "_writable", lambda: Refusing())
        with pytest.raises(LibraryBusyError, match="not kept"):
            keep_fitted(lib, "stage", "other", "code", [("k", "greybox", b"x")])
        monkeypatch.undo()
        assert fitted_rows(lib) == before  # the delete of the old rows rolled back too


# ---------------------------------------------------------------------------- the commands
def _csv(tmp_path, path) -> str:
    traj, _ = path
    pts = traj.sample(STAGE.dt)
    t = np.arange(len(pts)) * STAGE.dt
    f = tmp_path / "new.csv"
    np.savetxt(f, np.column_stack([t, pts]), delimiter=",", header="t,x,y", comments="")
    return str(f)


def _match(db, csv, out):
    return CliRunner().invoke(
        main, ["--db", str(db), "match", csv, "--machine", "stage", "--out", str(out)]
    )


def test_match_keeps_what_it_fitted_and_the_next_one_reads_it(db, new_path, tmp_path, monkeypatch):
    csv = _csv(tmp_path, new_path)
    first = _match(db, csv, tmp_path / "u1.csv")
    assert first.exit_code == 0, first.output
    assert "kept the 3 model(s)" in first.stderr
    # the next process fits nothing: a fit would raise
    monkeypatch.setattr(starter_mod, "fit_greybox", _no_fit)
    monkeypatch.setattr(starter_mod, "refine_machine", _no_fit)
    second = _match(db, csv, tmp_path / "u2.csv")
    assert second.exit_code == 0, second.output
    assert "kept" not in second.stderr
    assert (tmp_path / "u1.csv").read_bytes() == (tmp_path / "u2.csv").read_bytes()


def _no_fit(*args, **kw):
    raise AssertionError("fitted again")


def test_match_says_when_it_could_not_keep_them(db, new_path, tmp_path, monkeypatch):
    import primlib.cli._machine_fit as cli_fit

    def busy(*args, **kw):
        raise LibraryBusyError(f"{db} is in use by another process")

    monkeypatch.setattr(cli_fit, "_open_waiting", busy)
    res = _match(db, _csv(tmp_path, new_path), tmp_path / "u.csv")
    assert res.exit_code == 0 and (tmp_path / "u.csv").is_file()
    assert "were not kept" in res.stderr and "in use by another process" in res.stderr
    with duckdb.connect(str(db), read_only=True) as con:
        assert con.sql("SELECT count(*) FROM fitted_models").fetchall() == [(0,)]


def test_machine_fit_fits_once_then_reads(db):  # ~2 s
    run = CliRunner().invoke(main, ["--db", str(db), "machine", "fit", "stage"])
    assert run.exit_code == 0, run.output
    assert "3 model(s) fitted and kept" in run.output and "refined" in run.output
    again = CliRunner().invoke(main, ["--db", str(db), "machine", "fit", "stage", "--json"])
    assert again.exit_code == 0, again.output
    assert '"fitted": 0' in again.output and '"read": 3' in again.output


def test_machine_fit_refuses_an_unknown_or_empty_machine(db):
    before = db.read_bytes()
    res = CliRunner().invoke(main, ["--db", str(db), "machine", "fit", "nope"])
    assert res.exit_code == 2 and "nope" in res.stderr
    assert db.read_bytes() == before
    with Library(db) as lib:
        lib.add_machine({**nominal().to_dict(), "name": "empty"})
    res = CliRunner().invoke(main, ["--db", str(db), "machine", "fit", "empty"])
    assert res.exit_code == 2 and "no stored primitives" in res.stderr


def test_a_version_6_library_is_migrated_by_a_writer_and_then_keeps_models(db):
    con = duckdb.connect(str(db))
    con.execute("DROP TABLE fitted_models")
    con.execute("DELETE FROM migrations WHERE version > 6")
    con.execute("UPDATE meta SET value = '6' WHERE key = 'schema_version'")
    con.close()
    before = db.read_bytes()
    res = CliRunner().invoke(main, ["--db", str(db), "list"])  # reads with the file read-only
    assert res.exit_code != 0 and "schema version 6, older" in res.stderr
    assert db.read_bytes() == before
    run = CliRunner().invoke(main, ["--db", str(db), "machine", "fit", "stage"])
    assert run.exit_code == 0, run.output
    with Library(db, read_only=True) as lib:
        assert lib.schema_version == 7 and len(lib.primitives("stage")) == 3
        assert len(fitted_rows(lib, "stage")) == 3
