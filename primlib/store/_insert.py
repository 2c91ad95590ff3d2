"""Writing a batch of primitives: check all, sample, drop duplicates, one Arrow insert.

Every item is checked before the first insert, so bad input never leaves half a batch
behind; the batch then goes in as a single Arrow table in one transaction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import duckdb
import numpy as np

from primlib._errors import InputError
from primlib.store._codec import INSERT_COLUMNS, batch_table
from primlib.store._connection import transaction
from primlib.store._schema import utcnow
from primlib.store._types import AddResult
from primlib.store._validate import check_item, content_hash, sample_points

__all__ = ["insert"]

# A batch with at least this many bytes of points and signals is written straight into the
# file at commit (a checkpoint) instead of through the write-ahead log (DuckDB's default
# checkpoint threshold is 16 MiB).
_DIRECT_BYTES = 16 * 2**20


def _check_all(
    items: Sequence[Sequence[Any]], machine: str, dt: float, axes: list[str], single: bool
) -> tuple[list[dict[str, Any]], np.ndarray, np.ndarray]:
    """Checked items, their paths on the grid (flat), and the sample offsets (in values)."""
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence):
        raise InputError(
            f"items: expected a list of (path, u, name, source), got {type(items).__name__}"
        )
    checked = [
        check_item(None if single else i, item, machine, dt, axes) for i, item in enumerate(items)
    ]
    d = len(axes)
    n = np.array([c["n"] for c in checked], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(n * d)]).astype(np.int64)
    points = sample_points(checked, dt, d, offsets)
    for i, c in enumerate(checked):
        c["hash"] = content_hash(
            machine, points[offsets[i] : offsets[i + 1]].reshape(-1, d), c["u"]
        )
    return checked, points, offsets


def _stored_hashes(
    con: duckdb.DuckDBPyConnection, machine: str, hashes: list[str]
) -> dict[str, int]:
    """Hash -> smallest id among the machine's stored primitives with one of these hashes."""
    rows = con.execute(
        "SELECT content_hash, min(id) FROM primitives WHERE machine = $m "
        "AND content_hash IN (SELECT unnest($h)) GROUP BY content_hash",
        {"m": machine, "h": sorted(set(hashes))},
    ).fetchall()
    return {h: int(i) for h, i in rows}


def _duplicates(checked: list[dict[str, Any]], stored: dict[str, int]) -> dict[int, int | str]:
    """Batch position -> the stored id it repeats, or the earlier item's hash it repeats."""
    seen: set[str] = set()
    out: dict[int, int | str] = {}
    for i, c in enumerate(checked):
        h = c["hash"]
        if h in stored:
            out[i] = stored[h]
        elif h in seen:
            out[i] = h
        seen.add(h)
    return out


def _write(
    con: duckdb.DuckDBPyConnection,
    k: int,
    make_table: Callable[[np.ndarray], Any],
    direct: bool,
    cancelled: Callable[[], bool] | None,
) -> np.ndarray:
    """Draw k ids and insert ``make_table(ids)`` in one transaction; return the ids."""
    threads = int(con.sql("SELECT current_setting('threads')").fetchall()[0][0])
    # One thread: the parallel (order-preserving) insert was 2-3x slower here.
    con.execute("SET threads = 1")
    registered = False
    try:
        with transaction(con, cancelled):
            seq = con.sql(f"SELECT nextval('primitive_ids') FROM range({k})").fetchall()
            ids = np.array([r[0] for r in seq], dtype=np.int64)
            con.register("_primlib_batch", make_table(ids))
            registered = True
            cols = ", ".join(INSERT_COLUMNS)
            con.execute(f"INSERT INTO primitives ({cols}) SELECT {cols} FROM _primlib_batch")
            if direct:
                # DuckDB's size estimate misses list contents, so a big batch would go to
                # the WAL first and be written again at the next checkpoint (close): a low
                # threshold makes the commit write it to the file once.
                con.execute("SET checkpoint_threshold = '1MiB'")
    finally:
        # after the rollback: an aborted transaction refuses even this
        if registered:
            con.unregister("_primlib_batch")
        if direct:
            con.execute("RESET checkpoint_threshold")
        con.execute(f"SET threads = {threads}")
    return ids


def insert(
    con: duckdb.DuckDBPyConnection,
    items: Sequence[Sequence[Any]],
    machine: str,
    dt: float,
    axes: list[str],
    *,
    single: bool,
    on_file: bool,
    allow_duplicates: bool = False,
    cancelled: Callable[[], bool] | None = None,
) -> AddResult:
    """Check, sample and store a batch of (path, u, name, source) items of one machine.

    Items identical to a stored primitive of the machine (or to an earlier item) are not
    written unless ``allow_duplicates``; the result says which. ``cancelled`` is asked just
    before the commit (see :func:`primlib.store._connection.transaction`).
    """
    if isinstance(items, Sequence) and not isinstance(items, (str, bytes)) and len(items) == 0:
        return AddResult(())
    checked, points, offsets = _check_all(items, machine, dt, axes, single)
    d = len(axes)
    dup: dict[int, int | str] = {}
    if not allow_duplicates:
        dup = _duplicates(checked, _stored_hashes(con, machine, [c["hash"] for c in checked]))
    keep = [i for i in range(len(checked)) if i not in dup]
    new_ids = np.zeros(0, dtype=np.int64)
    if keep:
        rows = [checked[i] for i in keep]
        flat_points, sub_offsets = points, offsets
        if len(keep) < len(checked):
            parts = [points[offsets[i] : offsets[i + 1]] for i in keep]
            sub_offsets = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
            flat_points = np.concatenate(parts)
        added = utcnow()

        def make_table(ids: np.ndarray) -> Any:
            return batch_table(ids, machine, dt, d, rows, flat_points, sub_offsets, added)

        direct = on_file and 2 * sub_offsets[-1] * 8 >= _DIRECT_BYTES
        new_ids = _write(con, len(rows), make_table, direct, cancelled)
    ids: dict[int, int] = {i: int(pid) for i, pid in zip(keep, new_ids, strict=True)}
    by_hash = {checked[i]["hash"]: ids[i] for i in reversed(keep)}
    for i, ref in dup.items():
        ids[i] = ref if isinstance(ref, int) else by_hash[ref]
    return AddResult(tuple(ids[i] for i in range(len(checked))), tuple(sorted(dup)))
