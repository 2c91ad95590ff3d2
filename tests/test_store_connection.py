"""Opening a library (issue 12): read-only and damaged files are named as what they are."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from primlib import InputError, NotALibraryError
from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import Store

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    db = tmp_path_factory.mktemp("conn") / "lib.duckdb"
    with Store(db) as s:
        s.add_machine(Machine.from_json(DATA / "xyz.json"))
        rng = np.random.default_rng(0)
        items = []
        for _ in range(40):
            pts = np.cumsum(rng.standard_normal((400, 3)), axis=0)
            items.append((Trajectory.from_samples(pts, DT), rng.standard_normal((400, 3))))
        s.add_many(items, "xyz")
    return db


@pytest.fixture
def db(tmp_path, template) -> Path:
    db = tmp_path / "lib.duckdb"
    shutil.copyfile(template, db)
    return db


@pytest.fixture
def unwritable(db):
    """The library file made immutable (root) or read-only (other users)."""
    if os.geteuid() == 0:
        if shutil.which("chattr") is None:
            pytest.skip("chattr is not available to make the file immutable")
        done = subprocess.run(["chattr", "+i", str(db)], capture_output=True)
        if done.returncode != 0:
            pytest.skip(f"cannot make the file immutable here: {done.stderr.decode().strip()}")
        yield db
        subprocess.run(["chattr", "-i", str(db)], check=True)
    else:
        db.chmod(0o444)
        yield db
        db.chmod(0o644)


def test_an_unwritable_library_is_reported_read_only_not_as_foreign(unwritable):
    before = sha(unwritable)
    with pytest.raises(InputError, match=r"is read-only \(the file, its folder or its filesystem"):
        Store(unwritable)
    with Store(unwritable, read_only=True) as s:  # reading still works
        assert len(s.primitives("xyz")) == 40
    assert sha(unwritable) == before


def test_a_library_in_a_read_only_folder_is_reported_read_only(db):
    if os.geteuid() == 0:
        pytest.skip("root writes into a folder without write permission")
    db.parent.chmod(0o555)
    try:
        with pytest.raises(InputError, match="is read-only"):
            Store(db)
    finally:
        db.parent.chmod(0o755)


@pytest.mark.parametrize("keep", [0.5, 0.1])
def test_a_truncated_library_is_reported_damaged(db, keep):
    with open(db, "r+b") as fh:
        fh.truncate(int(os.path.getsize(db) * keep))
    before = sha(db)
    # DuckDB reads blocks lazily: the damage shows at the open or at the first read of a
    # lost block; either way it is named
    with pytest.raises(NotALibraryError, match="is damaged: DuckDB cannot read it") as exc:
        with Store(db, read_only=True) as s:
            assert s.bank("xyz").signals.size
    assert "not a primlib library" not in str(exc.value)
    assert sha(db) == before


def test_an_overwritten_library_is_reported_damaged(db):
    with open(db, "r+b") as fh:
        fh.seek(3 * 4096)
        fh.write(np.random.default_rng(1).bytes(20000))
    with pytest.raises(NotALibraryError, match="is damaged"):
        with Store(db, read_only=True) as s:
            s.bank("xyz")
