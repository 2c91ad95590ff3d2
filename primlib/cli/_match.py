"""``primlib match``: cut a new path into pieces of stored primitives and report them.

Reads the path CSV (fitted by :class:`primlib.nurbs.Trajectory`), matches it against the
machine's primitives (:func:`primlib.match.match_path`) and prints one row per segment.
``--out`` also builds the warm-start input (:func:`primlib.splice.warm_start`) and writes it
as a signal CSV; ``--plot`` draws the segmentation. Everything is computed before anything
is written, so a bad input writes nothing.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import click

from primlib._errors import InputError
from primlib.cli import main
from primlib.cli._machine_fit import keep_models
from primlib.cli._options import parse_origin
from primlib.cli._progress import match_progress
from primlib.defaults import TIME_SCALE

__all__ = ["match"]


def _interval(a: float, b: float) -> str:
    return f"{a:.4f}-{b:.4f}"


def _table(mt, duration: float) -> str:
    import numpy as np

    headers = ["seg", "path v", "path t [s]", "primitive", "primitive v", "angle", "k", "rmsd"]
    rows = []
    for j, s in enumerate(mt.segments, 1):
        if s.primitive is None:
            prim, piv, ang, k, r = "(unmatched)", "-", "-", "-", "-"
        else:
            prim = f"#{s.primitive}" + (f" {s.primitive_name}" if s.primitive_name else "")
            piv = _interval(s.primitive_start, s.primitive_end)
            ang = f"{np.degrees(s.angle):.1f}°"
            k = f"{s.time_scale:.3f}"
            r = f"{s.rmsd:.3g}"
        t = f"{s.start * duration:.3f}-{s.end * duration:.3f}"
        rows.append([str(j), _interval(s.start, s.end), t, prim, piv, ang, k, r])
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    right = {0, 5, 6, 7}

    def line(cells: list[str]) -> str:
        return "  ".join(
            c.rjust(w) if i in right else c.ljust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        ).rstrip()

    return "\n".join([line(headers), line(["-" * w for w in widths]), *(line(r) for r in rows)])


def _check_numbers(
    eps: float | None, min_segment: float | None, time_scale: tuple[float, float]
) -> None:
    """The numbers of ``primlib match``, each refused under its option's name."""
    from primlib.match import check_time_scale

    check_time_scale(time_scale, "--time-scale")
    if eps is not None and not (math.isfinite(eps) and eps > 0):
        raise InputError(f"--eps: expected a tolerance > 0, got {eps:g}")
    if min_segment is not None and not (math.isfinite(min_segment) and min_segment >= 0):
        raise InputError(f"--min-segment: expected a duration >= 0 s, got {min_segment:g}")


