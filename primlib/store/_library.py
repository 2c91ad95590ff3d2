"""The library: one DuckDB file of machines and the primitives learned on them.

Writes are transactions that check everything before the first insert, so bad input never
leaves half a batch behind. Arrays travel as Arrow buffers both ways: a batch is inserted as
one Arrow table whose list columns wrap the flat numpy buffers (no per-row Python work), and
a machine's whole bank comes back from one columnar query as flat numpy arrays plus offsets.
DuckDB lets one process open a file for writing; a second process gets
:class:`primlib.LibraryBusyError`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from datetime import UTC
from pathlib import Path
from typing import Any

import duckdb
import numpy as np
import pyarrow as pa

from primlib._errors import (
    InputError,
    LibraryBusyError,
    NotALibraryError,
    NotFoundError,
    PrimlibError,
)
from primlib.io._csv import MIN_ROWS
from primlib.store._schema import APPLICATION, SCHEMA_VERSION, migrate, utcnow
from primlib.store._types import Bank, Primitive, PrimitiveInfo

__all__ = ["Library"]

# Never reach for the network: a SQLite or Parquet file handed to us must fail, not trigger an
# extension download.
_CONFIG = {"autoinstall_known_extensions": False, "autoload_known_extensions": False}

# A path's duration must be a whole number of machine steps within this fraction of a step.
_STEP_RTOL = 1e-6
# A path that carries its own sample time must agree with the machine's to this relative.
_DT_RTOL = 1e-9
# A batch with at least this many bytes of points and signals is written straight into the
# file at commit (a checkpoint) instead of through the write-ahead log (DuckDB's default
# checkpoint threshold is 16 MiB).
_DIRECT_BYTES = 16 * 2**20

_INFO_COLUMNS = "id, name, machine, duration, dt, n_samples, dim, source, added"
_INSERT_COLUMNS = [
    "id",
    "machine",
    "name",
    "source",
    "added",
    "duration",
    "dt",
    "dim",
    "n_samples",
    "degree",
    "knots",
    "ctrlpts",
    "weights",
    "points",
    "signal",
]


def _list_array(flat: np.ndarray, offsets: np.ndarray) -> pa.Array:
    """A list column over a flat float64 buffer and offsets, without copying the values.

    32-bit offsets while they fit (DuckDB reads a ``ListArray`` a little faster than a
    ``LargeListArray``), 64-bit beyond 2**31 values.
    """
    if offsets[-1] < 2**31:
        return pa.ListArray.from_arrays(pa.array(offsets.astype(np.int32)), pa.array(flat))
    return pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(flat))


def _sample_points(
    checked: list[dict[str, Any]], dt: float, d: int, offsets: np.ndarray
) -> np.ndarray:
    """Every checked item's path on the machine grid, as one flat buffer (offsets in values).

    Trajectories go through :func:`primlib.nurbs.sample_many` (one sparse basis product per
    group of curves sharing degree, knots and sample count); other path objects through
    their own ``sample``.
    """
    from primlib.nurbs import Trajectory, sample_many

    native = [i for i, c in enumerate(checked) if isinstance(c["path"], Trajectory)]
    if len(native) == len(checked):
        out = sample_many([c["path"] for c in checked], dt)[0].reshape(-1)
    else:
        out = np.empty(int(offsets[-1]))
        if native:
            pts, _ = sample_many([checked[i]["path"] for i in native], dt)
            rows = np.array([checked[i]["n"] for i in native], dtype=np.int64)
            start = 0
            for i, r in zip(native, rows, strict=True):
                out[offsets[i] : offsets[i + 1]] = pts[start : start + r].ravel()
                start += r
        for i in sorted(set(range(len(checked))) - set(native)):
            c = checked[i]
            n = c["n"]
            points = np.asarray(c["path"].sample(dt), dtype=np.float64)
            if points.shape != (n, d):
                raise InputError(
                    f"{c['label']}: expected the path to sample to ({n}, {d}) finite points "
                    f"at dt = {dt:g} s, got {points.shape}"
                )
            out[offsets[i] : offsets[i + 1]] = points.ravel()
    if not np.isfinite(out).all():
        bad = int(np.searchsorted(offsets, np.flatnonzero(~np.isfinite(out))[0], side="right"))
        c = checked[bad - 1]
        raise InputError(
            f"{c['label']}: expected the path to sample to ({c['n']}, {d}) finite points at "
            f"dt = {dt:g} s, got NaN or inf"
        )
    return out


def _flat(column: pa.ChunkedArray) -> np.ndarray:
    """The values of a list column, concatenated, as float64 numpy.

    Zero copy for one chunk (what DuckDB returns up to a million rows): ``flatten`` slices
    the values buffer by the first and last offset and numpy wraps that slice. Several
    chunks cost one concatenation.
    """
    values = [chunk.flatten() for chunk in column.chunks if len(chunk)]
    parts = [v.to_numpy(zero_copy_only=v.null_count == 0) for v in values]
    if not parts:
        return np.zeros(0)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _is_duckdb_file(path: Path) -> bool:
    # A DuckDB file carries the magic bytes "DUCK" at offset 8 of its first block.
    with open(path, "rb") as fh:
        head = fh.read(12)
    return len(head) == 12 and head[8:12] == b"DUCK"


def _check_id(id: Any) -> int:
    if isinstance(id, bool) or not isinstance(id, (int, np.integer)):
        raise InputError(f"id: expected an integer primitive id, got {id!r}")
    return int(id)


class Library:
    """A library of motion primitives: NURBS paths with the ILC inputs learned for them.

    One DuckDB file holds the machines (sample time, axes, model) and, per machine, the
    primitives: the path's NURBS definition, and the path and its converged input sampled on
    the machine's grid t = 0, dt, ..., T (n = round(T / dt) + 1 samples).

    Parameters
    ----------
    path : str or path-like, optional
        The library file. None (the default) gives an in-memory library.
    read_only : bool, default False
        Open without write access; several processes may read one file at once, but none
        while another writes.
    create : bool, default True
        Create the file when it does not exist (otherwise that is an InputError).

    Raises
    ------
    NotALibraryError
        If the file is not a DuckDB database, a DuckDB database without primlib's ``meta``
        table (primlib never creates tables beside foreign ones), or a library of a newer
        schema than this primlib reads.
    LibraryBusyError
        If another process has the file open for writing (or this process has it open in
        the other mode).
    InputError
        If the path is a directory, its folder does not exist, or the file does not exist
        and ``create`` is False.

    Notes
    -----
    A writable Library holds DuckDB's file lock until :meth:`close` (or the end of a
    ``with`` block): other processes cannot open the file meanwhile.

    Examples
    --------
    >>> import tempfile, os
    >>> import primlib as pl
    >>> folder = tempfile.mkdtemp()
    >>> p = pl.Trajectory.from_csv("data/library/circle.csv")
    >>> t, u = pl.io.read_signal_csv("data/library/circle.signal.csv")
    >>> with pl.Library(os.path.join(folder, "lib.duckdb")) as lib:
    ...     _ = lib.add_machine(pl.Machine.from_json("data/machines/xyz.json"))
    ...     pid = lib.add(p, u, machine="xyz", name="circle")
    >>> with pl.Library(os.path.join(folder, "lib.duckdb"), read_only=True) as lib:
    ...     [r.name for r in lib.primitives(machine="xyz")]
    ['circle']
    """

    def __init__(
        self, path: str | os.PathLike | None = None, *, read_only: bool = False, create: bool = True
    ) -> None:
        self._path = None if path is None else os.fspath(path)
        self._read_only = bool(read_only)
        self._machines_cache: dict[str, Any] = {}
        self._bank_cache: dict[str, tuple[tuple, Bank]] = {}
        self._con: Any = None
        self._con = self._connect(create)
        try:
            self._open_schema()
        except BaseException:
            self._con.close()
            self._con = None
            raise

    # ------------------------------------------------------------------ opening
    @property
    def path(self) -> str | None:
        """The library file, or None for an in-memory library."""
        return self._path

    @property
    def read_only(self) -> bool:
        return self._read_only

    @property
    def _label(self) -> str:
        return self._path if self._path is not None else "the in-memory library"

    def _connect(self, create: bool) -> Any:
        if self._path is None:
            if self._read_only:
                raise InputError("read_only: an in-memory library cannot be read-only")
            return duckdb.connect(":memory:", config=_CONFIG)
        name = self._path
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
        elif self._read_only or not create:
            raise InputError(f"{name}: no such library file (add a machine to create one)")
        elif not p.parent.is_dir() and str(p.parent):
            raise InputError(f"{name}: cannot create the library, folder {p.parent} does not exist")
        try:
            con = duckdb.connect(name, read_only=self._read_only, config=_CONFIG)
        except duckdb.Error as exc:
            raise self._open_error(exc) from None
        if not self._read_only:
            # Points and signals are full-precision doubles: DuckDB's compression (ALP-RD)
            # saved about 10 % of the file here but made each checkpoint (the commit of a
            # big batch, the close after an add) about 20 % slower.
            con.execute("SET force_compression = 'uncompressed'")
        return con

    def _open_error(self, exc: Exception) -> PrimlibError:
        name = self._path
        msg = str(exc)
        if "could not set lock" in msg.lower() or "conflicting lock" in msg.lower():
            return LibraryBusyError(
                f"{name} is busy: another process has it open; try again when it finishes"
            )
        if isinstance(exc, duckdb.ConnectionException) and "configuration" in msg:
            return LibraryBusyError(
                f"{name} is already open in this process in the other mode "
                "(read-only or read-write); close it first"
            )
        if "Permission denied" in msg:
            return InputError(f"{name}: cannot open the library file (permission denied)")
        first = msg.splitlines()[0] if msg else type(exc).__name__
        return NotALibraryError(f"{name} is not a primlib library (DuckDB cannot open it: {first})")

    def _open_schema(self) -> None:
        con = self._con
        name = self._label
        objects = con.sql(
            "SELECT table_name FROM duckdb_tables() WHERE database_name = current_database() "
            "UNION ALL SELECT view_name FROM duckdb_views() "
            "WHERE database_name = current_database() AND NOT internal "
            "UNION ALL SELECT sequence_name FROM duckdb_sequences() "
            "WHERE database_name = current_database()"
        ).fetchall()
        objects = {row[0] for row in objects}
        if not objects:
            if self._read_only:
                raise NotALibraryError(
                    f"{name} is not a primlib library (an empty DuckDB database, opened read-only)"
                )
            migrate(con, 0)
            return
        if "meta" not in objects:
            raise NotALibraryError(
                f"{name} is not a primlib library (a DuckDB database without primlib's meta table)"
            )
        try:
            meta = dict(con.sql("SELECT key, value FROM meta").fetchall())
            version = int(meta.get("schema_version", ""))
        except (duckdb.Error, ValueError, TypeError):
            raise NotALibraryError(
                f"{name} is not a primlib library (its meta table is not primlib's)"
            ) from None
        if meta.get("application") != APPLICATION:
            raise NotALibraryError(
                f"{name} is not a primlib library (its meta table names no primlib application)"
            )
        if version > SCHEMA_VERSION:
            raise NotALibraryError(
                f"{name} is a primlib library of schema version {version}, newer than this "
                f"primlib reads ({SCHEMA_VERSION}); upgrade primlib"
            )
        if version < SCHEMA_VERSION:
            if self._read_only:
                raise NotALibraryError(
                    f"{name} is a primlib library of schema version {version}, older than "
                    f"this primlib reads ({SCHEMA_VERSION}); open it for writing once to upgrade it"
                )
            migrate(con, version)

    @property
    def schema_version(self) -> int:
        """The file's schema version."""
        row = self._db().sql("SELECT value FROM meta WHERE key = 'schema_version'").fetchall()
        return int(row[0][0])

    def migrations(self) -> list[tuple[int, str, Any]]:
        """The applied migrations: (version, description, applied at, UTC), in order."""
        rows = self._db().sql("SELECT version, description, applied FROM migrations ORDER BY 1")
        return [(v, d, t.replace(tzinfo=UTC)) for v, d, t in rows.fetchall()]

    # ------------------------------------------------------------------ plumbing
    def _db(self) -> Any:
        if self._con is None:
            raise InputError(f"{self._label} is closed")
        return self._con

    def _writable(self) -> Any:
        con = self._db()
        if self._read_only:
            raise InputError(f"{self._label} is open read-only; open it for writing to change it")
        return con

    @contextmanager
    def _transaction(self) -> Iterator[Any]:
        con = self._writable()
        con.begin()
        try:
            yield con
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

    def close(self) -> None:
        """Close the file (releasing its lock). Closing twice is harmless."""
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> Library:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._con is None else ("read-only" if self._read_only else "open")
        return f"Library({self._path!r}, {state})"

    # ------------------------------------------------------------------ machines
    def machines(self) -> list[str]:
        """Names of the machines in the library, sorted."""
        return [r[0] for r in self._db().sql("SELECT name FROM machines ORDER BY name").fetchall()]

    def _machine_row(self, name: str) -> tuple[float, list[str], str]:
        if not isinstance(name, str):
            raise InputError(f"machine: expected a machine name, got {name!r}")
        rows = (
            self._db()
            .sql("SELECT dt, axes, definition FROM machines WHERE name = $n", params={"n": name})
            .fetchall()
        )
        if not rows:
            known = ", ".join(self.machines()) or "no machines"
            raise NotFoundError(f"unknown machine {name!r}; the library has: {known}")
        dt, axes, definition = rows[0]
        return float(dt), list(axes), definition

    def machine(self, name: str) -> Any:
        """The machine called ``name``, a :class:`primlib.plant.Machine`.

        Raises
        ------
        NotFoundError
            ``unknown machine 'q'; the library has: xyz``.
        """
        _, _, definition = self._machine_row(name)
        cached = self._machines_cache.get(name)
        if cached is not None and cached[0] == definition:
            return cached[1]
        from primlib.plant import Machine

        machine = Machine.from_dict(json.loads(definition))
        self._machines_cache[name] = (definition, machine)
        return machine

    def add_machine(self, machine: Any, replace: bool = False) -> str:
        """Store a machine (its JSON definition), so primitives can be learned on it.

        Adding a machine identical to the stored one of that name does nothing.

        Parameters
        ----------
        machine : primlib.plant.Machine or mapping
            The machine, or its JSON dictionary (validated by ``Machine.from_dict``).
        replace : bool, default False
            Overwrite a different machine of the same name. Refused while it has primitives
            and the sample time or the axes change (their signals would no longer fit).

        Raises
        ------
        InputError
            A different machine of that name exists and ``replace`` is False; or the
            replacement changes dt or axes of a machine with primitives.
        """
        if isinstance(machine, Mapping):
            from primlib.plant import Machine

            machine = Machine.from_dict(machine)
        to_dict = getattr(machine, "to_dict", None)
        if not callable(to_dict):
            raise InputError(f"machine: expected a Machine, got {type(machine).__name__}")
        d = to_dict()
        name, dt, axes = d["name"], float(d["dt"]), [str(a) for a in d["axes"]]
        definition = json.dumps(d, sort_keys=True)
        with self._transaction() as con:
            rows = con.sql(
                "SELECT dt, axes, definition FROM machines WHERE name = $n", params={"n": name}
            ).fetchall()
            if rows:
                old_dt, old_axes, old_definition = rows[0]
                if json.loads(old_definition) == json.loads(definition):
                    return "unchanged"
                if not replace:
                    raise InputError(
                        f"machine {name!r} is already in {self._label} with another definition; "
                        "replace it explicitly (replace=True, or --replace)"
                    )
                count = con.sql(
                    "SELECT count(*) FROM primitives WHERE machine = $n", params={"n": name}
                ).fetchall()[0][0]
                if count and (old_dt != dt or list(old_axes) != axes):
                    raise InputError(
                        f"machine {name!r} has {count} primitives stored at dt = {old_dt:g} s "
                        f"on axes {', '.join(old_axes)}; its replacement must keep both, got "
                        f"dt = {dt:g} s on axes {', '.join(axes)}"
                    )
                status = "replaced"
                con.execute(
                    "UPDATE machines SET kind = $k, dt = $dt, axes = $a, definition = $d "
                    "WHERE name = $n",
                    {"k": d.get("kind", "lti"), "dt": dt, "a": axes, "d": definition, "n": name},
                )
            else:
                status = "added"
                con.execute(
                    "INSERT INTO machines VALUES ($n, $k, $dt, $a, $d, $t)",
                    {
                        "n": name,
                        "k": d.get("kind", "lti"),
                        "dt": dt,
                        "a": axes,
                        "d": definition,
                        "t": utcnow(),
                    },
                )
        self._machines_cache.pop(name, None)
        return status

    def remove_machine(self, name: str, primitives: bool = False) -> int:
        """Delete a machine, and with ``primitives=True`` its primitives too (one transaction).

        Returns
        -------
        int
            The number of primitives removed with it.

        Raises
        ------
        NotFoundError
            Unknown machine.
        InputError
            The machine has primitives and ``primitives`` is False.
        """
        self._machine_row(name)
        with self._transaction() as con:
            count = con.sql(
                "SELECT count(*) FROM primitives WHERE machine = $n", params={"n": name}
            ).fetchall()[0][0]
            if count and not primitives:
                raise InputError(
                    f"machine {name!r} has {count} primitives; remove them with it explicitly "
                    "(primitives=True, or --with-primitives)"
                )
            con.execute("DELETE FROM primitives WHERE machine = $n", {"n": name})
            con.execute("DELETE FROM machines WHERE name = $n", {"n": name})
        self._machines_cache.pop(name, None)
        self._bank_cache.pop(name, None)
        return int(count)

    def machine_summaries(self) -> list[dict[str, Any]]:
        """One dict per machine: name, kind, dt, axes, primitives (count), added (UTC)."""
        rows = (
            self._db()
            .sql(
                "SELECT m.name, m.kind, m.dt, m.axes, count(p.id), m.added FROM machines m "
                "LEFT JOIN primitives p ON p.machine = m.name "
                "GROUP BY m.name, m.kind, m.dt, m.axes, m.added ORDER BY m.name"
            )
            .fetchall()
        )
        return [
            {
                "name": n,
                "kind": k,
                "dt": dt,
                "axes": list(a),
                "primitives": c,
                "added": t.replace(tzinfo=UTC),
            }
            for n, k, dt, a, c, t in rows
        ]

    # ------------------------------------------------------------------ adding
    def add(
        self,
        path: Any,
        u: Any,
        machine: str,
        name: str | None = None,
        source: str | None = None,
    ) -> int:
        """Store one primitive: a path and the input learned for it on ``machine``.

        Parameters
        ----------
        path : primlib.nurbs.Trajectory
            The path; its duration must be a whole number of the machine's steps.
        u : array, shape (n, d)
            The converged input on t = 0, dt, ..., T, n = round(T / dt) + 1, d = the
            machine's axes.
        machine : str
            Name of a machine in the library.
        name, source : str, optional
            A name for the primitive and where it came from.

        Returns
        -------
        int
            The new primitive's id.

        Raises
        ------
        NotFoundError
            Unknown machine.
        InputError
            Wrong dimension, dt or shape, NaN or inf; nothing is written.
        """
        return self._insert([(path, u, name, source)], machine, single=True)[0]

    def add_many(self, items: Sequence[Sequence[Any]], machine: str) -> list[int]:
        """Store many primitives in ONE transaction: all of them, or (on any error) none.

        Every item is checked before the first insert; the batch then goes in as a single
        Arrow table (list columns over the flat numpy buffers).

        Parameters
        ----------
        items : sequence of (Trajectory, u, name, source)
            ``u`` array, shape (n_i, d); ``name`` and ``source`` may be None or left off.
        machine : str
            Name of a machine in the library.

        Returns
        -------
        list of int
            The new ids, in the order of ``items``.

        Raises
        ------
        NotFoundError
            Unknown machine.
        InputError
            Any bad item (the message names it); nothing is written.
        """
        return self._insert(items, machine, single=False)

    def _insert(self, items: Sequence[Sequence[Any]], machine: str, single: bool) -> list[int]:
        con = self._writable()
        dt, axes, _ = self._machine_row(machine)
        d = len(axes)
        if isinstance(items, (str, bytes)) or not isinstance(items, Sequence):
            raise InputError(
                f"items: expected a list of (path, u, name, source), got {type(items).__name__}"
            )
        k = len(items)
        if k == 0:
            return []
        checked = [
            self._check_item(None if single else i, item, machine, dt, axes)
            for i, item in enumerate(items)
        ]

        n = np.array([c["n"] for c in checked], dtype=np.int64)
        sample_offsets = np.concatenate([[0], np.cumsum(n * d)]).astype(np.int64)
        points = _sample_points(checked, dt, d, sample_offsets)
        # one flat buffer per big column: one Arrow list array each (measured faster to
        # insert than one chunk per primitive, the concatenation included)
        signals = _list_array(np.concatenate([c["u"].ravel() for c in checked]), sample_offsets)
        points = _list_array(points, sample_offsets)
        m = np.array([len(c["weights"]) for c in checked], dtype=np.int64)
        nk = np.array([len(c["knots"]) for c in checked], dtype=np.int64)
        ctrl_offsets = np.concatenate([[0], np.cumsum(m * d)])
        weight_offsets = np.concatenate([[0], np.cumsum(m)])
        knot_offsets = np.concatenate([[0], np.cumsum(nk)])
        knots = np.concatenate([c["knots"] for c in checked])
        ctrlpts = np.concatenate([c["ctrlpts"].ravel() for c in checked])
        weights = np.concatenate([c["weights"] for c in checked])
        added = utcnow()

        registered = direct = False
        threads = int(con.sql("SELECT current_setting('threads')").fetchall()[0][0])
        # One thread: the parallel (order-preserving) insert was 2-3x slower here.
        con.execute("SET threads = 1")
        try:
            with self._transaction():
                seq = con.sql(f"SELECT nextval('primitive_ids') FROM range({k})").fetchall()
                ids = np.array([r[0] for r in seq], dtype=np.int64)
                table = pa.table(
                    {
                        "id": pa.array(ids),
                        "machine": pa.array([machine] * k, pa.string()),
                        "name": pa.array([c["name"] for c in checked], pa.string()),
                        "source": pa.array([c["source"] for c in checked], pa.string()),
                        "added": pa.array([added] * k, pa.timestamp("us")),
                        "duration": pa.array([c["duration"] for c in checked], pa.float64()),
                        "dt": pa.array(np.full(k, dt)),
                        "dim": pa.array(np.full(k, d, dtype=np.int32)),
                        "n_samples": pa.array(n.astype(np.int32)),
                        "degree": pa.array(
                            np.array([c["degree"] for c in checked], dtype=np.int32)
                        ),
                        "knots": _list_array(knots, knot_offsets),
                        "ctrlpts": _list_array(ctrlpts, ctrl_offsets),
                        "weights": _list_array(weights, weight_offsets),
                        "points": points,
                        "signal": signals,
                    }
                )
                con.register("_primlib_batch", table)
                registered = True
                cols = ", ".join(_INSERT_COLUMNS)
                con.execute(f"INSERT INTO primitives ({cols}) SELECT {cols} FROM _primlib_batch")
                if self._path is not None and 2 * sample_offsets[-1] * 8 >= _DIRECT_BYTES:
                    # DuckDB's size estimate misses list contents, so a big batch would go
                    # to the WAL first and be written again at the next checkpoint (close):
                    # a low threshold makes the commit write it to the file once.
                    con.execute("SET checkpoint_threshold = '1MiB'")
                    direct = True
        finally:
            # after the rollback: an aborted transaction refuses even this
            if registered:
                con.unregister("_primlib_batch")
            if direct:
                con.execute("RESET checkpoint_threshold")
            con.execute(f"SET threads = {threads}")
        return ids.tolist()

    @staticmethod
    def _check_item(
        i: int | None, item: Any, machine: str, dt: float, axes: list[str]
    ) -> dict[str, Any]:
        d = len(axes)
        if (
            isinstance(item, (str, bytes))
            or not isinstance(item, Sequence)
            or not (2 <= len(item) <= 4)
        ):
            raise InputError(f"item {i}: expected (path, u, name, source), got {item!r:.60}")
        path, u = item[0], item[1]
        name = item[2] if len(item) > 2 else None
        source = item[3] if len(item) > 3 else None
        # add() names the primitive, add_many() the item too: "item 2 ('glyph-c'): ..."
        label = "primitive" if i is None else f"item {i}"
        if isinstance(name, str):
            label = f"primitive {name!r}" if i is None else f"{label} ({name!r})"
        for what, value in (("name", name), ("source", source)):
            if value is not None and not isinstance(value, str):
                raise InputError(f"{label}: expected {what} to be a string, got {value!r}")
        if not all(hasattr(path, a) for a in ("definition", "sample", "duration", "dim")):
            raise InputError(f"{label}: expected a Trajectory, got {type(path).__name__}")
        if path.dim != d:
            raise InputError(
                f"{label}: expected a {d}-D path for machine {machine!r} (axes "
                f"{', '.join(axes)}), got a {path.dim}-D path"
            )
        own_dt = getattr(path, "dt", None)
        if own_dt is not None and abs(float(own_dt) - dt) > _DT_RTOL * dt:
            raise InputError(
                f"{label}: expected a path sampled at the dt of machine {machine!r} ({dt:g} s), "
                f"got dt = {float(own_dt):g} s"
            )
        duration = float(path.duration)
        steps = duration / dt
        if not math.isfinite(steps) or steps < 1 or abs(steps - round(steps)) > _STEP_RTOL:
            raise InputError(
                f"{label}: expected a duration that is a whole number of steps of machine "
                f"{machine!r} (dt = {dt:g} s), got T = {duration:.9g} s"
            )
        n = int(round(steps)) + 1
        if n < MIN_ROWS:
            raise InputError(
                f"{label}: expected at least {MIN_ROWS} samples on the grid of machine {machine!r} "
                f"(T >= {MIN_ROWS - 1} dt = {(MIN_ROWS - 1) * dt:g} s), got {n}"
            )
        try:
            u = np.asarray(u, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{label}: expected a numeric signal array, got {u!r:.60}") from None
        if u.shape != (n, d):
            raise InputError(
                f"{label}: expected a signal of shape ({n}, {d}) (the path's grid at "
                f"dt = {dt:g} s, T = {duration:g} s), got {u.shape}"
            )
        if not np.isfinite(u).all():
            raise InputError(f"{label}: expected a finite signal, got NaN or inf")
        definition = path.definition()
        ctrlpts = np.asarray(definition["ctrlpts"], dtype=np.float64)
        weights = np.asarray(definition["weights"], dtype=np.float64).ravel()
        knots = np.asarray(definition["knots"], dtype=np.float64).ravel()
        if ctrlpts.ndim != 2 or ctrlpts.shape[1] != d or len(weights) != len(ctrlpts):
            raise InputError(
                f"{label}: expected control points (m, {d}) and m weights, got "
                f"{ctrlpts.shape} and {weights.shape}"
            )
        return {
            "n": n,
            "u": u,
            "path": path,
            "label": label,
            "name": name,
            "source": source,
            "duration": duration,
            "degree": int(definition["degree"]),
            "knots": knots,
            "ctrlpts": ctrlpts,
            "weights": weights,
        }

    # ------------------------------------------------------------------ reading
    @staticmethod
    def _info(row: Sequence[Any]) -> PrimitiveInfo:
        id_, name, machine, duration, dt, n, dim, source, added = row
        return PrimitiveInfo(
            id=int(id_),
            name=name,
            machine=machine,
            duration=float(duration),
            dt=float(dt),
            n_samples=int(n),
            dim=int(dim),
            source=source,
            added=added.replace(tzinfo=UTC),
        )

    def primitives(self, machine: str | None = None) -> list[PrimitiveInfo]:
        """Metadata of the stored primitives (no arrays), ordered by id.

        Parameters
        ----------
        machine : str, optional
            Only this machine's (NotFoundError if unknown).
        """
        con = self._db()
        if machine is None:
            rel = con.sql(f"SELECT {_INFO_COLUMNS} FROM primitives ORDER BY id")
        else:
            self._machine_row(machine)
            rel = con.sql(
                f"SELECT {_INFO_COLUMNS} FROM primitives WHERE machine = $m ORDER BY id",
                params={"m": machine},
            )
        return [self._info(r) for r in rel.fetchall()]

    def _not_found(self, id: int) -> NotFoundError:
        return NotFoundError(f"no primitive with id {id} in {self._label}")

    def info(self, id: int) -> PrimitiveInfo:
        """Metadata of one primitive (NotFoundError if there is none with that id)."""
        id = _check_id(id)
        rows = (
            self._db()
            .sql(f"SELECT {_INFO_COLUMNS} FROM primitives WHERE id = $id", params={"id": id})
            .fetchall()
        )
        if not rows:
            raise self._not_found(id)
        return self._info(rows[0])

    def get(self, id: int) -> Primitive:
        """One primitive with its trajectory, points and signal.

        Raises
        ------
        NotFoundError
            No primitive with that id.
        """
        id = _check_id(id)
        table = (
            self._db()
            .sql(
                f"SELECT {_INFO_COLUMNS}, degree, knots, ctrlpts, weights, points, signal "
                "FROM primitives WHERE id = $id",
                params={"id": id},
            )
            .to_arrow_table()
        )
        if table.num_rows == 0:
            raise self._not_found(id)
        row = [table.column(c)[0].as_py() for c in _INFO_COLUMNS.split(", ")]
        info = self._info(row)
        d = info.dim
        ctrlpts = _flat(table.column("ctrlpts")).reshape(-1, d)
        weights = _flat(table.column("weights"))
        knots = _flat(table.column("knots"))
        from primlib.nurbs import Trajectory

        trajectory = Trajectory.from_definition(
            int(table.column("degree")[0].as_py()), knots, ctrlpts, weights, info.duration
        )
        return Primitive(
            **{f: getattr(info, f) for f in info.__dataclass_fields__},
            trajectory=trajectory,
            points=_flat(table.column("points")).reshape(-1, d),
            signal=_flat(table.column("signal")).reshape(-1, d),
        )

    def signal(self, id: int) -> np.ndarray:
        """The stored input of one primitive, shape (n, d) (one indexed lookup).

        Raises
        ------
        NotFoundError
            No primitive with that id.
        """
        id = _check_id(id)
        table = (
            self._db()
            .sql("SELECT dim, signal FROM primitives WHERE id = $id", params={"id": id})
            .to_arrow_table()
        )
        if table.num_rows == 0:
            raise self._not_found(id)
        return _flat(table.column("signal")).reshape(-1, table.column("dim")[0].as_py())

    def bank(self, machine: str) -> Bank:
        """All primitives of a machine as flat arrays, from one columnar query.

        Parameters
        ----------
        machine : str
            A machine in the library.

        Returns
        -------
        Bank
            Ordered by id; ``points`` and ``signals`` of shape (N, d) concatenated, with
            ``offsets`` (k + 1,). Empty (k = 0) when the machine has no primitives.
            ``signals`` are read on first access (matching needs only the points), so
            read them before closing the library. The arrays are read-only: while the
            machine's primitives are unchanged, later calls return the same Bank without
            reading the file again.

        Raises
        ------
        NotFoundError
            Unknown machine.
        """
        dt, axes, _ = self._machine_row(machine)
        # Ids are issued by a sequence and never reused, and stored primitives never change,
        # so (count, largest id) pins down a machine's set exactly: an unchanged set is
        # served from the cache (its arrays are read-only), any add or remove reloads it.
        count, last = (
            self._db()
            .sql(
                "SELECT count(*), max(id) FROM primitives WHERE machine = $m",
                params={"m": machine},
            )
            .fetchall()[0]
        )
        key = (count, last, dt, tuple(axes))
        cached = self._bank_cache.get(machine)
        if cached is not None and cached[0] == key:
            return cached[1]
        bank = self._load_bank(machine, dt, axes)
        self._bank_cache[machine] = (key, bank)
        return bank

    def _load_bank(self, machine: str, dt: float, axes: list[str]) -> Bank:
        d = len(axes)
        table = (
            self._db()
            .sql(
                "SELECT id, name, duration, n_samples, degree, knots, ctrlpts, weights, "
                "points FROM primitives WHERE machine = $m",
                params={"m": machine},
            )
            .to_arrow_table()
        )
        # No ORDER BY: sorting moves every list (it cost 4x the scan here); a scan returns
        # rows in insertion (= id) order, and the rare other case is fixed with one take.
        ids = table.column("id").to_numpy().astype(np.int64)
        if np.any(np.diff(ids) <= 0):
            order = np.argsort(ids, kind="stable")
            table = table.take(pa.array(order))
            ids = ids[order]

        def offsets_of(counts: np.ndarray) -> np.ndarray:
            return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)

        n = table.column("n_samples").to_numpy().astype(np.int64)
        knots_arr = table.column("knots").combine_chunks()
        weights_arr = table.column("weights").combine_chunks()
        bank = Bank(
            machine=machine,
            dt=dt,
            dim=d,
            ids=ids,
            names=tuple(table.column("name").to_pylist()),
            durations=table.column("duration").to_numpy().astype(np.float64),
            offsets=offsets_of(n),
            points=_flat(table.column("points")).reshape(-1, d),
            degrees=table.column("degree").to_numpy().astype(np.int64),
            knots=_flat(table.column("knots")),
            knot_offsets=offsets_of(knots_arr.value_lengths().to_numpy(zero_copy_only=False)),
            ctrlpts=_flat(table.column("ctrlpts")).reshape(-1, d),
            weights=_flat(table.column("weights")),
            ctrl_offsets=offsets_of(weights_arr.value_lengths().to_numpy(zero_copy_only=False)),
            load_signals=lambda: self._bank_signals(machine, ids, d),
        )
        for value in vars(bank).values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        return bank

    def _bank_signals(self, machine: str, ids: np.ndarray, d: int) -> np.ndarray:
        """The signals of a bank's primitives, in the bank's order (read on first use)."""
        if self._con is None:
            raise InputError(
                f"{self._label} was closed before this bank's signals were read; "
                "read bank.signals while the library is open"
            )
        table = (
            self._db()
            .sql(
                "SELECT id, signal FROM primitives WHERE machine = $m",
                params={"m": machine},
            )
            .to_arrow_table()
        )
        got = table.column("id").to_numpy().astype(np.int64)
        if not np.array_equal(got, ids):
            # Rows removed or added since the bank was read: pick the bank's ids (never
            # reused, so an id names the same primitive), unless one of them is gone.
            order = np.argsort(got, kind="stable")
            pos = np.searchsorted(got[order], ids)
            pos = np.minimum(pos, max(len(got) - 1, 0))
            found = got[order][pos] == ids if len(got) else np.zeros(len(ids), bool)
            if not np.all(found):
                missing = int(ids[np.flatnonzero(~found)[0]])
                raise InputError(
                    f"{self._label}: primitive {missing} was removed after this bank was "
                    "read; read the bank again"
                )
            table = table.take(pa.array(order[pos]))
        signals = _flat(table.column("signal")).reshape(-1, d)
        signals.setflags(write=False)
        return signals

    # ------------------------------------------------------------------ removing
    def remove(self, id: int) -> None:
        """Delete one primitive (its id is never reused).

        Raises
        ------
        NotFoundError
            No primitive with that id.
        """
        id = _check_id(id)
        with self._transaction() as con:
            found = con.sql(
                "SELECT count(*) FROM primitives WHERE id = $id", params={"id": id}
            ).fetchall()[0][0]
            if not found:
                raise self._not_found(id)
            con.execute("DELETE FROM primitives WHERE id = $id", {"id": id})

    # ------------------------------------------------------------------ pipeline
    def match(self, path: Any, machine: str, eps: float, **kw: Any) -> Any:
        """Match a new path against this machine's primitives.

        Delegates to :func:`primlib.match.match_path` (see there for options); returns a
        :class:`primlib.match.Match`.
        """
        from primlib.match import match_path

        return match_path(self, path, machine=machine, eps=eps, **kw)

    def warm_start(self, path: Any, machine: str, eps: float, **kw: Any) -> Any:
        """Build a first-iteration ILC input for a new path from matched primitives.

        Delegates to :func:`primlib.splice.warm_start`; returns a ``WarmStart``.
        """
        from primlib.splice import warm_start

        return warm_start(self, path, machine=machine, eps=eps, **kw)
