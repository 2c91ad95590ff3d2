"""Library commands: ``machine add/list/remove``, ``ingest``, ``list``, ``show``, ``remove``.

A thin layer: files are read by :mod:`primlib.io`, paths fitted by
:class:`primlib.nurbs.Trajectory`, and everything is stored by :class:`primlib.store.Store`
(``ingest --learn`` learns through :class:`primlib.pipeline.Library`).
``ingest`` reads and checks every file before its one write transaction, so one bad file
means nothing is written.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click
import numpy as np

from primlib._errors import InputError
from primlib.cli import main
from primlib.pipeline import Library
from primlib.store import Store

__all__ = ["machine", "ingest", "list_primitives", "show", "remove"]

# Relative tolerance between a CSV file's time step and the machine's dt (the CSV reader's
# own tolerance on uniform spacing).
_DT_RTOL = 1e-6


def _db(ctx: click.Context) -> str:
    return ctx.find_root().obj["db"]


def _open(ctx: click.Context, *, read_only: bool = False, create: bool = False) -> Store:
    """The store of ``--db`` (persistence only)."""
    return Store(_db(ctx), read_only=read_only, create=create)


def _open_library(ctx: click.Context, *, read_only: bool = False) -> Library:
    """The library of ``--db`` with the pipeline (match, warm start, learn)."""
    return Library(_db(ctx), read_only=read_only, create=False)


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
    """Add the machine described by FILE (machine JSON, see API.md) to the library.

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
    with _open(ctx, read_only=True) as lib:
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


# ---------------------------------------------------------------------------- ingest
def _signal_for(path: Path) -> Path:
    # glyph-a.csv -> glyph-a.signal.csv beside it
    return path.with_name(f"{path.stem}.signal.csv")


def _without_sibling_signals(paths: tuple[str, ...]) -> tuple[str, ...]:
    # `primlib ingest folder/*.csv` names glyph.csv and glyph.signal.csv: the second is the
    # first one's signal, not a path.
    given = {Path(p).resolve() for p in paths}
    return tuple(
        p
        for p in paths
        if not (
            Path(p).name.endswith(".signal.csv")
            and Path(p).with_name(Path(p).name[: -len(".signal.csv")] + ".csv").resolve() in given
        )
    )


def _read_one(
    path: Path, signal: Path | None, m: Any, learn: bool
) -> tuple[Any, np.ndarray | None]:
    """Read, check and fit one path (and read its signal); errors name the file."""
    from primlib.io import read_path_csv, read_signal_csv
    from primlib.nurbs import Trajectory

    t, points = read_path_csv(path)
    dt = (t[-1] - t[0]) / (len(t) - 1)
    if abs(dt - m.dt) > _DT_RTOL * m.dt:
        raise InputError(
            f"{path}: expected samples at the dt of machine '{m.name}' ({m.dt:g} s), "
            f"got dt = {dt:.9g} s"
        )
    if points.shape[1] != m.dim:
        raise InputError(
            f"{path}: expected a {m.dim}-D path for machine '{m.name}' (axes "
            f"{', '.join(m.axes)}), got {points.shape[1]} coordinates"
        )
    u = None
    if not learn:
        if signal is None:
            signal = _signal_for(path)
            if not signal.exists():
                raise InputError(
                    f"{path}: expected its signal in {signal} (or --signal FILE, or --learn), "
                    "got no such file"
                )
        _, u = read_signal_csv(signal, t=t)
        if u.shape[1] != m.dim:
            raise InputError(
                f"{signal}: expected {m.dim} signal columns for machine '{m.name}', "
                f"got {u.shape[1]}"
            )
    try:
        trajectory = Trajectory.from_samples(points, m.dt)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
    return trajectory, u


