"""The ``machines`` table: one row per machine, its JSON definition the source of truth."""

from __future__ import annotations

import json
from datetime import UTC
from typing import Any

import duckdb

from primlib._errors import InputError, NotFoundError
from primlib.store._schema import utcnow

__all__ = ["machine_names", "machine_row", "put_machine", "delete_machine", "summaries"]


def machine_names(con: duckdb.DuckDBPyConnection) -> list[str]:
    """Names of the machines, sorted."""
    return [r[0] for r in con.sql("SELECT name FROM machines ORDER BY name").fetchall()]


def machine_row(con: duckdb.DuckDBPyConnection, name: str) -> tuple[float, list[str], str]:
    """(dt, axes, JSON definition) of a machine; NotFoundError naming the known ones."""
    if not isinstance(name, str):
        raise InputError(f"machine: expected a machine name, got {name!r}")
    rows = con.sql(
        "SELECT dt, axes, definition FROM machines WHERE name = $n", params={"n": name}
    ).fetchall()
    if not rows:
        known = ", ".join(machine_names(con)) or "no machines"
        raise NotFoundError(f"unknown machine {name!r}; the library has: {known}")
    dt, axes, definition = rows[0]
    return float(dt), list(axes), definition


def _count(con: duckdb.DuckDBPyConnection, name: str) -> int:
    return int(
        con.sql(
            "SELECT count(*) FROM primitives WHERE machine = $n", params={"n": name}
        ).fetchall()[0][0]
    )


def put_machine(
    con: duckdb.DuckDBPyConnection, d: dict[str, Any], replace: bool, label: str
) -> str:
    """Insert or replace a machine from its dictionary, inside the caller's transaction.

    Returns "added", "replaced" or "unchanged" (an identical definition is stored already).
    """
    name, dt, axes = d["name"], float(d["dt"]), [str(a) for a in d["axes"]]
    definition = json.dumps(d, sort_keys=True)
    rows = con.sql(
        "SELECT dt, axes, definition FROM machines WHERE name = $n", params={"n": name}
    ).fetchall()
    params = {"n": name, "k": d.get("kind", "lti"), "dt": dt, "a": axes, "d": definition}
    if not rows:
        con.execute(
            "INSERT INTO machines VALUES ($n, $k, $dt, $a, $d, $t)", {**params, "t": utcnow()}
        )
        return "added"
    old_dt, old_axes, old_definition = rows[0]
    if json.loads(old_definition) == json.loads(definition):
        return "unchanged"
    if not replace:
        raise InputError(
            f"machine {name!r} is already in {label} with another definition; "
            "replace it explicitly (replace=True, or --replace)"
        )
    count = _count(con, name)
    if count and (old_dt != dt or list(old_axes) != axes):
        raise InputError(
            f"machine {name!r} has {count} primitives stored at dt = {old_dt:g} s "
            f"on axes {', '.join(old_axes)}; its replacement must keep both, got "
            f"dt = {dt:g} s on axes {', '.join(axes)}"
        )
    con.execute(
        "UPDATE machines SET kind = $k, dt = $dt, axes = $a, definition = $d WHERE name = $n",
        params,
    )
    return "replaced"


def delete_machine(con: duckdb.DuckDBPyConnection, name: str, primitives: bool) -> int:
    """Delete a machine (and, when asked, its primitives) inside the caller's transaction."""
    count = _count(con, name)
    if count and not primitives:
        raise InputError(
            f"machine {name!r} has {count} primitives; remove them with it explicitly "
            "(primitives=True, or --with-primitives)"
        )
    con.execute("DELETE FROM primitives WHERE machine = $n", {"n": name})
    con.execute("DELETE FROM fitted_models WHERE machine = $n", {"n": name})
    con.execute("DELETE FROM machines WHERE name = $n", {"n": name})
    return count


def summaries(con: duckdb.DuckDBPyConnection) -> list[dict[str, Any]]:
    """One dict per machine: name, kind, dt, axes, primitives (count), added (UTC)."""
    rows = con.sql(
        "SELECT m.name, m.kind, m.dt, m.axes, count(p.id), m.added FROM machines m "
        "LEFT JOIN primitives p ON p.machine = m.name "
        "GROUP BY m.name, m.kind, m.dt, m.axes, m.added ORDER BY m.name"
    ).fetchall()
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
