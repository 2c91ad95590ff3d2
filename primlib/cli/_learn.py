"""``primlib learn``: ILC on a machine model from the library's warm start (or from zero).

The loop of the primitive-matching paper's figure 1: match the new path, splice the stored
signals into a first-iteration input, run ILC from it, and (``--ingest``) store the
converged input as a new primitive, so the library grows with every path it learns.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from primlib._errors import InputError
from primlib.cli import main
from primlib.cli._library import _open_waiting
from primlib.cli._options import parse_origin
from primlib.cli._output import FIGURE_FORMATS, check_output, segment_lines
from primlib.cli._progress import match_progress
from primlib.pipeline import LAWS

if TYPE_CHECKING:
    from primlib.pipeline import LearnRun

# Commands import the computing packages when they run, so `primlib --help` and `primlib
# list` do not load scipy, the matcher and the learners.

__all__ = ["learn", "example"]

# How long `learn --ingest` waits for readers to let go of the file before it stores (s).
STORE_WAIT = 30.0


def _check_options(eps: float | None, tol: float | None, band: float | None) -> None:
    if eps is not None and not eps > 0:
        raise InputError(f"--eps: expected a match tolerance > 0, got {eps}")
    if tol is not None and not tol > 0:
        raise InputError(f"--tol: expected a tolerance > 0, got {tol}")
    if band is not None and not band >= 0:
        raise InputError(f"--band: expected a width >= 0 s, got {band}")


def _as_json(path: Path, machine_name: str, run: LearnRun, cold: LearnRun | None, new_id) -> str:
    import numpy as np

    res = run.result
    rms, crms = np.asarray(res.rms_total), run.contour
    return json.dumps(
        {
            "path": str(path),
            "machine": machine_name,
            "start": run.start,
            "iterations": [
                {
                    "iteration": i,
                    "rms": float(rms[i]),
                    "rms_axes": np.asarray(res.rms)[i].tolist(),
                    "contour_rms": None if crms is None else crms[i],
                }
                for i in range(rms.size)
            ],
            "stopped": getattr(res, "stopped", None),
            "warm_start": None if run.warm is None else run.warm.to_dict(),
            "cold_rms": None if cold is None else np.asarray(cold.result.rms_total).tolist(),
            "ingested": new_id,
            "notes": list(run.notes),
        }
    )


def _as_text(run: LearnRun) -> list[str]:
    """The warm start's segments and the RMS per trial; row 0 is labelled as the start."""
    import numpy as np

    lines = []
    if run.warm is not None:
        lines.append(f"warm start from {len(run.warm.match.segments)} segment(s):")
        lines += [f"  {line}" for line in segment_lines(run.warm.sources)]
    rms, crms = np.asarray(run.result.rms_total), run.contour
    lines.append(
        f"{'iteration':>9}  {'rms':>12}" + ("" if crms is None else f"  {'contour rms':>12}")
    )
    start = "(warm start, before learning)" if run.warm is not None else "(zero input)"
    for i in range(rms.size):
        line = f"{i:>9}  {rms[i]:>12.6g}"
        if crms is not None:
            line += f"  {crms[i]:>12.6g}"
        lines.append(line + (f"  {start}" if i == 0 else ""))
    stopped = getattr(run.result, "stopped", None)
    if stopped:
        lines.append(f"stopped: {stopped}")
    return lines


def _plot(plot_file: Path, trajectory, run: LearnRun, cold: LearnRun | None) -> None:
    import numpy as np

    from primlib.plot import plot_warm_start

    plot_warm_start(
        plot_file,
        trajectory.sample(run.machine.dt),
        run.t,
        run.warm,
        np.asarray(run.result.rms_total),
        None if cold is None else np.asarray(cold.result.rms_total),
        axes=run.machine.axes,
    )


