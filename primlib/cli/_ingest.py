"""``primlib ingest``: store path files with their signals (or learn them) as primitives.

Every file is read, checked and fitted before the one write transaction, so one bad file
means nothing is written. The write lock is checked first (``--wait`` retries), so a busy
library is reported before any work. Ctrl-C leaves all or nothing and says which: during
reading, fitting or learning nothing has been written; during the write the interrupt is
held until the transaction decides — before the commit it rolls everything back, once the
commit has begun everything is stored.
"""

from __future__ import annotations

import signal as signals_module
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from primlib._errors import InputError
from primlib.cli import main
from primlib.cli._library import _db, _open_library, _open_waiting
from primlib.cli._options import parse_origins

if TYPE_CHECKING:
    import numpy as np

    from primlib.nurbs import Trajectory
    from primlib.plant import Machine
    from primlib.store import AddResult

# Commands import the computing packages when they run, so `primlib --help` and `primlib
# list` do not load scipy, the matcher and the learners.

__all__ = ["ingest"]

# Relative tolerance between a CSV file's time step and the machine's dt (the CSV reader's
# own tolerance on uniform spacing).
_DT_RTOL = 1e-6
# Exit status of a command stopped by Ctrl-C (128 + SIGINT), as shells report it.
_INTERRUPTED = 130


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
    path: Path, signal: Path | None, m: Machine, learn: bool
) -> tuple[Trajectory, np.ndarray | None]:
    """Read, check and fit one path (and read its signal); errors name the file."""
    from primlib.io import read_signal_csv
    from primlib.nurbs import Trajectory, read_path_samples

    t, points = read_path_samples(path, m.dt)
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


@contextmanager
def _interrupt_deferred() -> Iterator[threading.Event]:
    """Hold Ctrl-C (SIGINT) while the block runs; the event says whether one arrived."""
    arrived = threading.Event()
    main_thread = threading.current_thread() is threading.main_thread()
    # an ignored SIGINT (nohup, a background job) stays ignored: it must not cancel a write
    if not main_thread or signals_module.getsignal(signals_module.SIGINT) == signals_module.SIG_IGN:
        yield arrived
        return
    previous = signals_module.signal(signals_module.SIGINT, lambda *_: arrived.set())
    try:
        yield arrived
    finally:
        signals_module.signal(signals_module.SIGINT, previous)


def _read_all(ctx: click.Context, files, sigs, machine_name: str, learn: bool, iterations: int):
    """(path, trajectory, u) per file: read, checked, fitted (and learned), read-only."""
    # The library is open read-only meanwhile, so other readers are not locked out; the
    # write lock is taken only for the one transaction.
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
        if not learn:
            return read
        with click.progressbar(
            read, label="learning by ILC", file=sys.stderr, hidden=len(read) < 2
        ) as bar:
            return [
                (path, traj, lib.learn(traj, machine_name, iterations=iterations, contour=False).u)
                for path, traj, _ in bar
            ]


def _write(ctx: click.Context, items, machine_name: str, wait: float, allow: bool) -> AddResult:
    """The one write transaction, Ctrl-C held until it has committed or rolled back."""
    from primlib.store import WriteCancelled

    db = _db(ctx)
    with _interrupt_deferred() as interrupted:
        try:
            with _open_waiting(db, wait, create=False) as store:
                result = store.add_batch(
                    items, machine_name, allow_duplicates=allow, cancelled=interrupted.is_set
                )
        except WriteCancelled:
            click.echo(
                f"Interrupted: nothing was added to {db} (the write was rolled back)", err=True
            )
            ctx.exit(_INTERRUPTED)
    if interrupted.is_set():
        click.echo(
            f"Interrupt received after the commit had begun: the write completed, all "
            f"{result.added} new primitives are in {db}",
            err=True,
        )
    return result


def _report(ctx: click.Context, files, items, result: AddResult, machine_name: str) -> None:
    dup = set(result.duplicates)
    rows = zip(result.ids, files, items, strict=True)
    for i, (pid, path, (trajectory, _, nm, *_)) in enumerate(rows):
        if i in dup:
            click.echo(f"skipped {path}: identical to primitive {pid} (same path and signal)")
        else:
            click.echo(f"{pid:>6}  {nm}  ({trajectory.duration:g} s)")
    noun = "primitive" if result.added == 1 else "primitives"
    tail = f" ({len(dup)} already there, skipped; --allow-duplicates keeps them)" if dup else ""
    click.echo(f"added {result.added} {noun} to machine '{machine_name}' in {_db(ctx)}{tail}")


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
@click.option(
    "--origin",
    "origins",
    multiple=True,
    callback=parse_origins,
    metavar="X,Y[,Z]",
    help="Where the primitive ran: the machine's absolute position at the path's start when "
    "its signal was learned, one per PATH, in order (default: unknown).",
)
@click.option(
    "--allow-duplicates",
    is_flag=True,
    help="Store primitives identical to stored ones (same machine, path and signal) anyway.",
)
@click.option(
    "--wait",
    type=click.FloatRange(min=0),
    default=0,
    show_default=True,
    help="Seconds to keep retrying while another process holds the library.",
)
@click.pass_context
def ingest(
    ctx: click.Context,
    paths: tuple[str, ...],
    machine_name: str,
    signals: tuple[str, ...],
    learn: bool,
    iterations: int,
    name: str | None,
    origins: tuple[tuple[float, ...], ...],
    allow_duplicates: bool,
    wait: float,
) -> None:
    """Store paths (CSV: t,x,y[,z]) with their learned signals as primitives of a machine.

    Without --signal, a PATH named <stem>.signal.csv whose <stem>.csv is also
    given is taken as that path's signal, so a folder's *.csv can be ingested at
    once. Every file is read, checked and fitted before anything is written; then all of them go
    in as one transaction, so a single bad file leaves the library unchanged. Paths must be
    sampled at the machine's dt; each signal must lie on its path's time grid. A primitive
    already stored (same machine, path and signal) is skipped, saying so.

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
    if origins and len(origins) != len(paths):
        raise click.UsageError(
            f"got {len(origins)} --origin for {len(paths)} paths; give one per path, or none"
        )
    if name is not None and len(paths) > 1:
        raise click.UsageError(f"--name names one primitive, got {len(paths)} paths")
    from primlib.store import check_name

    check_name("--name", "the primitive's name", name)
    files = [Path(p) for p in paths]
    sigs: list[Path | None] = [Path(s) for s in signals] if signals else [None] * len(files)
    # the lock first: a busy library is reported (or waited for) before any work
    _open_waiting(_db(ctx), wait, create=False).close()
    try:
        read = _read_all(ctx, files, sigs, machine_name, learn, iterations)
    except KeyboardInterrupt:
        click.echo(f"Interrupted: nothing was added to {_db(ctx)}", err=True)
        ctx.exit(_INTERRUPTED)
    how = f" (learned by ILC, {iterations} iterations)" if learn else ""
    stems = [path.stem if name is None else name for path, _, _ in read]
    where = origins or (None,) * len(read)
    items = [
        (traj, u, nm, f"{path}{how}", origin)
        for (path, traj, u), nm, origin in zip(read, stems, where, strict=True)
    ]
    result = _write(ctx, items, machine_name, wait, allow_duplicates)
    _report(ctx, [path for path, _, _ in read], items, result, machine_name)
