"""Arrow codec: numpy buffers to DuckDB list columns and back, without per-row Python work.

A batch is inserted as one Arrow table whose list columns wrap flat numpy buffers; a
machine's whole bank comes back from one columnar query as flat numpy arrays plus offsets.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from typing import TYPE_CHECKING, Any

import numpy as np

from primlib.store._types import Bank, PrimitiveInfo

if TYPE_CHECKING:
    import pyarrow as pa

__all__ = [
    "INFO_COLUMNS",
    "INSERT_COLUMNS",
    "list_array",
    "flat",
    "offsets_of",
    "info_from_row",
    "batch_table",
    "bank_from_table",
    "in_id_order",
]

INFO_COLUMNS = "id, name, machine, duration, dt, n_samples, dim, source, added, origin, error_rms"
INSERT_COLUMNS = [
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
    "content_hash",
    "origin",
    "error_rms",
]


def list_array(flat_values: np.ndarray, offsets: np.ndarray) -> pa.Array:
    """A list column over a flat float64 buffer and offsets, without copying the values.

    32-bit offsets while they fit (DuckDB reads a ``ListArray`` a little faster than a
    ``LargeListArray``), 64-bit beyond 2**31 values.
    """
    import pyarrow as pa  # Arrow is loaded on writes and bulk reads only

    if offsets[-1] < 2**31:
        return pa.ListArray.from_arrays(pa.array(offsets.astype(np.int32)), pa.array(flat_values))
    return pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(flat_values))


def flat(column: pa.ChunkedArray) -> np.ndarray:
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


def offsets_of(counts: np.ndarray) -> np.ndarray:
    """Start offsets (k + 1,) of k consecutive runs of the given lengths."""
    return np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]).astype(np.int64)


def info_from_row(row: Sequence[Any]) -> PrimitiveInfo:
    """A :class:`PrimitiveInfo` from one row of :data:`INFO_COLUMNS`."""
    id_, name, machine, duration, dt, n, dim, source, added, origin, error_rms = row
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
        origin=None if origin is None else tuple(float(x) for x in origin),
        error_rms=None if error_rms is None else float(error_rms),
    )


def batch_table(
    ids: np.ndarray,
    machine: str,
    dt: float,
    d: int,
    checked: list[dict[str, Any]],
    points: np.ndarray,
    sample_offsets: np.ndarray,
    added: datetime,
) -> pa.Table:
    """The Arrow table of one insert batch, columns :data:`INSERT_COLUMNS`.

    ``checked`` are the validated items (``validate.check_item``), ``points`` every item's
    path on the machine grid as one flat buffer with ``sample_offsets`` (in values).
    """
    import pyarrow as pa  # Arrow is loaded on writes and bulk reads only

    k = len(checked)
    m = np.array([len(c["weights"]) for c in checked], dtype=np.int64)
    nk = np.array([len(c["knots"]) for c in checked], dtype=np.int64)
    n = np.array([c["n"] for c in checked], dtype=np.int32)
    # one flat buffer per big column: one Arrow list array each (measured faster to insert
    # than one chunk per primitive, the concatenation included)
    signals = np.concatenate([c["u"].ravel() for c in checked])
    return pa.table(
        {
            "id": pa.array(ids),
            "machine": pa.array([machine] * k, pa.string()),
            "name": pa.array([c["name"] for c in checked], pa.string()),
            "source": pa.array([c["source"] for c in checked], pa.string()),
            "added": pa.array([added] * k, pa.timestamp("us")),
            "duration": pa.array([c["duration"] for c in checked], pa.float64()),
            "dt": pa.array(np.full(k, dt)),
            "dim": pa.array(np.full(k, d, dtype=np.int32)),
            "n_samples": pa.array(n),
            "degree": pa.array(np.array([c["degree"] for c in checked], dtype=np.int32)),
            "knots": list_array(np.concatenate([c["knots"] for c in checked]), offsets_of(nk)),
            "ctrlpts": list_array(
                np.concatenate([c["ctrlpts"].ravel() for c in checked]), offsets_of(m * d)
            ),
            "weights": list_array(np.concatenate([c["weights"] for c in checked]), offsets_of(m)),
            "points": list_array(points, sample_offsets),
            "signal": list_array(signals, sample_offsets),
            "content_hash": pa.array([c["hash"] for c in checked], pa.string()),
            "origin": pa.array(
                [None if c["origin"] is None else c["origin"].tolist() for c in checked],
                pa.list_(pa.float64()),
            ),
            "error_rms": pa.array([c["error_rms"] for c in checked], pa.float64()),
        }
    )


def in_id_order(table: pa.Table) -> tuple[pa.Table, np.ndarray]:
    """The table sorted by its ``id`` column, and the ids (int64).

    A scan returns rows in insertion (= id) order, so the sort is skipped then (sorting
    moves every list: it cost 4x the scan here); the rare other case costs one take.
    """
    import pyarrow as pa  # Arrow is loaded on writes and bulk reads only

    ids = table.column("id").to_numpy().astype(np.int64)
    if np.any(np.diff(ids) <= 0):
        order = np.argsort(ids, kind="stable")
        table = table.take(pa.array(order))
        ids = ids[order]
    return table, ids


def _origins(rows: list[list[float] | None], d: int) -> np.ndarray:
    """(k, d) origins, NaN where a primitive's origin is unknown (NULL)."""
    out = np.full((len(rows), d), np.nan)
    for i, row in enumerate(rows):  # one short list per primitive, not per sample
        if row is not None:
            out[i] = row
    return out


def bank_from_table(
    table: pa.Table,
    machine: str,
    dt: float,
    d: int,
    load_signals: Callable[[np.ndarray], np.ndarray],
) -> Bank:
    """A read-only :class:`Bank` from the columns id, name, duration, n_samples, degree,
    knots, ctrlpts, weights, points, origin, error_rms of one machine's rows (any order).

    ``load_signals(ids)`` reads the signals of these ids, in this order, on first use.
    """
    table, ids = in_id_order(table)
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
        points=flat(table.column("points")).reshape(-1, d),
        degrees=table.column("degree").to_numpy().astype(np.int64),
        knots=flat(table.column("knots")),
        knot_offsets=offsets_of(knots_arr.value_lengths().to_numpy(zero_copy_only=False)),
        ctrlpts=flat(table.column("ctrlpts")).reshape(-1, d),
        weights=flat(table.column("weights")),
        ctrl_offsets=offsets_of(weights_arr.value_lengths().to_numpy(zero_copy_only=False)),
        origins=_origins(table.column("origin").to_pylist(), d),
        errors=table.column("error_rms").to_numpy(zero_copy_only=False).astype(float),
        load_signals=lambda: load_signals(ids),
    )
    for value in vars(bank).values():
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
    return bank
