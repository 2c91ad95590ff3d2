"""``primlib reproduce cee-mfac``: the CEE-MFAC paper's simulation study (Table 2)."""

from __future__ import annotations

import json
import math

import click

from primlib.cli._reproduce import reproduce, study_options

__all__ = ["cee_mfac"]


@reproduce.command("cee-mfac")
@study_options("like the paper's Figs. 4-6")
@click.option(
    "--duration",
    type=click.FloatRange(min=0.0, min_open=True),
    default=2 * math.pi,
    show_default="2 pi, one revolution",
    help="Seconds of the ellipse to run.",
)
@click.option(
    "--ccc-gain",
    type=click.FloatRange(min=0.0),
    default=1.0,
    show_default=True,
    help="Cross-coupling gain K_p, V per mm of contour error.",
)
def cee_mfac(as_json, plot_dir, duration, ccc_gain):
    """Ellipse x = 10 sin t, y = 5 cos t mm on the linear-motor stage: C1-C3 (MFAC with the
    linear, circular, exact contour estimate) and C4 (PID with the exact one).

    Prints e_max and e_mad (µm, true contour error) beside the paper's Table 2.
    """
    from primlib.reproduce._cee_mfac import PAPER_TABLE2, cee_mfac_study

    study = cee_mfac_study(duration=duration, ccc_gain=ccc_gain)
    if plot_dir is not None:
        from primlib.plot import plot_cee

        for path in plot_cee(study, plot_dir):
            click.echo(f"wrote {path}", err=True)
    if as_json:
        click.echo(json.dumps(study.to_json()))
        return
    click.echo(
        f"{'case':<6}{'e_max µm':>10}{'e_mad µm':>10}{'paper e_max':>13}{'paper e_mad':>13}"
        f"{'est. e_max':>12}{'track max':>11}"
    )
    for case, m in study.metrics.items():
        p = PAPER_TABLE2[case]
        click.echo(
            f"{case:<6}{m['e_max']:>10.2f}{m['e_mad']:>10.2f}{p['e_max']:>13.2f}"
            f"{p['e_mad']:>13.2f}{m['e_max_estimated']:>12.2f}{m['tracking_max']:>11.2f}"
        )
