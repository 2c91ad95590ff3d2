"""``primlib reproduce cee-mfac``: the CEE-MFAC paper's simulation study (Table 2), and with
``--sweep`` the same loops against feed speed, where the choice of estimator starts to count."""

from __future__ import annotations

import math

import click

from primlib._errors import InputError
from primlib.cli._progress import stderr_progress
from primlib.cli._reproduce import figures_and_json, reproduce, study_options

__all__ = ["cee_mfac"]


def _speeds(ctx, param, value):
    if value is None:
        return None
    try:
        speeds = tuple(float(x) for x in value.split(","))
    except ValueError:
        raise click.BadParameter(f"expected comma-separated numbers, got {value!r}") from None
    if not all(math.isfinite(s) and s > 0 for s in speeds):
        raise click.BadParameter(f"expected positive rates in rad/s, got {value!r}")
    return speeds


@reproduce.command("cee-mfac")
@study_options("like the paper's Figs. 4-6; with --sweep, cee-sweep.png")
@click.option(
    "--duration",
    type=click.FloatRange(min=0.0, min_open=True),
    default=None,
    show_default="2 pi, one revolution",
    help="Seconds of the ellipse to run (not with --sweep).",
)
@click.option(
    "--ccc-gain",
    type=click.FloatRange(min=0.0),
    default=1.0,
    show_default=True,
    help="Cross-coupling gain K_p, V per mm of contour error.",
)
@click.option(
    "--sweep",
    is_flag=True,
    help="Run the MFAC loop with each estimator (linear, circular, exact) over a range of "
    "feed speeds and report e_max, e_mad and the tracking lag per speed.",
)
@click.option(
    "--speeds",
    callback=_speeds,
    default=None,
    help="With --sweep: ellipse rates in rad/s, comma-separated (peak feed = 10 x rate "
    "mm/s). Default 2,4,8,12,16,20,24.",
)
@click.option(
    "--revolutions",
    type=click.FloatRange(min=1.0, min_open=True),
    default=2.0,
    show_default=True,
    help="With --sweep: revolutions per run; figures are taken over the last one.",
)
def cee_mfac(as_json, plot_dir, duration, ccc_gain, sweep, speeds, revolutions):
    """Ellipse x = 10 sin t, y = 5 cos t mm on the linear-motor stage: C1-C3 (MFAC with the
    linear, circular, exact contour estimate) and C4 (PID with the exact one).

    Prints e_max and e_mad (µm, true contour error) beside the paper's Table 2. With
    --sweep, the same MFAC loops at higher feed speeds (progress on stderr).
    """
    if sweep:
        if duration is not None:
            raise InputError("--duration: not used with --sweep (see --revolutions)")
        _sweep(as_json, plot_dir, ccc_gain, speeds, revolutions)
        return
    if speeds is not None:
        raise InputError("--speeds: only used with --sweep")
    from primlib.reproduce import CEE_PAPER, cee_mfac_study

    study = cee_mfac_study(
        duration=2 * math.pi if duration is None else duration,
        ccc_gain=ccc_gain,
        progress=stderr_progress("cee-mfac cases"),
    )
    if figures_and_json(study, "plot_cee", plot_dir, as_json):
        return
    click.echo(
        f"{'case':<6}{'e_max µm':>10}{'e_mad µm':>10}{'paper e_max':>13}{'paper e_mad':>13}"
        f"{'est. e_max':>12}{'track max':>11}"
    )
    for case, m in study.metrics.items():
        p = CEE_PAPER[case]
        click.echo(
            f"{case:<6}{m['e_max']:>10.2f}{m['e_mad']:>10.2f}{p['e_max']:>13.2f}"
            f"{p['e_mad']:>13.2f}{m['e_max_estimated']:>12.2f}{m['tracking_max']:>11.2f}"
        )


def _sweep(as_json, plot_dir, ccc_gain, speeds, revolutions):
    from primlib.reproduce import CEE_SWEEP_SPEEDS, cee_mfac_sweep

    sw = cee_mfac_sweep(
        CEE_SWEEP_SPEEDS if speeds is None else speeds,
        revolutions=revolutions,
        ccc_gain=ccc_gain,
        progress=stderr_progress("cee-mfac sweep runs (speed x estimator)"),
    )
    if figures_and_json(sw, "plot_cee", plot_dir, as_json):
        return
    names = ("linear", "circular", "exact")
    click.echo(
        f"{'feed':>6} {'lag':>7}  {'e_max µm: linear / circular / exact':<36}"
        f"{'e_mad µm: linear / circular / exact':<36}{'est. error µm (linear)':>22}"
    )
    for i, feed in enumerate(sw.feed):
        e_max = " / ".join(f"{sw.e_max[n][i]:.2f}" for n in names)
        e_mad = " / ".join(f"{sw.e_mad[n][i]:.2f}" for n in names)
        click.echo(
            f"{feed:>6.0f} {sw.lag['exact'][i]:>7.1f}  {e_max:<36}{e_mad:<36}"
            f"{sw.estimate_error['linear'][i]:>22.2f}"
        )
    click.echo("feed in mm/s (peak), lag = largest tracking error in µm (exact loop)")
    onset = sw.onset()
    est, con = onset["estimate_feed"], onset["contour_feed"]
    click.echo(
        "the linear estimate errs by more than 1 µm from "
        + (f"{est:g} mm/s" if est is not None else "no speed swept")
        + "; the exact estimator lowers e_max by 10 % or more from "
        + (f"{con:g} mm/s" if con is not None else "no speed swept")
    )
