"""The library's schema: ordered, recorded migrations.

A library file starts empty (schema version 0). Each entry of :data:`MIGRATIONS` moves it one
version forward; :func:`migrate` applies, in order, those above the file's version, each in
its own transaction together with the bump of ``meta.schema_version`` and a row in
``migrations`` (version, description, time applied, UTC). A failing step rolls back alone
and leaves the file at the previous version. Steps are SQL text or a callable taking the
connection. Never edit a released step: append a new one.

Layout (version 7):

``meta(key, value)``
    ``application = primlib`` marks a primlib library; ``schema_version``.
``migrations(version, description, applied)``
    One row per applied step.
``machines(name, kind, dt, axes, definition, added)``
    ``definition`` is the machine's JSON (docs/files.rst format), from which
    :meth:`primlib.plant.Machine.from_dict` rebuilds it.
``primitives(id, machine, name, source, added, duration, dt, dim, n_samples, degree, knots,
ctrlpts, weights, points, signal)``
    The NURBS definition (``ctrlpts`` flattened row-major, m x dim), and the path and its
    signal sampled on the machine's grid t = 0, dt, ..., T, each a flattened row-major
    (n_samples x dim) ``DOUBLE[]``. DuckDB stores columns apart, so listing metadata never
    reads the arrays. ``id`` is the primary key (a unique ART index: one row by id without
    a scan) and comes from the sequence ``primitive_ids``, so a removed id is never reused.
    ``content_hash`` (version 3) identifies machine, path and signal
    (:func:`primlib.store._validate.content_hash`): the same primitive is not stored twice
    unless asked to. ``origin`` (version 5, nullable ``DOUBLE[]``, one coordinate per axis)
    is the absolute machine position the primitive's path started from when its signal
    was learned (where it ran); NULL where unknown, as for every row stored before.
    ``error_rms`` (version 6, nullable ``DOUBLE``) is the RMS tracking error (Euclidean over
    the axes, output units) the stored signal is estimated to leave there without the
    measurement noise (:meth:`primlib.ilc.TrialLearner.input_error`): what the signal is
    worth, noise that ILC learned into it included; NULL where unknown.
``fitted_models(key, machine, bank, code, kind, created, payload)`` (version 7)
    Models fitted to a machine's stored primitives (the grey-box and refined models of a
    warm start, :mod:`primlib.pipeline._fitted`), kept so that the next process reads them
    instead of fitting again. ``key`` names everything the fit depends on (the machine's
    definition, the primitive ids, the options, primlib's code and numpy's and scipy's
    versions); ``bank`` the machine's primitive ids and ``code`` primlib's, by which rows
    of an earlier set of primitives or another primlib are dropped when a new one is kept;
    ``payload`` the model (``.npz`` bytes, no pickle). Derived data: deleting every row
    loses nothing but time.
``series(id, machine, name, created, state, start, options, notes, duration, dt, dim,
n_samples, degree, knots, ctrlpts, weights, points, origin, steps, primitive, finished)``
    A trial series on a real stage (:mod:`primlib.store._trials`): the path (NURBS and
    sampled, absolute coordinates), ``origin`` the absolute start position, ``steps`` the
    number of measured trials (the counter a step checks in its transaction), ``state``
    ``running`` or ``finished`` (then ``primitive`` is the id it was stored as).
``trials(series, trial, input, measured, digest, rms, rms_axes, contour_rms, noise_floor,
q_cutoff, created, recorded)``
    One row per trial: its input (n x d, flattened), and once run the measured output
    (absolute positions), its SHA-256 ``digest``, the RMS tracking and contour error, and the
    noise floor and Q cut-off the learning law estimated after it.

To add a step, append ``(next version, description, SQL text or callable)`` to
:data:`MIGRATIONS`; nothing else changes.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import duckdb
import numpy as np

from primlib.store._codec import flat
from primlib.store._validate import content_hash

if TYPE_CHECKING:
    pass

__all__ = ["APPLICATION", "MIGRATIONS", "SCHEMA_VERSION", "Migration", "migrate", "utcnow"]

APPLICATION = "primlib"

Migration = tuple[int, str, "str | Callable[[Any], None]"]


def _add_content_hash(con: duckdb.DuckDBPyConnection) -> None:
    """Version 3: the ``content_hash`` column, computed for the rows already stored."""
    import pyarrow as pa  # Arrow is loaded by this migration only

    con.execute("ALTER TABLE primitives ADD COLUMN content_hash VARCHAR")
    table = con.sql("SELECT id, machine, dim, points, signal FROM primitives").to_arrow_table()
    if table.num_rows == 0:
        return
    lengths = table.column("points").combine_chunks().value_lengths().to_numpy()
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    points, signals = flat(table.column("points")), flat(table.column("signal"))
    dims = table.column("dim").to_numpy()
    hashes = [
        content_hash(
            machine,
            points[offsets[i] : offsets[i + 1]].reshape(-1, int(dims[i])),
            signals[offsets[i] : offsets[i + 1]].reshape(-1, int(dims[i])),
        )
        for i, machine in enumerate(table.column("machine").to_pylist())
    ]
    con.register("_primlib_hashes", pa.table({"id": table.column("id"), "h": hashes}))
    try:
        con.execute(
            "UPDATE primitives SET content_hash = _primlib_hashes.h FROM _primlib_hashes "
            "WHERE primitives.id = _primlib_hashes.id"
        )
    finally:
        con.unregister("_primlib_hashes")


MIGRATIONS: list[Migration] = [
    (
        1,
        "meta, migration log and machines",
        """
        CREATE TABLE meta (key VARCHAR PRIMARY KEY, value VARCHAR NOT NULL);
        CREATE TABLE migrations (
            version INTEGER PRIMARY KEY,
            description VARCHAR NOT NULL,
            applied TIMESTAMP NOT NULL
        );
        CREATE TABLE machines (
            name VARCHAR PRIMARY KEY,
            kind VARCHAR NOT NULL,
            dt DOUBLE NOT NULL,
            axes VARCHAR[] NOT NULL,
            definition VARCHAR NOT NULL,
            added TIMESTAMP NOT NULL
        );
        INSERT INTO meta VALUES ('application', 'primlib'), ('schema_version', '0');
        """,
    ),
    (
        2,
        "primitives: NURBS definition, and path and signal on the machine's dt grid",
        """
        CREATE SEQUENCE primitive_ids START 1;
        CREATE TABLE primitives (
            id BIGINT PRIMARY KEY,
            machine VARCHAR NOT NULL,
            name VARCHAR,
            source VARCHAR,
            added TIMESTAMP NOT NULL,
            duration DOUBLE NOT NULL,
            dt DOUBLE NOT NULL,
            dim INTEGER NOT NULL,
            n_samples INTEGER NOT NULL,
            degree INTEGER NOT NULL,
            knots DOUBLE[] NOT NULL,
            ctrlpts DOUBLE[] NOT NULL,
            weights DOUBLE[] NOT NULL,
            points DOUBLE[] NOT NULL,
            signal DOUBLE[] NOT NULL
        );
        """,
    ),
    (3, "primitives: content_hash, so the same primitive is not stored twice", _add_content_hash),
    (
        4,
        "trial series and their trials: each trial's input and measured output",
        """
        CREATE SEQUENCE series_ids START 1;
        CREATE TABLE series (
            id BIGINT PRIMARY KEY,
            machine VARCHAR NOT NULL,
            name VARCHAR,
            created TIMESTAMP NOT NULL,
            state VARCHAR NOT NULL,
            start VARCHAR NOT NULL,
            options VARCHAR NOT NULL,
            notes VARCHAR NOT NULL,
            duration DOUBLE NOT NULL,
            dt DOUBLE NOT NULL,
            dim INTEGER NOT NULL,
            n_samples INTEGER NOT NULL,
            degree INTEGER NOT NULL,
            knots DOUBLE[] NOT NULL,
            ctrlpts DOUBLE[] NOT NULL,
            weights DOUBLE[] NOT NULL,
            points DOUBLE[] NOT NULL,
            origin DOUBLE[] NOT NULL,
            steps INTEGER NOT NULL,
            primitive BIGINT,
            finished TIMESTAMP
        );
        CREATE TABLE trials (
            series BIGINT NOT NULL,
            trial INTEGER NOT NULL,
            input DOUBLE[] NOT NULL,
            measured DOUBLE[],
            digest VARCHAR,
            rms DOUBLE,
            rms_axes DOUBLE[],
            contour_rms DOUBLE,
            noise_floor DOUBLE,
            q_cutoff DOUBLE,
            created TIMESTAMP NOT NULL,
            recorded TIMESTAMP,
            PRIMARY KEY (series, trial)
        );
        """,
    ),
    (
        5,
        "primitives: origin, the absolute start position where the primitive ran",
        "ALTER TABLE primitives ADD COLUMN origin DOUBLE[]",
    ),
    (
        6,
        "primitives: error_rms, the tracking error the stored signal leaves where it ran",
        "ALTER TABLE primitives ADD COLUMN error_rms DOUBLE",
    ),
    (
        7,
        "fitted_models: the models a warm start fits to a machine's primitives, kept",
        """
        CREATE TABLE fitted_models (
            key VARCHAR PRIMARY KEY,
            machine VARCHAR NOT NULL,
            bank VARCHAR NOT NULL,
            code VARCHAR NOT NULL,
            kind VARCHAR NOT NULL,
            created TIMESTAMP NOT NULL,
            payload BLOB NOT NULL
        );
        """,
    ),
]


SCHEMA_VERSION = MIGRATIONS[-1][0]
"""The schema version this primlib writes and reads."""


def utcnow() -> datetime:
    """The current UTC time as a naive datetime (DuckDB ``TIMESTAMP``), to the microsecond."""
    return datetime.now(UTC).replace(tzinfo=None)


def check_migrations(migrations: list[Migration]) -> None:
    """Raise ValueError unless versions run 1, 2, 3, ... in order (a programming error)."""
    versions = [m[0] for m in migrations]
    if versions != list(range(1, len(versions) + 1)):
        raise ValueError(f"migrations must be numbered 1, 2, ... in order, got {versions}")


def migrate(
    con: duckdb.DuckDBPyConnection, current: int, migrations: list[Migration] | None = None
) -> list[int]:
    """Apply the migrations above ``current``, in order, one transaction each.

    Parameters
    ----------
    con : duckdb connection
        A writable connection to the library.
    current : int
        The file's schema version (0 for a file with no tables).
    migrations : list of (version, description, step), optional
        Defaults to :data:`MIGRATIONS`; tests pass longer lists to exercise upgrades.

    Returns
    -------
    list of int
        The versions applied (empty when the file was up to date).
    """
    migrations = MIGRATIONS if migrations is None else migrations
    check_migrations(migrations)
    applied = []
    for version, description, step in migrations:
        if version <= current:
            continue
        con.begin()
        try:
            if callable(step):
                step(con)
            else:
                con.execute(step)
            con.execute(
                "UPDATE meta SET value = $v WHERE key = 'schema_version'", {"v": str(version)}
            )
            con.execute(
                "INSERT INTO migrations VALUES ($v, $d, $t)",
                {"v": version, "d": description, "t": utcnow()},
            )
            con.commit()
        except BaseException:
            con.rollback()
            raise
        applied.append(version)
    return applied
