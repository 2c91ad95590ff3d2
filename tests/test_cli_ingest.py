"""``primlib ingest`` (issue 12): duplicates, names, a busy library, --wait, Ctrl-C."""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from primlib.cli import main
from primlib.io import write_path_csv, write_signal_csv
from primlib.store import Store

ROOT = Path(__file__).resolve().parents[1]
XYZ = ROOT / "data" / "machines" / "xyz.json"
DT = 0.005
N = 161


def write_pair(folder: Path, stem: str, k: int = 0) -> Path:
    t = np.arange(N) * DT
    pts = np.column_stack([20 * np.cos(t + k), 20 * np.sin(2 * t + k), 3 * t])
    write_path_csv(folder / f"{stem}.csv", t, pts)
    u = np.random.default_rng(k).standard_normal((N, 3))
    write_signal_csv(folder / f"{stem}.signal.csv", t, u)
    return folder / f"{stem}.csv"


def run(db: Path, *args):
    return CliRunner().invoke(main, ["--db", str(db), *map(str, args)])


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def names(db: Path) -> list[str]:
    with Store(db, read_only=True) as s:
        return [p.name for p in s.primitives()]


@pytest.fixture
def db(tmp_path) -> Path:
    db = tmp_path / "lib.duckdb"
    assert run(db, "machine", "add", XYZ).exit_code == 0
    return db


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(ROOT)}


# ---------------------------------------------------------------------------- duplicates
def test_reingesting_the_same_files_skips_them_and_says_so(tmp_path, db):
    files = [write_pair(tmp_path, f"g{k}", k) for k in range(3)]
    assert run(db, "ingest", *files, "-m", "xyz").exit_code == 0
    before = sha(db)
    res = run(db, "ingest", *files, "-m", "xyz")
    assert res.exit_code == 0, res.output
    assert res.stdout.count("identical to primitive") == 3
    assert "added 0 primitives" in res.stdout and "3 already there, skipped" in res.stdout
    assert names(db) == ["g0", "g1", "g2"]
    assert sha(db) == before


def test_one_file_twice_in_one_batch_is_stored_once(tmp_path, db):
    f = write_pair(tmp_path, "twice", 1)
    res = run(db, "ingest", f, f, "-m", "xyz")
    assert res.exit_code == 0, res.output
    assert f"skipped {f}: identical to primitive 1" in res.stdout
    assert names(db) == ["twice"]


def test_allow_duplicates_keeps_the_copies(tmp_path, db):
    f = write_pair(tmp_path, "keep", 2)
    assert run(db, "ingest", f, "-m", "xyz").exit_code == 0
    res = run(db, "ingest", f, "-m", "xyz", "--allow-duplicates")
    assert res.exit_code == 0 and "added 1 primitive " in res.stdout
    assert names(db) == ["keep", "keep"]


# ---------------------------------------------------------------------------- names
@pytest.mark.parametrize("name", ["", "two\nlines"])
def test_an_empty_or_multi_line_name_is_refused(tmp_path, db, name):
    f = write_pair(tmp_path, "named", 3)
    before = sha(db)
    res = run(db, "ingest", f, "-m", "xyz", "--name", name)
    assert res.exit_code == 2
    assert res.stderr == (
        f"Error: --name: expected the primitive's name to be non-empty printable text on "
        f"one line, got {name!r}\n"
    )
    assert sha(db) == before


# ---------------------------------------------------------------------------- busy, --wait
def _hold(db: Path, seconds: float | None = None) -> subprocess.Popen:
    """A process holding the write lock until stdin closes (or ``seconds`` pass)."""
    code = (
        "import sys, time\nfrom primlib.store import Store\ns = Store(sys.argv[1])\n"
        "print('open', flush=True)\n"
        + ("sys.stdin.read()\n" if seconds is None else f"time.sleep({seconds})\n")
        + "s.close()\n"
    )
    holder = subprocess.Popen(
        [sys.executable, "-c", code, str(db)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    assert holder.stdout.readline().strip() == "open"
    return holder


def _release(holder: subprocess.Popen) -> None:
    holder.stdin.close()
    holder.wait(timeout=30)
    holder.stdout.close()


def test_ingest_against_a_busy_library_says_busy_before_reading_anything(tmp_path, db):
    missing = tmp_path / "no-signal.csv"  # a file ingest would refuse if it read it first
    write_path_csv(missing, np.arange(N) * DT, np.random.default_rng(0).random((N, 3)))
    holder = _hold(db)
    try:
        res = run(db, "ingest", missing, "-m", "xyz")
        assert res.exit_code == 2
        assert res.stderr == (
            f"Error: {db} is busy: another process has it open; try again when it finishes\n"
        )
    finally:
        _release(holder)


def test_ingest_wait_retries_until_the_library_is_free(tmp_path, db):
    f = write_pair(tmp_path, "later", 4)
    holder = _hold(db, seconds=1.5)
    try:
        res = run(db, "ingest", f, "-m", "xyz", "--wait", "60")
        assert res.exit_code == 0, res.output
    finally:
        _release(holder)
    assert names(db) == ["later"]


def test_ingest_wait_gives_up_after_its_time(tmp_path, db):
    f = write_pair(tmp_path, "never", 5)
    holder = _hold(db)
    try:
        t0 = time.monotonic()
        res = run(db, "ingest", f, "-m", "xyz", "--wait", "0.5")
        assert res.exit_code == 2 and "is busy" in res.stderr and "waited 0.5 s" in res.stderr
        assert time.monotonic() - t0 < 30
    finally:
        _release(holder)


# ---------------------------------------------------------------------------- Ctrl-C
@pytest.fixture(scope="module")
def many(tmp_path_factory) -> list[Path]:
    """Enough path files that the commit takes a noticeable time."""
    folder = tmp_path_factory.mktemp("many")
    rng = np.random.default_rng(7)
    t = np.arange(4001) * DT
    files = []
    for k in range(30):
        pts = np.column_stack([20 * np.cos(t / 7 + k), 20 * np.sin(t / 5 + k), t])
        write_path_csv(folder / f"p{k:03d}.csv", t, pts)
        write_signal_csv(folder / f"p{k:03d}.signal.csv", t, rng.standard_normal((t.size, 3)))
        files.append(folder / f"p{k:03d}.csv")
    return files


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.5, 1.0, 2.0])
def test_ctrl_c_during_ingest_leaves_nothing_or_everything_and_says_which(
    tmp_path, db, many, delay
):
    cmd = [sys.executable, "-m", "primlib", "--db", str(db), "ingest", *map(str, many), "-m", "xyz"]
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=_env(),
        # as from a terminal: a test run in the background inherits SIGINT ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    # the command has started once it reports reading (Ctrl-C while Python itself starts
    # up is the interpreter's business, not primlib's)
    first = proc.stderr.readline()
    assert first.startswith(f"reading {len(many)} paths"), first
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    err = first + err
    assert "Traceback" not in err and "Aborted!" not in err, err
    stored = len(names(db))
    if delay == 0.0:  # still reading 30 files: nothing can have been written
        assert proc.returncode == 130, (out, err)
    if proc.returncode == 130:
        assert stored == 0
        assert f"Interrupted: nothing was added to {db}" in err
        assert "added" not in out
    else:
        # 0: the write finished and said so; -SIGINT: on a fast machine the interrupt came
        # after the command had finished and reported (the interpreter then dies of it)
        assert proc.returncode in (0, -signal.SIGINT), (out, err)
        assert stored == len(many)
        assert f"added {len(many)} primitives" in out
