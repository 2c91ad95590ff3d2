"""Opening a library file: the DuckDB connection, its lock, the schema check, transactions.

DuckDB lets one process open a file for writing (several may read it when none writes); a
second process gets :class:`primlib.LibraryBusyError`. What cannot be opened is reported as
what it is: a folder or missing file (:class:`primlib.InputError`), a file this user or its
filesystem does not let us write (read-only), a file that is not a DuckDB database or not
primlib's (:class:`primlib.NotALibraryError`), a DuckDB file DuckDB cannot read (damaged).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import duckdb

from primlib._errors import InputError, LibraryBusyError, NotALibraryError, PrimlibError
from primlib.store._schema import APPLICATION, SCHEMA_VERSION, migrate

__all__ = ["connect", "check_schema", "transaction", "reading", "WriteCancelled"]

# Never reach for the network: a SQLite or Parquet file handed to us must fail, not trigger an
# extension download.
_CONFIG = {"autoinstall_known_extensions": False, "autoload_known_extensions": False}


class WriteCancelled(KeyboardInterrupt):
    """A write was cancelled before its commit (an interrupt): it was rolled back whole."""


def _is_duckdb_file(path: Path) -> bool:
    # A DuckDB file carries the magic bytes "DUCK" at offset 8 of its first block.
    with open(path, "rb") as fh:
        head = fh.read(12)
    return len(head) == 12 and head[8:12] == b"DUCK"


def _check_file(name: str, read_only: bool, create: bool) -> None:
    """Refuse, before DuckDB sees it, what the filesystem alone says cannot be opened."""
    p = Path(name)
    if p.is_dir():
        raise InputError(f"{name}: expected a library file, got a directory")
    if p.exists():
        try:
            is_duckdb = _is_duckdb_file(p)
        except OSError as exc:
            raise InputError(f"{name}: cannot read the library file ({exc.strerror})") from None
        if not is_duckdb:
            raise NotALibraryError(
                f"{name} is not a primlib library (it is not a DuckDB database file)"
            )
        folder = p.parent if str(p.parent) else Path(".")
        # A writer needs the file and its folder (DuckDB's write-ahead log lives beside it).
        # os.access also answers False for a read-only filesystem and an immutable file.
        if not read_only and not (os.access(p, os.W_OK) and os.access(folder, os.W_OK)):
            raise InputError(
                f"{name} is read-only (the file, its folder or its filesystem cannot be "
                "written); it can be read but not changed"
            )
    elif read_only or not create:
        raise InputError(f"{name}: no such library file (add a machine to create one)")
    elif not p.parent.is_dir() and str(p.parent):
        raise InputError(f"{name}: cannot create the library, folder {p.parent} does not exist")


def _open_error(name: str, exc: duckdb.Error) -> PrimlibError:
    """The primlib error for a DuckDB error raised while opening an existing DuckDB file."""
    msg = str(exc)
    if isinstance(exc, duckdb.ConnectionException):
        return LibraryBusyError(
            f"{name} is already open in this process in the other mode "
            "(read-only or read-write); close it first"
        )
    # DuckDB reports a lock held by another process as a plain IOException; its text is the
    # only thing that tells it from a failed read.
    if isinstance(exc, duckdb.IOException) and "lock" in msg.lower():
        return LibraryBusyError(
            f"{name} is busy: another process has it open; try again when it finishes"
        )
    # The file passed the magic-byte check: it is a DuckDB file that DuckDB cannot read
    # (truncated, overwritten, a failed checksum).
    return _damaged(name, exc)


def _damaged(name: str, exc: duckdb.Error) -> NotALibraryError:
    msg = str(exc)
    first = msg.splitlines()[0] if msg else type(exc).__name__
    return NotALibraryError(f"{name} is damaged: DuckDB cannot read it ({first})")


@contextmanager
def reading(name: str) -> Iterator[None]:
    """Report a read that fails on the file's own bytes as a damaged library.

    DuckDB reads blocks lazily, so a truncated or overwritten file can open and fail only
    when the damaged block is read: an ``IOException`` (a short read) or, for a failed
    block checksum, a bare ``duckdb.Error`` (no subclass says "corrupt").
    """
    try:
        yield
    except duckdb.IOException as exc:
        raise _damaged(name, exc) from None
    except duckdb.Error as exc:
        if type(exc) is duckdb.Error:
            raise _damaged(name, exc) from None
        raise


def connect(path: str | None, read_only: bool, create: bool) -> duckdb.DuckDBPyConnection:
    """A DuckDB connection to the library file (in memory for None), checks done first.

    Raises
    ------
    InputError
        A folder, a missing file (without ``create``), a read-only file opened for writing.
    NotALibraryError
        Not a DuckDB file, or a damaged one.
    LibraryBusyError
        Another process holds the lock, or this one has the file open in the other mode.
    """
    if path is None:
        if read_only:
            raise InputError("read_only: an in-memory library cannot be read-only")
        return duckdb.connect(":memory:", config=_CONFIG)
    _check_file(path, read_only, create)
    try:
        con = duckdb.connect(path, read_only=read_only, config=_CONFIG)
    except duckdb.Error as exc:
        raise _open_error(path, exc) from None
    if not read_only:
        # Points and signals are full-precision doubles: DuckDB's compression (ALP-RD)
        # saved about 10 % of the file here but made each checkpoint (the commit of a
        # big batch, the close after an add) about 20 % slower.
        con.execute("SET force_compression = 'uncompressed'")
    return con


def _objects(con: duckdb.DuckDBPyConnection) -> set[str]:
    rows = con.sql(
        "SELECT table_name FROM duckdb_tables() WHERE database_name = current_database() "
        "UNION ALL SELECT view_name FROM duckdb_views() "
        "WHERE database_name = current_database() AND NOT internal "
        "UNION ALL SELECT sequence_name FROM duckdb_sequences() "
        "WHERE database_name = current_database()"
    ).fetchall()
    return {row[0] for row in rows}


def _schema_version(con: duckdb.DuckDBPyConnection, name: str) -> int:
    try:
        with reading(name):
            rows = con.sql("SELECT key, value FROM meta").fetchall()
    except duckdb.Error:  # a meta table of other columns
        rows = None
    try:
        meta = dict(rows)
        version = int(meta.get("schema_version", ""))
    except (ValueError, TypeError):
        raise NotALibraryError(
            f"{name} is not a primlib library (its meta table is not primlib's)"
        ) from None
    if meta.get("application") != APPLICATION:
        raise NotALibraryError(
            f"{name} is not a primlib library (its meta table names no primlib application)"
        )
    return version


def check_schema(con: duckdb.DuckDBPyConnection, name: str, read_only: bool) -> None:
    """Make sure the file is a primlib library this primlib reads; create or upgrade it.

    An empty database becomes a library; an older schema is migrated (a writer only).

    Raises
    ------
    NotALibraryError
        Foreign tables, a foreign ``meta`` table, a newer schema, an empty or older file
        opened read-only, or a file DuckDB fails to read (damaged).
    """
    with reading(name):
        objects = _objects(con)
    if not objects:
        if read_only:
            raise NotALibraryError(
                f"{name} is not a primlib library (an empty DuckDB database, opened read-only)"
            )
        migrate(con, 0)
        return
    if "meta" not in objects:
        raise NotALibraryError(
            f"{name} is not a primlib library (a DuckDB database without primlib's meta table)"
        )
    version = _schema_version(con, name)
    if version > SCHEMA_VERSION:
        raise NotALibraryError(
            f"{name} is a primlib library of schema version {version}, newer than this "
            f"primlib reads ({SCHEMA_VERSION}); upgrade primlib"
        )
    if version < SCHEMA_VERSION:
        if read_only:
            raise NotALibraryError(
                f"{name} is a primlib library of schema version {version}, older than "
                f"this primlib reads ({SCHEMA_VERSION}); open it for writing once to upgrade it"
            )
        migrate(con, version)


@contextmanager
def transaction(
    con: duckdb.DuckDBPyConnection, cancelled: Callable[[], bool] | None = None
) -> Iterator[duckdb.DuckDBPyConnection]:
    """One transaction: committed when the block ends, rolled back on any exception.

    Parameters
    ----------
    con : duckdb connection
    cancelled : callable, optional
        Asked once, just before the commit; True rolls everything back and raises
        :class:`WriteCancelled` (how an interrupt deferred by the caller cancels a write
        that has not committed yet).
    """
    con.begin()
    try:
        yield con
        if cancelled is not None and cancelled():
            raise WriteCancelled("the write was cancelled before its commit; nothing was written")
    except BaseException:
        con.rollback()
        raise
    try:
        con.commit()
    except BaseException:
        # a failed commit (disk full, I/O) must not leave the connection mid-transaction
        try:
            con.rollback()
        except duckdb.Error:
            pass
        raise
