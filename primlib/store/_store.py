"""The store: one DuckDB file of machines and the primitives learned on them.

Persistence only. Writes are transactions that check everything before the first insert;
arrays travel as Arrow buffers both ways (:mod:`primlib.store._codec`); opening, locking and
the schema check live in :mod:`primlib.store._connection`. Matching and warm starts live in
:mod:`primlib.pipeline`, whose ``Library`` extends this class.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable, Mapping, Sequence
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import duckdb
import numpy as np

from primlib._errors import InputError, NotFoundError
from primlib.store import _machines
from primlib.store._codec import INFO_COLUMNS, bank_from_table, flat, info_from_row
from primlib.store._connection import check_schema, connect, reading, transaction
from primlib.store._insert import insert
from primlib.store._types import AddResult, Bank, Primitive, PrimitiveInfo
from primlib.store._validate import check_id

if TYPE_CHECKING:  # nurbs and plant load scipy: imported where a path or machine is rebuilt
    from primlib.nurbs import Trajectory
    from primlib.plant import Machine

__all__ = ["Store"]


def _reads(method):
    """A reading method: a failure on the file's own bytes reports the file as damaged."""

    @functools.wraps(method)
    def wrapper(self: Store, *args: Any, **kw: Any) -> Any:
        with reading(self._label):
            return method(self, *args, **kw)

    return wrapper


