"""Library commands: ``machine add/list/remove``, ``list``, ``show``, ``remove``.

A thin layer: files are read by :mod:`primlib.io`, paths fitted by
:class:`primlib.nurbs.Trajectory`, and everything is stored by :class:`primlib.store.Store`
(``match`` and ``learn`` open a :class:`primlib.pipeline.Library`). ``ingest`` lives in
:mod:`primlib.cli._ingest`.
"""

from __future__ import annotations

import json
import time
from typing import TYPE_CHECKING, Any

import click

from primlib._errors import LibraryBusyError
from primlib.cli import main
from primlib.cli._output import TABLE_FORMATS, check_output

if TYPE_CHECKING:
    from primlib.pipeline import Library
    from primlib.store import Store

# Commands import the computing packages when they run, so `primlib --help` and `primlib
# list` do not load scipy, the matcher and the learners.

__all__ = ["machine", "list_primitives", "show", "remove"]


def _db(ctx: click.Context) -> str:
    obj = ctx.find_root().obj
    return obj.get("remote") or obj["db"]


def _remote(ctx: click.Context, allowed: bool) -> Any:
    """With ``--remote URL``: a :class:`primlib.client.Client` (the library's method names)
    for a read command that passes ``remote=True``; any other command is refused."""
    url = ctx.find_root().obj.get("remote")
    if not url:
        return None
    if not allowed:
        raise click.UsageError(
            f"--remote: '{ctx.command_path}' works on a library file (--db); against a "
            "server only list, show, match, machine list and trials status, list and input run"
        )
    from primlib.client import Client

    return Client(url)


def _open(
    ctx: click.Context, *, read_only: bool = False, create: bool = False, remote: bool = False
) -> Store:
    """The store of ``--db`` (persistence only), or the server of ``--remote``."""
    from primlib.store import Store

    return _remote(ctx, remote) or Store(_db(ctx), read_only=read_only, create=create)


def _open_library(ctx: click.Context, *, read_only: bool = False, remote: bool = False) -> Library:
    """The library of ``--db`` with the pipeline (match, warm start, learn), or the server
    of ``--remote``."""
    from primlib.pipeline import Library

    return _remote(ctx, remote) or Library(_db(ctx), read_only=read_only, create=False)


def _open_waiting(db: str, wait: float, **kw: Any) -> Store:
    """Open the store, retrying while another process holds it, for up to ``wait`` seconds.

    Raises
    ------
    LibraryBusyError
        Still busy after ``wait`` seconds (at once for ``wait = 0``).
    """
    from primlib.store import Store

    deadline = time.monotonic() + wait
    while True:
        try:
            return Store(db, **kw)
        except LibraryBusyError as exc:
            left = deadline - time.monotonic()
            if left <= 0:
                if wait > 0:
                    raise LibraryBusyError(f"{exc} (waited {wait:g} s)") from None
                raise
            time.sleep(min(0.2, left))


def _table(headers: list[str], rows: list[list[str]], right: set[int]) -> str:
    """A plain aligned text table (numbers right-aligned)."""
    widths = [
        max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)
    ]

    def line(cells: list[str]) -> str:
        out = [
            c.rjust(w) if i in right else c.ljust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        ]
        return "  ".join(out).rstrip()

    return "\n".join([line(headers), line(["-" * w for w in widths]), *(line(r) for r in rows)])


def _when(added: Any) -> str:
    return added.strftime("%Y-%m-%d %H:%M:%S")


# ---------------------------------------------------------------------------- machines
@main.group("machine")
def machine() -> None:
    """Machines: the axes, sample time and model that a library's signals belong to."""


@machine.command("add")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--replace", is_flag=True, help="Overwrite a different machine of the same name.")
@click.pass_context
def machine_add(ctx: click.Context, file: str, replace: bool) -> None:
    """Add the machine described by FILE (machine JSON, see docs/files.rst) to the library.

    Creates the library file if there is none. Adding an identical machine again changes
    nothing; a different one of the same name needs --replace (refused while it has
    primitives and its dt or axes would change).
    """
    from primlib.plant import Machine

    m = Machine.from_json(file)
    with _open(ctx, create=True) as lib:
        status = lib.add_machine(m, replace=replace)
    where = _db(ctx)
    axes = ", ".join(m.axes)
    if status == "unchanged":
        click.echo(f"machine '{m.name}' is already in {where}, unchanged")
    else:
        click.echo(f"{status} machine '{m.name}' (dt = {m.dt:g} s, axes {axes}) in {where}")


@machine.command("list")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON array instead of a table.")
@click.pass_context
def machine_list(ctx: click.Context, as_json: bool) -> None:
    """List the library's machines with their sample time, axes and primitive count."""
    with _open(ctx, read_only=True, remote=True) as lib:
        rows = lib.machine_summaries()
    if as_json:
        for r in rows:
            r["added"] = r["added"].isoformat()
        click.echo(json.dumps(rows, indent=2))
        return
    if not rows:
        click.echo(f"no machines in {_db(ctx)}")
        return
    body = [
        [
            r["name"],
            r["kind"],
            f"{r['dt']:g}",
            ",".join(r["axes"]),
            str(r["primitives"]),
            _when(r["added"]),
        ]
        for r in rows
    ]
    click.echo(
        _table(["name", "kind", "dt [s]", "axes", "primitives", "added (UTC)"], body, {2, 4})
    )