@main.command("learn")
@click.argument("path", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--machine", "-m", "machine_name", required=True, help="Machine name.")
@click.option("--cold", is_flag=True, help="Start ILC from zero instead of the warm start.")
@click.option(
    "--iterations",
    "-n",
    default=20,
    show_default=True,
    type=click.IntRange(min=1),
    help="ILC trials at most (the table also shows trial 0, the start).",
)
@click.option("--eps", type=float, help="Match tolerance (default: 3e-4 of the path's extent).")
@click.option("--band", type=float, help="Transition band width, seconds (default 8 dt).")
@click.option(
    "--law",
    default="norm-optimal",
    show_default=True,
    type=click.Choice(LAWS, case_sensitive=False),
    help="ILC law: p, pd, pid, norm-optimal (primlib.ilc.learn) or, on a two-axis machine, "
    "the master-slave tdilc, tdccilc, pdilc, pdccilc (primlib.ilc.learn_master_slave).",
)
@click.option(
    "--tol",
    type=float,
    help="Stop when the RMS tracking error (master-slave laws: contour error) is below this.",
)
@click.option("--ingest", is_flag=True, help="Store the converged input as a new primitive.")
@click.option("--name", help="Name of the stored primitive (default: the file's stem).")
@click.option(
    "--plot",
    "plot_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Write a figure: path and segments, u0 with bands, RMS warm vs cold.",
)
@click.option(
    "--origin",
    metavar="X,Y[,Z]",
    callback=parse_origin,
    help="Where the path starts on the machine, absolute: the warm start's grey-box model "
    "evaluates its position-dependent terms (force ripple) there. Default: unknown.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.pass_context
def learn(
    ctx: click.Context,
    path: Path,
    machine_name: str,
    cold: bool,
    iterations: int,
    eps: float | None,
    band: float | None,
    law: str,
    tol: float | None,
    ingest: bool,
    name: str | None,
    plot_file: Path | None,
    origin: tuple[float, ...] | None,
    as_json: bool,
) -> None:
    """Learn the input for PATH (CSV t,x,y[,z]) by ILC on the machine's model.

    Starts from the library's warm start (match, time scale, superpose, splice) unless
    --cold; prints the RMS tracking (and contour) error per iteration, iteration 0 being
    the start itself; --ingest stores the converged input as a new primitive. Example:

    primlib learn data/paths/zigzag.csv --machine xyz --plot warm-start.png
    """
    from primlib.cli._machine_fit import keep_models
    from primlib.nurbs import read_path
    from primlib.pipeline import Library, check_law, store_learned
    from primlib.store import check_name

    _check_options(eps, tol, band)
    if not path.is_file():
        raise InputError(f"{path}: expected a path CSV file, got no such file")
    check_output("--plot", plot_file, FIGURE_FORMATS, inputs=[path])
    stored_name = path.stem if name is None else name
    if ingest:
        check_name("--name", "the primitive's name", stored_name)
    trajectory = read_path(path)
    db = ctx.find_root().obj["db"]
    opts = {"iterations": iterations, "eps": eps, "band": band, "law": law, "tol": tol}
    if origin is not None:
        opts["origin"] = origin
    opts["progress"] = match_progress()  # a long path's match shows its progress
    # Learn with the library open read-only (other readers and writers are not locked out
    # for the whole run); take the write lock only to store the result.
    with Library(db, read_only=True, create=False) as lib:
        check_law(law, lib.machine(machine_name), option="--law")
        run = lib.starter.learn(trajectory, machine_name, cold=cold, **opts)
        cold_run = None
        if plot_file is not None and run.start == "warm":
            cold_run = lib.starter.learn(trajectory, machine_name, cold=True, contour=False, **opts)
    new_id = None
    if ingest:
        # Readers open the file for moments; after a learning run that may have taken minutes,
        # wait for them rather than throw the result away.
        with _open_waiting(db, STORE_WAIT, create=False) as store:
            new_id = store_learned(
                store,
                run,
                trajectory,
                machine_name,
                name=stored_name,
                source=f"{path} (primlib learn, {run.start} start)",
            )
    # the models are fitted on the library as it last stood at a quarter's growth: the stored
    # primitive leaves them valid below the next such size (and beyond, the rows kept are
    # never read, and go with the next keep)
    keep_models(db, lib, say=not as_json)
    if plot_file is not None:
        _plot(plot_file, trajectory, run, cold_run)
    if as_json:
        click.echo(_as_json(path, machine_name, run, cold_run, new_id))
        return
    for note in run.notes:
        click.echo(f"note: {note}", err=True)
    click.echo("\n".join(_as_text(run)))
    if new_id is not None:
        click.echo(f"stored primitive {new_id} ({stored_name}) for machine '{machine_name}'")
    if plot_file is not None:
        click.echo(f"wrote {plot_file}", err=True)
    sys.stdout.flush()


def _example_files(data_dir: Path, path_name: str) -> tuple[Path, Path, Path]:
    """The example's machine JSON, library folder and path CSV, or one sentence why not."""
    machine_file = data_dir / "machines" / "xyz.json"
    lib_dir = data_dir / "library"
    for f in (machine_file, lib_dir):
        if not f.exists():
            raise InputError(
                f"{f}: expected the example data (run from a primlib clone, or "
                f"pass --data), got no such file"
            )
    path = data_dir / "paths" / f"{path_name}.csv"
    if not path.is_file():
        names = sorted(p.stem for p in (data_dir / "paths").glob("*.csv"))
        raise InputError(
            f"--path: expected one of the example paths in {data_dir / 'paths'} "
            f"({', '.join(names) or 'none'}), got {path_name!r}"
        )
    return machine_file, lib_dir, path


def _add_example_library(db: str, machine, lib_dir: Path) -> int:
    """Add the example machine and bundled primitives when missing; how many were added."""
    from primlib.io import read_signal_csv
    from primlib.nurbs import Trajectory
    from primlib.store import Store

    files = sorted(f for f in lib_dir.glob("*.csv") if not f.name.endswith(".signal.csv"))
    with Store(db) as lib:
        if machine.name not in lib.machines():
            lib.add_machine(machine)
        elif lib.machine(machine.name).to_dict() != machine.to_dict():
            raise InputError(
                f"{db}: machine '{machine.name}' there has another model than the example's "
                f"({lib_dir.parent / 'machines' / 'xyz.json'}); the example's primitives would "
                "not fit it, so nothing was added (use another --db)"
            )
        if lib.primitives(machine.name):
            return 0
        items = []
        for f in files:
            traj = Trajectory.from_csv(f)
            _, u = read_signal_csv(f.with_name(f"{f.stem}.signal.csv"), t=traj.times(machine.dt))
            items.append((traj, u, f.stem, str(f)))
        return len(lib.add_many(items, machine.name))


@main.command("example")
@click.option(
    "--data",
    "data_dir",
    default="data",
    show_default=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="The repository's data folder (machines/, library/, paths/).",
)
@click.option(
    "--path",
    "path_name",
    default="glyph-chain",
    show_default=True,
    help="Which example path of DATA/paths to learn.",
)
@click.option("--iterations", "-n", default=8, show_default=True, type=click.IntRange(min=1))
@click.option(
    "--plot",
    "plot_file",
    default="warm-start.png",
    show_default=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Figure to write.",
)
@click.pass_context
def example(
    ctx: click.Context, data_dir: Path, path_name: str, iterations: int, plot_file: Path
) -> None:
    """Build the example library from DATA and learn an example path from its warm start.

    Adds the XYZ machine of the primitive-matching paper and the bundled primitives
    (DATA/library/<stem>.csv with <stem>.signal.csv) to the library when they are not there
    yet (refused when the library's machine xyz has another model), then runs ``primlib
    learn DATA/paths/PATH.csv --machine xyz --plot FIG``: match, warm start, ILC, and a
    figure of the path's segments, u0 with its junction bands, and the RMS per iteration
    warm vs cold.
    """
    from primlib.plant import Machine

    machine_file, lib_dir, path = _example_files(data_dir, path_name)
    check_output("--plot", plot_file, FIGURE_FORMATS)
    machine = Machine.from_json(machine_file)
    db = ctx.find_root().obj["db"]
    added = _add_example_library(db, machine, lib_dir)
    if added:
        click.echo(
            f"added {added} example primitives to machine '{machine.name}' in {db}", err=True
        )
    ctx.invoke(
        learn, path=path, machine_name=machine.name, iterations=iterations, plot_file=plot_file
    )