@main.command("match")
@click.argument("path_csv", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "--machine", "-m", "machine_name", required=True, help="Machine whose primitives to use."
)
@click.option(
    "--eps",
    type=float,
    default=None,
    help=(
        "Kabsch RMSD tolerance per segment (path units). Default: 3e-4 of the path's "
        "extent, as for the warm start and learn."
    ),
)
@click.option(
    "--rotation",
    type=click.Choice(["full", "z", "none"]),
    default="full",
    show_default=True,
    help="Rotations allowed: any proper rotation, about the vertical z axis only, or none.",
)
@click.option(
    "--time-scale",
    nargs=2,
    type=float,
    default=TIME_SCALE,
    show_default=True,
    help="Allowed stored duration / segment duration (low high).",
)
@click.option(
    "--min-segment",
    "min_segment",
    type=float,
    default=None,
    metavar="SECONDS",
    help=(
        "Shortest matched segment kept; shorter matches join the unmatched stretch beside "
        "them (filled from the model). Default: one transition band, 8 machine steps."
    ),
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of a table.")
@click.option(
    "--plot",
    "plot_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Save a figure: the path by segment with the transformed pieces, RMSD per segment.",
)
@click.option(
    "--out",
    "out_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Also build the warm-start input from the match and write it as a signal CSV.",
)
@click.option(
    "--origin",
    metavar="X,Y[,Z]",
    callback=parse_origin,
    help="Where the path starts on the machine, absolute (for --out): the grey-box model's "
    "position-dependent terms (force ripple) are evaluated there. Default: unknown.",
)
@click.pass_context
def match(
    ctx: click.Context,
    path_csv: Path,
    machine_name: str,
    eps: float | None,
    rotation: str,
    time_scale: tuple[float, float],
    min_segment: float | None,
    as_json: bool,
    plot_file: Path | None,
    out_file: Path | None,
    origin: tuple[float, ...] | None,
) -> None:
    """Match PATH_CSV (header t,x,y or t,x,y,z) against a machine's primitives.

    Prints one row per segment: path interval, matched primitive and its interval,
    rotation angle, time scale k (stored duration / segment duration) and Kabsch RMSD.

    \b
    primlib match new_path.csv -m xyz --eps 0.05
    primlib match new_path.csv --machine xyz --json --plot match.png --out u0.csv
    """
    import numpy as np

    from primlib.cli._library import _db, _open_library
    from primlib.cli._output import FIGURE_FORMATS, TABLE_FORMATS, check_output
    from primlib.match import default_eps
    from primlib.nurbs import read_path

    _check_numbers(eps, min_segment, time_scale)
    inputs = (path_csv, _db(ctx))
    check_output("--plot", plot_file, FIGURE_FORMATS, inputs)
    check_output("--out", out_file, TABLE_FORMATS, inputs)
    if plot_file is not None and ctx.find_root().obj.get("remote"):
        raise click.UsageError("--plot: draws from the library file; not with --remote")
    # a CSV table or a geomdl JSON curve; values beyond MAX_ABS_VALUE or a path that does
    # not move are refused here, with the file's name
    traj = read_path(path_csv)
    with _open_library(ctx, read_only=True, remote=True) as lib:
        m = lib.machine(machine_name)
        if traj.dim != m.dim:
            raise InputError(
                f"{path_csv}: expected a {m.dim}-D path for machine {machine_name!r}, "
                f"got {traj.dim}-D"
            )
        e = eps if eps is not None else default_eps(traj)
        kw = {"rotation": rotation, "time_scale": tuple(time_scale)}
        if min_segment is not None:  # else the library's default (a server's too)
            kw["min_segment"] = min_segment
        if not ctx.find_root().obj.get("remote"):
            kw["progress"] = match_progress()
        ws = None
        if out_file is not None:
            kw.update({} if origin is None else {"origin": origin})
            ws = lib.warm_start(traj, machine=machine_name, eps=e, **kw)
            mt = ws.match
        else:
            mt = lib.match(traj, machine=machine_name, eps=e, **kw)
        pieces = None
        if plot_file is not None:
            from primlib.match import matched_pieces

            pieces = matched_pieces(mt.segments, lib.bank(machine_name))
    keep_models(_db(ctx), lib, say=not as_json)
    n = max(int(round(traj.duration / m.dt)) + 1, 2)
    if plot_file is not None:
        from primlib.plot import plot_match

        plot_match(plot_file, traj.at(np.linspace(0.0, 1.0, n)), mt, pieces)
    if ws is not None:
        _write_warm(ws, out_file)
    if as_json:
        click.echo(_as_json(mt, path_csv, traj.duration, out_file, plot_file))
        return
    click.echo(_summary(mt, path_csv, machine_name, e, rotation))
    click.echo(_table(mt, traj.duration))
    if out_file is not None:
        _report_warm(ws, out_file)
    if plot_file is not None:
        click.echo(f"figure written to {plot_file}")


def _summary(mt, path_csv: Path, machine_name: str, eps: float, rotation: str) -> str:
    """The line above the table: counts, the fraction matched, the settings, the time."""
    info = mt.info
    return (
        f"{path_csv}: {len(mt.segments)} segment(s), {mt.n_unmatched} unmatched, "
        f"{100 * mt.matched_fraction:.1f} % of the path matched, machine {machine_name}, "
        f"eps {eps:.4g}, rotation {rotation}, "
        f"{info.get('probes', 0)} probes in {info.get('seconds', 0.0):.2f} s"
    )


def _write_warm(ws, out_file: Path) -> None:
    from primlib.io import write_signal_csv

    write_signal_csv(out_file, ws.t, ws.u)


def _report_warm(ws, out_file: Path) -> None:
    """What each segment of the warm start used, and where it was written."""
    from primlib.cli._output import segment_lines

    click.echo("\n".join(segment_lines(ws.sources)))
    click.echo(f"warm-start input written to {out_file}")


def _as_json(mt, path_csv: Path, duration: float, out_file, plot_file) -> str:
    """``match --json``: the Match's fields, the path, and the files written."""
    d = mt.to_dict()
    d["path"] = str(path_csv)
    d["duration"] = float(duration)
    if out_file is not None:
        d["out"] = str(out_file)
    if plot_file is not None:
        d["plot"] = str(plot_file)
    return json.dumps(d, indent=2)
