"""``primlib reproduce pdccilc``: the master–slave PDCCILC paper's simulation study."""

from __future__ import annotations

import click

from primlib.cli._progress import stderr_progress
from primlib.cli._reproduce import figures_and_json, reproduce, study_options

__all__ = ["pdccilc"]


@reproduce.command("pdccilc")
@study_options("like the paper's Figs. 7-12")
@click.option(
    "--iterations",
    type=click.IntRange(min=1),
    default=50,
    show_default=True,
    help="Learning iterations per law and contour.",
)
@click.option(
    "--q-cutoff",
    type=click.FloatRange(min=0.0, min_open=True),
    default=1.0,
    show_default=True,
    help="-3 dB frequency (Hz) of the zero-phase Q-filter.",
)
@click.option(
    "--no-q-filter",
    is_flag=True,
    help="Learn without a Q-filter (the laws then diverge after some 20 trials: see README).",
)
@click.option(
    "--no-convergence",
    is_flag=True,
    help="Skip the lifted convergence figures (sigma_max, rho, asymptotic error).",
)
def pdccilc(as_json, plot_dir, iterations, q_cutoff, no_q_filter, no_convergence):
    """Four laws (TDILC, TDCCILC, PDILC, PDCCILC) on the paper's stage (eq. 33), three contours.

    Prints the RMS contour error before and after learning, its reduction, and the lifted
    convergence figures of eqs. (29)-(30) for every law and contour.
    """
    # imported here, not at the top: the study pulls in scipy and the figures matplotlib,
    # which `primlib --help` and every other command need not load
    from primlib.reproduce import PDCCILC_PAPER, pdccilc_study

    study = pdccilc_study(
        iterations=iterations,
        q_cutoff=None if no_q_filter else q_cutoff,
        convergence=not no_convergence,
        progress=stderr_progress("pdccilc cases (contour x law)"),
    )
    if figures_and_json(study, "plot_pdccilc", plot_dir, as_json):
        return
    click.echo(
        f"{'contour':<11}{'law':<9}{'RMS0 µm':>9}{'RMS µm':>9}{'reduct.':>9}"
        f"{'sigma':>9}{'rho<=':>9}{'RMSinf µm':>11}"
    )
    for contour, laws in study.rms_contour.items():
        best = min(laws, key=lambda k: laws[k][-1])
        for law, rms in laws.items():
            conv = study.convergence.get(contour, {}).get(law)
            tail = ""
            if conv is not None:
                rho = f"{conv['spectral_radius']:.4f}"
                tail = (
                    f"{conv['max_singular_value']:>9.4f}{rho:>9}"
                    f"{conv['asymptotic_rms_contour'] * 1e3:>11.2f}"
                )
            mark = " *" if law == best else ""
            click.echo(
                f"{contour:<11}{law:<9}{rms[0] * 1e3:>9.2f}{rms[-1] * 1e3:>9.2f}"
                f"{study.reduction(contour, law) * 100:>8.1f}%{tail}{mark}"
            )
        paper = PDCCILC_PAPER[contour]
        click.echo(
            f"{'':<11}paper: {paper['best']} best, {paper['reduction'] * 100:.0f} % reduction;"
            f" here: {best} best, PDCCILC {study.reduction(contour, 'PDCCILC') * 100:.1f} %"
            if "PDCCILC" in laws
            else ""
        )