@main.command()
@click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option(
    "--machine", "-m", "machine_name", required=True, help="Machine the signals belong to."
)
@click.option(
    "--signal",
    "-s",
    "signals",
    multiple=True,
    type=click.Path(dir_okay=False),
    help="Signal CSV (t,ux,uy[,uz]) for a path; give one per PATH, in order. "
    "Without any, each PATH's signal is read from <stem>.signal.csv beside it "
    "(glyph.csv -> glyph.signal.csv).",
)
@click.option(
    "--learn", is_flag=True, help="Learn each signal by ILC on the machine's model instead."
)
@click.option(
    "--iterations",
    type=click.IntRange(min=1),
    default=30,
    show_default=True,
    help="ILC trials with --learn.",
)
@click.option("--name", help="Name of the primitive (one PATH only); default: the file's stem.")
@click.pass_context
def ingest(
    ctx: click.Context,
    paths: tuple[str, ...],
    machine_name: str,
    signals: tuple[str, ...],
    learn: bool,
    iterations: int,
    name: str | None,
) -> None:
    """Store paths (CSV: t,x,y[,z]) with their learned signals as primitives of a machine.

    Without --signal, a PATH named <stem>.signal.csv whose <stem>.csv is also
    given is taken as that path's signal, so a folder's *.csv can be ingested at
    once. Every file is read, checked and fitted before anything is written; then all of them go
    in as one transaction, so a single bad file leaves the library unchanged. Paths must be
    sampled at the machine's dt; each signal must lie on its path's time grid.

    \b
    primlib ingest glyph.csv --signal glyph-u.csv --machine xyz
    primlib ingest data/library/*.csv --machine xyz   # each with <stem>.signal.csv
    primlib ingest glyph.csv --learn --machine xyz    # learn the signal by ILC
    """
    if learn and signals:
        raise click.UsageError("--learn and --signal are mutually exclusive")
    if not signals:
        paths = _without_sibling_signals(paths)
    if signals and len(signals) != len(paths):
        raise click.UsageError(
            f"got {len(signals)} --signal for {len(paths)} paths; give one per path, or none "
            "to read <stem>.signal.csv beside each"
        )
    if name is not None and len(paths) > 1:
        raise click.UsageError(f"--name names one primitive, got {len(paths)} paths")
    files = [Path(p) for p in paths]
    sigs: list[Path | None] = [Path(s) for s in signals] if signals else [None] * len(files)

    # Read, check and fit every file (and learn) with the library open read-only, so other
    # readers are not locked out meanwhile; take the write lock only for the one transaction.
    with _open_library(ctx, read_only=True) as lib:
        m = lib.machine(machine_name)
        read = []
        with click.progressbar(
            list(zip(files, sigs, strict=True)),
            label=f"reading {len(files)} paths",
            file=sys.stderr,
            hidden=len(files) < 2,
        ) as bar:
            for path, signal in bar:
                read.append((path, *_read_one(path, signal, m, learn)))
        if learn:
            with click.progressbar(
                read, label="learning by ILC", file=sys.stderr, hidden=len(read) < 2
            ) as bar:
                read = [
                    (
                        path,
                        traj,
                        lib.learn(traj, machine_name, iterations=iterations, contour=False).u,
                    )
                    for path, traj, _ in bar
                ]
    how = f" (learned by ILC, {iterations} iterations)" if learn else ""
    items = [(traj, u, name or path.stem, f"{path}{how}") for path, traj, u in read]
    with _open(ctx) as lib:
        ids = lib.add_many(items, machine_name)
    for pid, (trajectory, _, nm, _) in zip(ids, items, strict=True):
        click.echo(f"{pid:>6}  {nm}  ({trajectory.duration:g} s)")
    noun = "primitive" if len(ids) == 1 else "primitives"
    click.echo(f"added {len(ids)} {noun} to machine '{machine_name}' in {_db(ctx)}")


# ---------------------------------------------------------------------------- list/show/remove
@main.command("list")
@click.option("--machine", "-m", "machine_name", help="Only this machine's primitives.")
@click.option("--json", "as_json", is_flag=True, help="Print a JSON array instead of a table.")
@click.pass_context
def list_primitives(ctx: click.Context, machine_name: str | None, as_json: bool) -> None:
    """List the stored primitives: id, name, machine, duration, samples, source, added."""
    with _open(ctx, read_only=True) as lib:
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
    with _open(ctx, read_only=True) as lib:
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
