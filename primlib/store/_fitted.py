"""Models fitted to a machine's primitives, kept in the library file (schema version 7).

A warm start fits a grey-box and a refined model to the machine's stored pairs; on a
library learned on a machine with friction that takes most of a minute, and every process
(each ``primlib match --out``) paid it again. The models are derived data, so the table
holds them by a key that names everything they depend on (made by
:mod:`primlib.pipeline._fitted`, which also encodes them): a row either is the model for
that key or is never read. Keeping a new set for a machine drops the rows of any other set
of its primitives, so the table holds one set of primitives' models per machine.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import duckdb

from primlib._errors import LibraryBusyError
from primlib.store._connection import reading, transaction
from primlib.store._schema import utcnow

if TYPE_CHECKING:
    from primlib.store._store import Store

__all__ = ["read_fitted", "keep_fitted", "fitted_rows", "KEEP_PER_MACHINE"]

KEEP_PER_MACHINE = 64
"""Rows kept per machine (a warm start keeps three: the grey-box model, the refined model and
the grey-box model beside it; options such as ``modes`` add others); the oldest are dropped
beyond this."""


def read_fitted(store: Store, key: str) -> bytes | None:
    """The payload kept under ``key``, None when there is none."""
    with reading(store._label):
        # fetchall: a fetchone() leaves the result open and the connection refuses other work
        rows = (
            store._db()
            .sql("SELECT payload FROM fitted_models WHERE key = $k", params={"k": key})
            .fetchall()
        )
    return bytes(rows[0][0]) if rows else None


def keep_fitted(
    store: Store, machine: str, bank: str, code: str, rows: Sequence[tuple[str, str, bytes]]
) -> int:
    """Keep ``rows`` (key, kind, payload) fitted by primlib ``code`` to ``machine``'s
    primitive set ``bank`` in one transaction, dropping the machine's rows of any other set
    or code (never read again); the number of rows written.

    Raises
    ------
    InputError
        The store is open read-only.
    LibraryBusyError
        Another connection wrote the same rows at the same time (nothing written: a conflict
        or a duplicate key).
    """
    con = store._writable()
    now = utcnow()
    m = {"m": machine, "b": bank, "c": code}
    try:
        with transaction(con):
            con.execute(
                "DELETE FROM fitted_models WHERE machine = $m AND (bank <> $b OR code <> $c)", m
            )
            for key, kind, payload in rows:
                con.execute(
                    "INSERT OR REPLACE INTO fitted_models VALUES ($k, $m, $b, $c, $kind, $t, $p)",
                    {**m, "k": key, "kind": kind, "t": now, "p": payload},
                )
            con.execute(
                "DELETE FROM fitted_models WHERE machine = $m AND key NOT IN (SELECT key FROM "
                "fitted_models WHERE machine = $m ORDER BY created DESC, key LIMIT $n)",
                {"m": machine, "n": KEEP_PER_MACHINE},
            )
    except (duckdb.TransactionException, duckdb.ConstraintException) as exc:
        # another connection of this process wrote the same rows: a conflict at commit, or
        # (two server readers keeping one model, 1 in ~300 in a stress test) a duplicate key
        # at the insert -- which reached a client as an internal error
        raise LibraryBusyError(
            f"{store._label}: the fitted models were not kept (a concurrent write: {exc})"
        ) from None
    return len(rows)


def fitted_rows(store: Store, machine: str | None = None) -> list[tuple[str, str, str, int]]:
    """(machine, kind, key, payload bytes) of the kept models, of one machine or all."""
    sql = "SELECT machine, kind, key, octet_length(payload) FROM fitted_models"
    args: dict = {}
    if machine is not None:
        sql += " WHERE machine = $m"
        args["m"] = machine
    with reading(store._label):
        rel = store._db().sql(sql + " ORDER BY machine, kind, key", params=args or None)
        return [tuple(r) for r in rel.fetchall()]
