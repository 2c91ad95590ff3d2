"""``primlib trials``: learning on a real stage, one trial at a time, kept in the library.

``start`` writes the first input and records the series; after each run on the stage,
``step`` reads the measured output and writes the next input; ``status`` prints the errors
per trial and the stop rule's verdict; ``finish`` stores the converged pair as a primitive;
``run`` does the loop with a program that runs one trial (``--trial-command``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import click

from primlib._errors import InputError
from primlib.cli import main
from primlib.cli._library import _remote
from primlib.cli._output import TABLE_FORMATS, check_output

if TYPE_CHECKING:  # numpy is imported where a command runs: `--help` stays fast
    import numpy as np

__all__ = ["trials"]

_LAW_CHOICES = ("p", "pd", "pid", "norm-optimal")


def _db(ctx: click.Context) -> str:
    _remote(ctx, False)  # with --remote only status, list and input run (on the server)
    return ctx.find_root().obj["db"]


def _default_out(series: int, trial: int) -> Path:
    return Path(f"series{series}-trial{trial}-input.csv")


def _write_input(out: Path, t: np.ndarray, u: np.ndarray) -> None:
    from primlib.io import write_signal_csv

    write_signal_csv(out, t, u)


def _fmt(x: float | None, spec: str = ".6g") -> str:
    return "-" if x is None else format(x, spec)


@main.group("trials")
def trials() -> None:
    """Trial series on a real stage: start, step, status, finish, run."""


@trials.command("start")
@click.argument("path", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--machine", "-m", "machine_name", required=True, help="Machine name.")
@click.option(
    "--warm/--cold",
    default=True,
    show_default=True,
    help="First input from the library's warm start (the model inverse where nothing "
    "matches), or zero.",
)
@click.option(
    "--inverse", is_flag=True, help="First input from the model inverse (for comparison)."
)
@click.option("--law", type=click.Choice(_LAW_CHOICES), default="norm-optimal", show_default=True)
@click.option(
    "--plain",
    is_flag=True,
    help="The plain law: learn from the last error only (no averaging, no Q from the trials).",
)
@click.option(
    "--average",
    type=click.IntRange(min=1),
    help="Trials averaged per update (default 8; --plain: 1).",
)
@click.option(
    "--margin",
    type=float,
    default=0.2,
    show_default=True,
    help="Stop rule: converged when the repeatable error is within MARGIN x the noise floor.",
)
@click.option("--q-cutoff", type=float, help="A fixed Q-filter cut-off in Hz (plain law).")
@click.option("--eps", type=float, help="Match tolerance (default: 3e-4 of the path's extent).")
@click.option("--name", help="Name of the series (and of the primitive it finishes as).")
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The first input (signal CSV); default series<ID>-trial0-input.csv.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.pass_context
def start_cmd(
    ctx: click.Context,
    path: Path,
    machine_name: str,
    warm: bool,
    inverse: bool,
    law: str,
    plain: bool,
    average: int | None,
    margin: float,
    q_cutoff: float | None,
    eps: float | None,
    name: str | None,
    out: Path | None,
    as_json: bool,
) -> None:
    """Start a trial series for PATH (CSV t,x,y[,z], the machine's absolute coordinates).

    Writes the first input to run on the stage and records the series. Example:

    primlib trials start glyph.csv --machine stage --out u0.csv
    """
    from primlib.nurbs import Trajectory
    from primlib.pipeline import Library
    from primlib.trials import start

    check_output("--out", out, TABLE_FORMATS, inputs=[path])
    if eps is not None and not eps > 0:
        raise InputError(f"--eps: expected a match tolerance > 0, got {eps}")
    if not path.is_file():
        raise InputError(f"{path}: expected a path CSV file, got no such file")
    traj = Trajectory.from_csv(path)
    options = {
        "law": law,
        "noise_aware": not plain,
        "average": average if average is not None else (1 if plain else 8),
        "margin": margin,
        "q_cutoff": q_cutoff,
    }
    with Library(_db(ctx), create=False) as lib:
        first = "inverse" if inverse else "warm" if warm else "cold"
        res = start(
            lib, traj, machine_name, first=first, eps=eps, name=name or path.stem, **options
        )
    out = out or _default_out(res.series, 0)
    _write_input(out, res.t, res.u)
    if as_json:
        click.echo(
            json.dumps(
                {
                    "series": res.series,
                    "start": res.start,
                    "notes": list(res.notes),
                    "out": str(out),
                }
            )
        )
        return
    for note in res.notes:
        click.echo(f"note: {note}", err=True)
    click.echo(f"started trial series {res.series} ({res.start} start) on machine '{machine_name}'")
    click.echo(f"wrote trial 0's input to {out}: run it on the stage, then `trials step`")


@trials.command("step")
@click.argument("series", type=int)
@click.option(
    "--measured",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Measured positions of the trial just run (CSV t,x,y[,z], absolute).",
)
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    help="The next input (signal CSV); default series<ID>-trial<k>-input.csv.",
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.pass_context
def step_cmd(ctx: click.Context, series: int, measured: Path, out: Path | None, as_json) -> None:
    """Record the measured output of series SERIES' pending trial and write the next input."""
    from primlib.pipeline import Library
    from primlib.store import TrialStore
    from primlib.trials import read_measured, step

    check_output("--out", out, TABLE_FORMATS, inputs=[measured])
    with Library(_db(ctx), create=False) as lib:
        rec = TrialStore(lib).series(series)
        y = read_measured(measured, rec.dt, rec.n_samples, rec.dim)
        res = step(lib, series, y, label=str(measured))
    out = out or _default_out(series, res.trial + 1)
    _write_input(out, res.t, res.u)
    verdict = "converged" if res.converged else "diverging" if res.diverging else "learning"
    if as_json:
        payload = {
            "series": series,
            "trial": res.trial,
            "rms": res.rms,
            "contour_rms": res.contour_rms,
            "noise_floor": res.noise_floor,
            "q_cutoff": res.q_cutoff,
            "verdict": verdict,
            "out": str(out),
        }
        click.echo(json.dumps(payload))
        return
    click.echo(
        f"trial {res.trial}: rms {res.rms:.6g}, contour rms {_fmt(res.contour_rms)}, noise floor "
        f"{_fmt(res.noise_floor)}, Q cut-off {_fmt(res.q_cutoff, '.4g')} Hz: {verdict}"
    )
    click.echo(f"wrote trial {res.trial + 1}'s input to {out}")


def _status_lines(d: dict) -> list[str]:
    """``trials status``'s table from :meth:`SeriesStatus.to_dict`'s dict (local or remote)."""
    where = ", ".join(f"{v:.6g}" for v in d["origin"])
    law = d["options"]["law"] + ("" if d["options"].get("noise_aware") else " (plain)")
    lines = [
        f"trial series {d['series']} ({d['name'] or '-'}) on machine '{d['machine']}', "
        f"{d['start']} start at ({where}), law {law}",
        f"{'trial':>5}  {'rms':>12}  {'contour rms':>12}  {'noise floor':>12}  {'Q Hz':>8}",
    ]
    for t in d["trials"]:
        if t["pending"]:
            lines.append(f"{t['trial']:>5}  {'(pending)':>12}")
            continue
        lines.append(
            f"{t['trial']:>5}  {t['rms']:>12.6g}  {_fmt(t['contour_rms']):>12}  "
            f"{_fmt(t['noise_floor']):>12}  {_fmt(t['q_cutoff'], '.4g'):>8}"
        )
    tail = f" as primitive {d['primitive']}" if d["primitive"] is not None else ""
    lines.append(f"{d['verdict']}{tail} (noise floor {_fmt(d['noise_floor'])})")
    return lines


@trials.command("status")
@click.argument("series", type=int)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object.")
@click.pass_context
def status_cmd(ctx: click.Context, series: int, as_json: bool) -> None:
    """Print the RMS tracking and contour error per trial and the stop rule's verdict."""
    client = _remote(ctx, True)
    if client is not None:
        d = client.trials.status(series)
    else:
        from primlib.pipeline import Library
        from primlib.trials import status

        with Library(_db(ctx), read_only=True) as lib:
            d = status(lib, series).to_dict()
    if as_json:
        click.echo(json.dumps(d))
        return
    click.echo("\n".join(_status_lines(d)))


@trials.command("finish")
@click.argument("series", type=int)
@click.option("--name", help="Name of the primitive (default: the series' name).")
@click.option("--force", is_flag=True, help="Store it even though it has not converged.")
@click.pass_context
def finish_cmd(ctx: click.Context, series: int, name: str | None, force: bool) -> None:
    """Store series SERIES' converged input as a primitive of its machine."""
    from primlib.pipeline import Library
    from primlib.trials import finish

    with Library(_db(ctx), create=False) as lib:
        pid = finish(lib, series, name=name, force=force)
        info = lib.info(pid)
    click.echo(f"stored primitive {pid} ({info.name}) for machine '{info.machine}': {info.source}")


@trials.command("input")
@click.argument("series", type=int)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path))
@click.pass_context
def input_cmd(ctx: click.Context, series: int, out: Path | None) -> None:
    """Write series SERIES' pending input again (after a crash, or a lost file)."""
    from primlib.pipeline import Library
    from primlib.trials import pending

    check_output("--out", out, TABLE_FORMATS)
    client = _remote(ctx, True)
    if client is not None:
        trial, t, u = client.trials.pending(series)
    else:
        with Library(_db(ctx), read_only=True) as lib:
            trial, t, u = pending(lib, series)
    out = out or _default_out(series, trial)
    _write_input(out, t, u)
    click.echo(f"wrote trial {trial}'s input to {out}")


