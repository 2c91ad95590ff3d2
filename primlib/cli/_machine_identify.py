"""``primlib machine identify`` and ``primlib machine excite``: a machine JSON from one
recorded experiment, and the input to record it with.

Thin: files are read and written by :mod:`primlib.io`, the fit and the excitation are
:func:`primlib.identify.identify` and :func:`primlib.identify.excite`. Every file is read
and checked (grids, lengths, columns, numbers) and every output path checked before any
computing; the machine JSON is written atomically at the end.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import click

from primlib._errors import InputError
from primlib.cli._library import machine
from primlib.cli._output import FIGURE_FORMATS, check_output

if TYPE_CHECKING:  # numpy is imported where a command runs: `--help` stays fast
    import numpy as np

__all__ = ["machine_identify", "machine_excite"]

_STRUCTURES = ("auto", "integrator", "first-order", "second-order")
_GRID_RTOL = 1e-6  # the CSV reader's own tolerance on a uniform step
_PID_KEYS = ("kp", "ki", "kd", "tf")
# Above this held-out normalised RMS error the summary warns that the model does not follow
# the stage (issue 11's acceptance bound for an identified model).
_POOR_FIT = 0.05


def _parse_pid(values: tuple[str, ...], axes: tuple[str, ...]) -> dict | None:
    """``KP,KI,KD[,TF]`` for every axis, or ``AXIS=KP,KI,KD[,TF]`` per axis."""
    if not values:
        return None
    out: dict[str, dict[str, float]] = {}
    for raw in values:
        axis, _, gains = raw.rpartition("=")
        parts = gains.split(",")
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            numbers = []
        if len(parts) not in (3, 4) or len(numbers) != len(parts):
            raise InputError(
                f"--pid {raw}: expected KP,KI,KD[,TF] or AXIS=KP,KI,KD[,TF] (numbers), got {raw!r}"
            )
        spec = dict(zip(_PID_KEYS, numbers, strict=False))
        targets = axes if not axis else (axis.strip(),)
        for a in targets:
            if a not in axes:
                raise InputError(
                    f"--pid {raw}: expected an axis among {', '.join(axes)}, got {a!r}"
                )
            out[a] = spec
    return out


def _same_grid(t_ref: np.ndarray, t: np.ndarray, ref_name: str, name: str) -> None:
    import numpy as np

    dt_ref = t_ref[1] - t_ref[0]
    if len(t) != len(t_ref):
        raise InputError(
            f"{name}: expected as many samples as {ref_name} ({len(t_ref)}), got {len(t)}"
        )
    if np.max(np.abs(t - t_ref)) > _GRID_RTOL * dt_ref:
        raise InputError(
            f"{name}: expected the time grid of {ref_name} (dt = {dt_ref:.9g} s), "
            f"got dt = {t[1] - t[0]:.9g} s"
        )


def _read_record(input_file: Path, output_file: Path, reference_file: Path | None):
    from primlib.io import read_path_csv, read_signal_csv

    t, u = read_signal_csv(input_file)
    t_y, points = read_path_csv(output_file)
    _same_grid(t, t_y, str(input_file), str(output_file))
    if points.shape[1] != u.shape[1]:
        raise InputError(
            f"{output_file}: expected {u.shape[1]} position columns like the input "
            f"{input_file}, got {points.shape[1]}"
        )
    ref = None
    if reference_file is not None:
        t_r, r_points = read_path_csv(reference_file)
        _same_grid(t, t_r, str(input_file), str(reference_file))
        if r_points.shape[1] != u.shape[1]:
            raise InputError(
                f"{reference_file}: expected {u.shape[1]} position columns like the input "
                f"{input_file}, got {r_points.shape[1]}"
            )
        ref = r_points - r_points[0]
    return t, u, points - points[0], ref


def _summary(res, out: Path, plot_file: Path | None) -> str:
    m = res.machine
    lines = [
        f"identified machine '{m.name}' (dt = {m.dt:g} s, axes {', '.join(m.axes)}"
        f"{', in the given PID loop' if m.feedback else ''}) from {len(res.y)} samples, "
        f"the last {len(res.y) - res.n_est} held out",
        f"{'axis':<5} {'structure':<13} {'held-out NRMSE':>14}  num +- std / den +- std",
    ]
    for a, f in zip(m.axes, res.fits, strict=True):
        num = ", ".join(f"{v:.5g}+-{s:.2g}" for v, s in zip(f.num, f.num_std, strict=True))
        den = ", ".join(f"{v:.5g}+-{s:.2g}" for v, s in zip(f.den, f.den_std, strict=True))
        lines.append(f"{a:<5} {f.structure:<13} {100 * f.nrmse:>12.3f} %  [{num}] / [{den}]")
    poor = [a for a, f in zip(m.axes, res.fits, strict=True) if f.nrmse > _POOR_FIT]
    if poor:
        lines.append(
            f"warning: held-out NRMSE above {100 * _POOR_FIT:g} % on {', '.join(poor)}: the "
            "model does not follow the stage there; excite with more amplitude and down to "
            "lower frequencies (friction and drift dominate small, fast motions)"
        )
    lines.append(f"wrote {out}; add it with: primlib machine add {out}")
    if plot_file is not None:
        lines.append(f"figure written to {plot_file}")
    return "\n".join(lines)


@machine.command("identify")
@click.option(
    "--input",
    "input_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Signal CSV t,ux,uy[,uz]: the input applied in the experiment.",
)
@click.option(
    "--output",
    "output_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Path CSV t,x,y[,z]: the measured positions (absolute; the first sample is the start).",
)
@click.option("--name", required=True, help="Name of the identified machine.")
@click.option(
    "--out",
    "out_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Machine JSON to write.",
)
@click.option(
    "--dt",
    "machine_dt",
    type=float,
    default=None,
    help="The machine's sample time in s (default: the record's step).",
)
@click.option(
    "--structure",
    type=click.Choice(_STRUCTURES),
    default="auto",
    show_default=True,
    help="Model structure per axis; auto picks it on the held-out data.",
)
@click.option(
    "--pid",
    multiple=True,
    metavar="[AXIS=]KP,KI,KD[,TF]",
    help="The experiment ran in this PID loop (every axis, or the named one; "
    "repeat per axis): the plant inside is identified.",
)
@click.option(
    "--reference",
    "reference_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Path CSV of the PID loops' reference (default: hold the start).",
)
@click.option(
    "--holdout",
    type=float,
    default=None,
    help="Fraction of the record (its end) held out of the fit [default: 0.3].",
)
@click.option("--json", "as_json", is_flag=True, help="Print the fit quality as one JSON object.")
@click.option(
    "--plot",
    "plot_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Save a figure: measured vs model output per axis.",
)
def machine_identify(
    input_file: Path,
    output_file: Path,
    name: str,
    out_file: Path,
    machine_dt: float | None,
    structure: str,
    pid: tuple[str, ...],
    reference_file: Path | None,
    holdout: float | None,
    as_json: bool,
    plot_file: Path | None,
) -> None:
    """Identify a machine from one experiment: per-axis continuous models fitted by
    output-error least squares, written as machine JSON with the fit quality in its note.

    \b
    primlib machine excite --duration 20 --amplitude 1 --axes 3 --dt 0.005 --out u.csv
    (run u.csv on the stage, record y.csv)
    primlib machine identify --input u.csv --output y.csv --name stage --out stage.json
    primlib machine add stage.json
    """
    import numpy as np

    from primlib.identify import HOLDOUT, identify

    inputs = [input_file, output_file, reference_file]
    check_output("--out", out_file, (".json",), inputs)
    check_output("--plot", plot_file, FIGURE_FORMATS, inputs)
    if machine_dt is not None and not (np.isfinite(machine_dt) and machine_dt > 0):
        raise InputError(f"--dt: expected a sample time > 0 s, got {machine_dt}")
    t, u, y, ref = _read_record(input_file, output_file, reference_file)
    axes = ("x", "y", "z")[: u.shape[1]]
    gains = _parse_pid(pid, axes)
    if ref is not None and gains is None:
        raise InputError("--reference: expected --pid (a reference only acts through a PID loop)")
    res = identify(
        u,
        y,
        float(t[1] - t[0]),
        structure=structure,
        pid=gains,
        reference=ref,
        holdout=HOLDOUT if holdout is None else holdout,
        axes=axes,
        name=name,
        machine_dt=machine_dt,
    )
    if plot_file is not None:
        from primlib.plot import save_identified

        save_identified(res, plot_file)
    res.machine.to_json(out_file)
    if as_json:
        report = {**res.to_dict(), "out": str(out_file)}
        if plot_file is not None:
            report["plot"] = str(plot_file)
        click.echo(json.dumps(report, indent=2))
    else:
        click.echo(_summary(res, out_file, plot_file))


@machine.command("excite")
@click.option("--duration", required=True, type=float, help="Record length in s.")
@click.option("--amplitude", required=True, type=float, help="Largest |u| per axis.")
@click.option(
    "--axes", "n_axes", required=True, type=click.IntRange(2, 3), help="Number of axes (2 or 3)."
)
@click.option(
    "--out",
    "out_file",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Signal CSV to write (t,ux,uy[,uz]).",
)
@click.option(
    "--kind",
    type=click.Choice(("multisine", "prbs")),
    default="multisine",
    show_default=True,
    help="Schroeder-phased multisine or PRBS.",
)
@click.option(
    "--dt",
    type=float,
    default=None,
    help="Sample time in s (default: the --machine's, else 0.005).",
)
@click.option(
    "--band",
    type=(float, float),
    default=None,
    metavar="LOW HIGH",
    help="Excited band in Hz [default: periods/duration to a fifth of Nyquist].",
)
@click.option("--max-rate", type=float, default=None, help="Largest |du/dt| (input units/s).")
@click.option(
    "--max-velocity",
    type=float,
    default=None,
    help="Largest predicted |dy/dt| of the --machine's response (output units/s).",
)
@click.option(
    "--machine",
    "machine_file",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Nominal machine JSON to predict the velocity with.",
)
@click.option(
    "--periods", type=int, default=None, help="Multisine periods in the record [default: 4]."
)
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the PRBS.")
def machine_excite(
    duration: float,
    amplitude: float,
    n_axes: int,
    out_file: Path,
    kind: str,
    dt: float | None,
    band: tuple[float, float] | None,
    max_rate: float | None,
    max_velocity: float | None,
    machine_file: Path | None,
    periods: int | None,
    seed: int,
) -> None:
    """Write an excitation input for an identification experiment (signal CSV), within
    the amplitude and the rate or predicted-velocity limits."""
    import numpy as np

    from primlib.identify import PERIODS, excite
    from primlib.io import write_signal_csv
    from primlib.plant import Machine

    check_output("--out", out_file, (".csv",), [machine_file])
    if max_velocity is not None and machine_file is None:
        raise InputError(
            "--max-velocity: expected --machine (a nominal model to predict the velocity "
            "with); --max-rate limits the input's own rate"
        )
    nominal = None if machine_file is None else Machine.from_json(machine_file)
    if dt is None:
        dt = 0.005 if nominal is None else nominal.dt
    u = excite(
        duration,
        amplitude,
        n_axes,
        dt,
        kind=kind,
        band=band,
        max_rate=max_rate,
        max_velocity=max_velocity,
        machine=nominal,
        seed=seed,
        periods=PERIODS if periods is None else periods,
    )
    t = np.arange(len(u)) * dt
    write_signal_csv(out_file, t, u)
    peak = np.max(np.abs(u))
    rate = np.max(np.abs(np.diff(u, axis=0, prepend=0.0))) / dt
    click.echo(
        f"wrote {out_file}: {kind}, {len(u)} samples at dt = {dt:g} s, {n_axes} axes, "
        f"peak |u| {peak:.4g}, peak |du/dt| {rate:.4g}/s"
    )