@machine.command("remove")
@click.argument("name")
@click.option("--with-primitives", is_flag=True, help="Also remove the primitives learned on it.")
@click.pass_context
def machine_remove(ctx: click.Context, name: str, with_primitives: bool) -> None:
    """Remove machine NAME (refused while it has primitives, unless --with-primitives)."""
    with _open(ctx) as lib:
        count = lib.remove_machine(name, primitives=with_primitives)
    extra = f" and its {count} primitives" if count else ""
    click.echo(f"removed machine '{name}'{extra} from {_db(ctx)}")


# ---------------------------------------------------------------------------- list/show/remove
@main.command("list")
@click.option("--machine", "-m", "machine_name", help="Only this machine's primitives.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON array instead of a table.")
@click.pass_context
def list_primitives(ctx: click.Context, machine_name: str | None, as_json: bool) -> None:
    """List the stored primitives: id, name, machine, duration, samples, source, added."""
    with _open(ctx, read_only=True, remote=True) as lib:
        infos = lib.primitives(machine=machine_name)
    if as_json:
        click.echo(json.dumps([p.to_dict() for p in infos], indent=2))
        return
    if not infos:
        click.echo(f"no primitives in {_db(ctx)}")
        return
    rows = [
        [
            str(p.id),
            p.name or "",
            p.machine,
            f"{p.duration:.3f}",
            str(p.n_samples),
            p.source or "",
            _when(p.added),
        ]
        for p in infos
    ]
    headers = ["id", "name", "machine", "duration [s]", "samples", "source", "added (UTC)"]
    click.echo(_table(headers, rows, {0, 3, 4}))


@main.command()
@click.argument("id", type=int)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object (with the NURBS).")
@click.option(
    "--signal-out",
    type=click.Path(dir_okay=False),
    help="Also write the stored signal as CSV (t,ux,uy[,uz]).",
)
@click.option(
    "--path-out",
    type=click.Path(dir_okay=False),
    help="Also write the stored path samples as CSV (t,x,y[,z]).",
)
@click.pass_context
def show(
    ctx: click.Context, id: int, as_json: bool, signal_out: str | None, path_out: str | None
) -> None:
    """Show one primitive: metadata, its NURBS and its signal's size per axis."""
    import numpy as np

    check_output("--signal-out", signal_out, TABLE_FORMATS)
    check_output("--path-out", path_out, TABLE_FORMATS)
    with _open(ctx, read_only=True, remote=True) as lib:
        p = lib.get(id)
        axes = lib.machine(p.machine).axes
    traj = p.trajectory
    rms = np.sqrt(np.mean(p.signal**2, axis=0))
    peak = np.max(np.abs(p.signal), axis=0)
    if signal_out or path_out:
        from primlib.io import write_path_csv, write_signal_csv

        if signal_out:
            write_signal_csv(signal_out, p.times(), p.signal)
        if path_out:
            write_path_csv(path_out, p.times(), p.points)
    if as_json:
        d = p.to_dict()
        d["axes"] = list(axes)
        d["nurbs"] = {
            "degree": traj.degree,
            "knots": traj.knots.tolist(),
            "ctrlpts": traj.ctrlpts.tolist(),
            "weights": traj.weights.tolist(),
        }
        d["signal_rms"] = dict(zip(axes, rms.tolist(), strict=True))
        d["signal_peak"] = dict(zip(axes, peak.tolist(), strict=True))
        click.echo(json.dumps(d, indent=2))
        return
    start, end = p.points[0], p.points[-1]
    fmt = lambda a: "(" + ", ".join(f"{x:.6g}" for x in a) + ")"  # noqa: E731
    lines = [
        f"primitive {p.id}: {p.name or '(unnamed)'}",
        f"  machine    {p.machine} (axes {', '.join(axes)})",
        f"  duration   {p.duration:g} s, {p.n_samples} samples at dt = {p.dt:g} s",
        f"  source     {p.source or ''}",
        f"  added      {_when(p.added)} UTC",
        f"  nurbs      degree {traj.degree}, {len(traj.weights)} control points, "
        f"{'rational' if traj.rational else 'non-rational'}, extent {traj.extent:.6g}",
        f"  path       from {fmt(start)} to {fmt(end)}",
        f"  origin     {'unknown' if p.origin is None else fmt(p.origin)} (where it ran)",
        f"  error      {'unknown' if p.error_rms is None else f'{p.error_rms:.4g}'} (RMS "
        "tracking error its signal leaves where it ran, noise aside)",
        "  signal     "
        + ", ".join(
            f"{a}: rms {r:.4g}, peak {k:.4g}" for a, r, k in zip(axes, rms, peak, strict=True)
        ),
    ]
    click.echo("\n".join(lines))


@main.command()
@click.argument("id", type=int)
@click.pass_context
def remove(ctx: click.Context, id: int) -> None:
    """Remove primitive ID from the library (ids are never reused)."""
    with _open(ctx) as lib:
        info = lib.info(id)
        lib.remove(id)
    click.echo(
        f"removed primitive {id} ({info.name or 'unnamed'}, machine '{info.machine}') "
        f"from {_db(ctx)}"
    )