class Store:
    """A library file of motion primitives: NURBS paths with the ILC inputs learned for them.

    One DuckDB file holds the machines (sample time, axes, model) and, per machine, the
    primitives: the path's NURBS definition, and the path and its converged input sampled on
    the machine's grid t = 0, dt, ..., T (n = round(T / dt) + 1 samples). This class only
    stores; :class:`primlib.Library` (``primlib.pipeline.Library``) adds matching and warm
    starts on top of it.

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
        table (primlib never creates tables beside foreign ones), a library of a newer
        schema than this primlib reads, or a damaged file.
    LibraryBusyError
        If another process has the file open for writing (or this process has it open in
        the other mode).
    InputError
        If the path is a directory, its folder does not exist, the file does not exist and
        ``create`` is False, or it is read-only (file, folder or filesystem) and
        ``read_only`` is False.

    Notes
    -----
    A writable Store holds DuckDB's file lock until :meth:`close` (or the end of a ``with``
    block): other processes cannot open the file meanwhile.

    Examples
    --------
    >>> import tempfile, os
    >>> from primlib.store import Store
    >>> folder = tempfile.mkdtemp()
    >>> p = pl.Trajectory.from_csv("data/library/circle.csv")
    >>> t, u = pl.io.read_signal_csv("data/library/circle.signal.csv")
    >>> with Store(os.path.join(folder, "lib.duckdb")) as store:
    ...     _ = store.add_machine(pl.Machine.from_json("data/machines/xyz.json"))
    ...     pid = store.add(p, u, machine="xyz", name="circle")
    >>> with Store(os.path.join(folder, "lib.duckdb"), read_only=True) as store:
    ...     [r.name for r in store.primitives(machine="xyz")]
    ['circle']
    """

    def __init__(
        self, path: str | os.PathLike | None = None, *, read_only: bool = False, create: bool = True
    ) -> None:
        self._path = None if path is None else os.fspath(path)
        self._read_only = bool(read_only)
        self._machines_cache: dict[str, tuple[str, Machine]] = {}
        self._bank_cache: dict[str, tuple[tuple, Bank]] = {}
        self._con: duckdb.DuckDBPyConnection = None
        self._con = connect(self._path, self._read_only, create)
        try:
            check_schema(self._con, self._label, self._read_only)
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
        """True when opened without write access."""
        return self._read_only

    @property
    def _label(self) -> str:
        return self._path if self._path is not None else "the in-memory library"

    @property
    def schema_version(self) -> int:
        """The file's schema version."""
        row = self._db().sql("SELECT value FROM meta WHERE key = 'schema_version'").fetchall()
        return int(row[0][0])

    def migrations(self) -> list[tuple[int, str, datetime]]:
        """The applied migrations: (version, description, applied at, UTC), in order."""
        rows = self._db().sql("SELECT version, description, applied FROM migrations ORDER BY 1")
        return [(v, d, t.replace(tzinfo=UTC)) for v, d, t in rows.fetchall()]

    def _db(self) -> duckdb.DuckDBPyConnection:
        if self._con is None:
            raise InputError(f"{self._label} is closed")
        return self._con

    def _writable(self) -> duckdb.DuckDBPyConnection:
        con = self._db()
        if self._read_only:
            raise InputError(f"{self._label} is open read-only; open it for writing to change it")
        return con

    def close(self) -> None:
        """Close the file (releasing its lock). Closing twice is harmless."""
        if self._con is not None:
            self._con.close()
            self._con = None

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._con is None else ("read-only" if self._read_only else "open")
        return f"{type(self).__name__}({self._path!r}, {state})"

    # ------------------------------------------------------------------ machines
    @_reads
    def machines(self) -> list[str]:
        """Names of the machines in the library, sorted."""
        return _machines.machine_names(self._db())

    def _machine_row(self, name: str) -> tuple[float, list[str], str]:
        return _machines.machine_row(self._db(), name)

    def machine(self, name: str) -> Machine:
        """The machine called ``name``.

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

    def add_machine(self, machine: Machine | Mapping[str, Any], replace: bool = False) -> str:
        """Store a machine (its JSON definition), so primitives can be learned on it.

        Adding a machine identical to the stored one of that name does nothing.

        Parameters
        ----------
        machine : primlib.plant.Machine or mapping
            The machine, or its JSON dictionary (validated by ``Machine.from_dict``).
        replace : bool, default False
            Overwrite a different machine of the same name. Refused while it has primitives
            and the sample time or the axes change (their signals would no longer fit).

        Returns
        -------
        str
            "added", "replaced" or "unchanged".

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
        with transaction(self._writable()) as con:
            status = _machines.put_machine(con, d, replace, self._label)
        self._machines_cache.pop(d["name"], None)
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
        with transaction(self._writable()) as con:
            count = _machines.delete_machine(con, name, primitives)
        self._machines_cache.pop(name, None)
        self._bank_cache.pop(name, None)
        return count

    @_reads
    def machine_summaries(self) -> list[dict[str, Any]]:
        """One dict per machine: name, kind, dt, axes, primitives (count), added (UTC)."""
        return _machines.summaries(self._db())

    # ------------------------------------------------------------------ adding
    def add(
        self,
        path: Trajectory,
        u: np.ndarray,
        machine: str,
        name: str | None = None,
        source: str | None = None,
        origin: Any = None,
        error_rms: float | None = None,
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
            A name for the primitive (printable, one line, non-empty) and where it came from.
        origin : array, shape (d,), optional
            Where it ran: the absolute machine position the path started from when ``u``
            was learned (finite, one coordinate per axis). None: unknown.
        error_rms : float, optional
            The RMS tracking error (Euclidean over axes, output units) ``u`` is estimated to
            leave there without the measurement noise (finite, >= 0;
            :meth:`primlib.ilc.TrialLearner.input_error`). None: unknown.

        Returns
        -------
        int
            The new primitive's id; or, when the machine already holds an identical
            primitive (same path and signal), that one's id and nothing is written.

        Raises
        ------
        NotFoundError
            Unknown machine.
        InputError
            Wrong dimension, dt or shape; NaN, inf or a value beyond
            ``primlib.defaults.MAX_ABS_VALUE``; a path that does not move; a bad name; an
            origin without one finite coordinate per axis; an error_rms that is not a
            finite number >= 0. Nothing is written.
        """
        item = (path, u, name, source, origin, error_rms)
        return self.add_batch([item], machine, single=True).ids[0]

    def add_many(self, items: Sequence[Sequence[Any]], machine: str) -> list[int]:
        """Store many primitives in ONE transaction: all of them, or (on any error) none.

        Items identical to a stored primitive of the machine, or to an earlier item, are
        not stored again (:meth:`add_batch` says which, and can keep them).

        Parameters
        ----------
        items : sequence of (Trajectory, u, name, source, origin, error_rms)
            ``u`` array, shape (n_i, d); ``name``, ``source``, ``origin`` (the absolute
            start position, shape (d,)) and ``error_rms``, as in :meth:`add`, may be None or
            left off.
        machine : str
            Name of a machine in the library.

        Returns
        -------
        list of int
            The ids, in the order of ``items`` (a duplicate gets the id it repeats).

        Raises
        ------
        NotFoundError
            Unknown machine.
        InputError
            Any bad item (the message names it); nothing is written.
        """
        return list(self.add_batch(items, machine).ids)

    def add_batch(
        self,
        items: Sequence[Sequence[Any]],
        machine: str,
        *,
        allow_duplicates: bool = False,
        cancelled: Callable[[], bool] | None = None,
        single: bool = False,
    ) -> AddResult:
        """Store many primitives in one transaction and say what was written.

        Parameters
        ----------
        items : sequence of (Trajectory, u, name, source, origin, error_rms)
        machine : str
        allow_duplicates : bool, default False
            Store items identical to stored primitives (or to each other) anyway.
        cancelled : callable, optional
            Asked just before the commit; True rolls the batch back and raises
            :class:`primlib.store.WriteCancelled` (a KeyboardInterrupt): how a caller that
            defers Ctrl-C cancels a write that has not committed.
        single : bool
            Name the item "primitive" rather than "item i" in messages (``add``).

        Returns
        -------
        AddResult
        """
        con = self._writable()
        dt, axes, _ = self._machine_row(machine)
        return insert(
            con,
            items,
            machine,
            dt,
            axes,
            single=single,
            on_file=self._path is not None,
            allow_duplicates=allow_duplicates,
            cancelled=cancelled,
        )

    # ------------------------------------------------------------------ reading
    @_reads
    def primitives(self, machine: str | None = None) -> list[PrimitiveInfo]:
        """Metadata of the stored primitives (no arrays), ordered by id.

        Parameters
        ----------
        machine : str, optional
            Only this machine's (NotFoundError if unknown).
        """
        con = self._db()
        if machine is None:
            rel = con.sql(f"SELECT {INFO_COLUMNS} FROM primitives ORDER BY id")
        else:
            self._machine_row(machine)
            rel = con.sql(
                f"SELECT {INFO_COLUMNS} FROM primitives WHERE machine = $m ORDER BY id",
                params={"m": machine},
            )
        return [info_from_row(r) for r in rel.fetchall()]

    def _not_found(self, id: int) -> NotFoundError:
        return NotFoundError(f"no primitive with id {id} in {self._label}")

    @_reads
    def info(self, id: int) -> PrimitiveInfo:
        """Metadata of one primitive (NotFoundError if there is none with that id)."""
        id = check_id(id)
        rows = (
            self._db()
            .sql(f"SELECT {INFO_COLUMNS} FROM primitives WHERE id = $id", params={"id": id})
            .fetchall()
        )
        if not rows:
            raise self._not_found(id)
        return info_from_row(rows[0])

    @_reads
    def get(self, id: int) -> Primitive:
        """One primitive with its trajectory, points and signal.

        Raises
        ------
        NotFoundError
            No primitive with that id.
        """
        id = check_id(id)
        table = (
            self._db()
            .sql(
                f"SELECT {INFO_COLUMNS}, degree, knots, ctrlpts, weights, points, signal "
                "FROM primitives WHERE id = $id",
                params={"id": id},
            )
            .to_arrow_table()
        )
        if table.num_rows == 0:
            raise self._not_found(id)
        info = info_from_row([table.column(c)[0].as_py() for c in INFO_COLUMNS.split(", ")])
        d = info.dim
        from primlib.nurbs import Trajectory

        trajectory = Trajectory.from_definition(
            int(table.column("degree")[0].as_py()),
            flat(table.column("knots")),
            flat(table.column("ctrlpts")).reshape(-1, d),
            flat(table.column("weights")),
            info.duration,
        )
        return Primitive(
            **{f: getattr(info, f) for f in info.__dataclass_fields__},
            trajectory=trajectory,
            points=flat(table.column("points")).reshape(-1, d),
            signal=flat(table.column("signal")).reshape(-1, d),
        )

    @_reads
    def signal(self, id: int) -> np.ndarray:
        """The stored input of one primitive, shape (n, d) (one indexed lookup).

        Raises
        ------
        NotFoundError
            No primitive with that id.
        """
        id = check_id(id)
        table = (
            self._db()
            .sql("SELECT dim, signal FROM primitives WHERE id = $id", params={"id": id})
            .to_arrow_table()
        )
        if table.num_rows == 0:
            raise self._not_found(id)
        return flat(table.column("signal")).reshape(-1, table.column("dim")[0].as_py())

    @_reads
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
        table = (
            self._db()
            .sql(
                "SELECT id, name, duration, n_samples, degree, knots, ctrlpts, weights, "
                "points, origin, error_rms FROM primitives WHERE machine = $m",
                params={"m": machine},
            )
            .to_arrow_table()
        )
        d = len(axes)
        bank = bank_from_table(
            table, machine, dt, d, lambda ids: self._bank_signals(machine, ids, d)
        )
        self._bank_cache[machine] = (key, bank)
        return bank

    @_reads
    def _bank_signals(self, machine: str, ids: np.ndarray, d: int) -> np.ndarray:
        """The signals of a bank's primitives, in the bank's order (read on first use)."""
        if self._con is None:
            raise InputError(
                f"{self._label} was closed before this bank's signals were read; "
                "read bank.signals while the library is open"
            )
        table = (
            self._db()
            .sql("SELECT id, signal FROM primitives WHERE machine = $m", params={"m": machine})
            .to_arrow_table()
        )
        got = table.column("id").to_numpy().astype(np.int64)
        if not np.array_equal(got, ids):
            # Rows removed or added since the bank was read: pick the bank's ids (never
            # reused, so an id names the same primitive), unless one of them is gone.
            order = np.argsort(got, kind="stable")
            pos = np.minimum(np.searchsorted(got[order], ids), max(len(got) - 1, 0))
            found = got[order][pos] == ids if len(got) else np.zeros(len(ids), bool)
            if not np.all(found):
                missing = int(ids[np.flatnonzero(~found)[0]])
                raise InputError(
                    f"{self._label}: primitive {missing} was removed after this bank was "
                    "read; read the bank again"
                )
            import pyarrow as pa  # Arrow is loaded on bulk reads only

            table = table.take(pa.array(order[pos]))
        signals = flat(table.column("signal")).reshape(-1, d)
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
        id = check_id(id)
        with transaction(self._writable()) as con:
            found = con.sql(
                "SELECT count(*) FROM primitives WHERE id = $id", params={"id": id}
            ).fetchall()[0][0]
            if not found:
                raise self._not_found(id)
            con.execute("DELETE FROM primitives WHERE id = $id", {"id": id})
