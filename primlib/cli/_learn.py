"""``primlib learn``: ILC on a machine model from the library's warm start (or from zero).

The loop of the primitive-matching paper's figure 1: match the new path, splice the stored
signals into a first-iteration input, run ILC from it, and (``--ingest``) store the
converged input as a new primitive, so the library grows with every path it learns.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click
import numpy as np

from primlib._errors import InputError, NoMatchError
from primlib.cli import main

__all__ = ["learn", "example", "run_learning", "MASTER_SLAVE_LAWS"]

# laws of the master-slave PDCCILC paper: two-axis machines, primlib.ilc.learn_master_slave
MASTER_SLAVE_LAWS = ("tdilc", "tdccilc", "pdilc", "pdccilc")


def run_learning(
    lib,
    trajectory,
    machine_name: str,
    *,
    cold: bool,
    iterations: int,
    eps: float | None,
    band: float | None,
    law: str,
    tol: float | None,
    contour: bool = True,
) -> dict[str, Any]:
    """Warm start (unless ``cold``) and ILC on the machine model; everything the CLI reports.

    Returns
    -------
    dict
        ``machine`` (Machine), ``reference`` (n, d), ``t`` (n,), ``warm`` (WarmStart or None),
        ``start`` ("warm" / "cold"), ``result`` (ILCResult), ``contour`` (list or None),
        ``notes`` (list of str).
    """
    from primlib.ilc import learn as ilc_learn
    from primlib.ilc import learn_master_slave
    from primlib.match import default_eps
    from primlib.splice import warm_start

    m = lib.machine(machine_name)
    master_slave = law.lower() in MASTER_SLAVE_LAWS
    if master_slave and m.dim != 2:
        raise InputError(
            f"--law: expected a two-axis machine for the master-slave law {law!r}, got "
            f"machine '{machine_name}' with {m.dim} axes ({','.join(m.axes)})"
        )
    pts = trajectory.sample(m.dt)
    ref = pts - pts[0]
    t = np.arange(pts.shape[0]) * m.dt
    notes: list[str] = []
    ws = None
    u0 = None
    if not cold:
        e = eps if eps is not None else default_eps(trajectory)
        try:
            ws = warm_start(lib, trajectory, machine_name, e, band=band)
            u0 = ws.u
        except NoMatchError as exc:
            notes.append(f"no warm start ({exc}); starting from zero")
    if master_slave:
        # tol there is on the RMS estimated contour error (the law's own measure)
        res = learn_master_slave(m, ref, u0, law=law.lower(), iterations=iterations, tol=tol)
    else:
        # the convergence check is iterative beyond 400 samples (Lanczos on FFT operators):
        # no dense n x n SVD, long paths (n = 5000) check in about a second
        res = ilc_learn(
            m, ref, u0, law=law, iterations=iterations, tol=tol, contour=contour and m.dim >= 2
        )
    crms = None if res.rms_contour is None else [float(x) for x in res.rms_contour]
    return {
        "machine": m,
        "reference": ref,
        "t": t,
        "warm": ws,
        "start": "warm" if ws is not None else "cold",
        "result": res,
        "contour": crms,
        "notes": notes,
    }


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
    help="ILC trials at most.",
)
@click.option("--eps", type=float, help="Match tolerance (default: 3e-4 of the path's extent).")
@click.option("--band", type=float, help="Transition band width, seconds (default 8 dt).")
@click.option(
    "--law",
    default="norm-optimal",
    show_default=True,
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
    as_json: bool,
) -> None:
    """Learn the input for PATH (CSV t,x,y[,z]) by ILC on the machine's model.

    Starts from the library's warm start (match, time scale, superpose, splice) unless
    --cold; prints the RMS tracking (and contour) error per iteration; --ingest stores the
    converged input as a new primitive. Example:

    primlib learn data/paths/zigzag.csv --machine xyz --plot warm-start.png
    """
    from primlib.nurbs import Trajectory
    from primlib.store import Library

    if eps is not None and not eps > 0:
        raise InputError(f"--eps: expected a match tolerance > 0, got {eps}")
    if tol is not None and not tol > 0:
        raise InputError(f"--tol: expected a tolerance > 0, got {tol}")
    if band is not None and not band >= 0:
        raise InputError(f"--band: expected a width >= 0 s, got {band}")
    if not path.is_file():
        raise InputError(f"{path}: expected a path CSV file, got no such file")
    trajectory = Trajectory.from_csv(path)
    db = ctx.find_root().obj["db"]
    with Library(db, read_only=not ingest, create=False) as lib:
        run = run_learning(
            lib,
            trajectory,
            machine_name,
            cold=cold,
            iterations=iterations,
            eps=eps,
            band=band,
            law=law,
            tol=tol,
        )
        cold_run = None
        if plot_file is not None and run["start"] == "warm":
            cold_run = run_learning(
                lib,
                trajectory,
                machine_name,
                cold=True,
                iterations=iterations,
                eps=eps,
                band=band,
                law=law,
                tol=tol,
                contour=False,
            )
        res = run["result"]
        new_id = None
        if ingest:
            new_id = lib.add(
                trajectory,
                np.asarray(res.u),
                machine=machine_name,
                name=name or path.stem,
                source=f"{path} (primlib learn, {run['start']} start)",
            )
    if plot_file is not None:
        from primlib.plot._warm import plot_warm_start

        plot_warm_start(
            plot_file,
            trajectory.sample(run["machine"].dt),
            run["t"],
            run["warm"],
            np.asarray(res.rms_total),
            None if cold_run is None else np.asarray(cold_run["result"].rms_total),
            axes=run["machine"].axes,
        )
    rms = np.asarray(res.rms_total)
    crms = run["contour"]
    if as_json:
        out = {
            "path": str(path),
            "machine": machine_name,
            "start": run["start"],
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
            "warm_start": None if run["warm"] is None else run["warm"].to_dict(),
            "cold_rms": None
            if cold_run is None
            else np.asarray(cold_run["result"].rms_total).tolist(),
            "ingested": new_id,
            "notes": run["notes"],
        }
        click.echo(json.dumps(out))
        return
    for note in run["notes"]:
        click.echo(f"note: {note}", err=True)
    ws = run["warm"]
    if ws is not None:
        click.echo(f"warm start from {len(ws.match.segments)} segment(s):")
        for line in ws.sources:
            click.echo(f"  {line}")
    click.echo(
        f"{'iteration':>9}  {'rms':>12}" + ("" if crms is None else f"  {'contour rms':>12}")
    )
    for i in range(rms.size):
        line = f"{i:>9}  {rms[i]:>12.6g}"
        if crms is not None:
            line += f"  {crms[i]:>12.6g}"
        click.echo(line)
    stopped = getattr(res, "stopped", None)
    if stopped:
        click.echo(f"stopped: {stopped}")
    if new_id is not None:
        click.echo(f"stored primitive {new_id} ({name or path.stem}) for machine '{machine_name}'")
    if plot_file is not None:
        click.echo(f"wrote {plot_file}", err=True)
    sys.stdout.flush()


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
    yet, then runs ``primlib learn DATA/paths/PATH.csv --machine xyz --plot FIG``: match,
    warm start, ILC, and a figure of the path's segments, u0 with its junction bands, and
    the RMS per iteration warm vs cold.
    """
    from primlib.io import read_signal_csv
    from primlib.nurbs import Trajectory
    from primlib.plant import Machine
    from primlib.store import Library

    machine_file = data_dir / "machines" / "xyz.json"
    lib_dir = data_dir / "library"
    path = data_dir / "paths" / f"{path_name}.csv"
    for f in (machine_file, lib_dir, path):
        if not f.exists():
            raise InputError(
                f"{f}: expected the example data (run from a primlib clone, or "
                f"pass --data), got no such file"
            )
    machine = Machine.from_json(machine_file)
    files = sorted(f for f in lib_dir.glob("*.csv") if not f.name.endswith(".signal.csv"))
    db = ctx.find_root().obj["db"]
    with Library(db) as lib:
        if machine.name not in lib.machines():
            lib.add_machine(machine)
        if not lib.primitives(machine.name):
            items = []
            for f in files:
                traj = Trajectory.from_csv(f)
                t = traj.times(machine.dt)
                _, u = read_signal_csv(f.with_name(f"{f.stem}.signal.csv"), t=t)
                items.append((traj, u, f.stem, str(f)))
            lib.add_many(items, machine.name)
            click.echo(
                f"added {len(items)} example primitives to machine '{machine.name}' in {db}",
                err=True,
            )
    ctx.invoke(
        learn, path=path, machine_name=machine.name, iterations=iterations, plot_file=plot_file
    )