@trials.command("list")
@click.option("--machine", "-m", "machine_name", help="Only this machine's series.")
@click.pass_context
def list_cmd(ctx: click.Context, machine_name: str | None) -> None:
    """List the trial series: id, machine, name, state, trials, last rms."""
    client = _remote(ctx, True)
    if client is not None:
        rows = client.trials.list(machine_name)
    else:
        from primlib.pipeline import Library
        from primlib.store import TrialStore

        rows = []
        with Library(_db(ctx), read_only=True) as lib:
            store = TrialStore(lib)
            for sid in store.ids(machine_name):
                r = store.series(sid)
                done = [t for t in store.trials(sid) if not t.pending]
                last = done[-1].rms if done else None
                rows.append({"series": sid, "machine": r.machine, "name": r.name,
                             "state": r.state, "steps": r.steps, "last_rms": last})  # fmt: skip
    for r in rows:
        click.echo(
            f"{r['series']:>4}  {r['machine']}  {r['name'] or '-'}  {r['state']}  {r['steps']}  "
            f"{_fmt(r['last_rms'])}"
        )


@trials.command("run")
@click.argument("series", type=int)
@click.option(
    "--trial-command",
    required=True,
    help='Runs one trial: "CMD {input} {output}" ({input}: signal CSV t,ux,uy[,uz]; '
    "{output}: the measured positions, CSV t,x,y[,z], absolute).",
)
@click.option("--max-trials", type=click.IntRange(min=1), default=20, show_default=True)
@click.option("--timeout", type=float, help="Seconds a trial may take.")
@click.option(
    "--workdir",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("."),
    show_default=True,
    help="Folder of the trial files.",
)
@click.pass_context
def run_cmd(
    ctx: click.Context,
    series: int,
    trial_command: str,
    max_trials: int,
    timeout: float | None,
    workdir: Path,
) -> None:
    """Run series SERIES' trials with a program until it converges (or diverges)."""
    from primlib.trials import run_command

    def report(res) -> None:
        click.echo(
            f"trial {res.trial}: rms {res.rms:.6g}, contour rms {_fmt(res.contour_rms)}, "
            f"noise floor {_fmt(res.noise_floor)}, Q cut-off {_fmt(res.q_cutoff, '.4g')} Hz"
        )

    result = run_command(
        _db(ctx),
        series,
        trial_command,
        max_trials=max_trials,
        timeout=timeout,
        workdir=str(workdir),
        callback=report,
    )
    click.echo(f"stopped: {result.stopped} after {len(result.steps)} trial(s) in this run")
