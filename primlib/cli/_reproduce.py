"""``primlib reproduce``: the source papers' studies, re-run on primlib's own code.

Each study registers a subcommand on :data:`reproduce` from its own module.
"""

from __future__ import annotations

import json

import click

from primlib.cli import main

__all__ = ["reproduce", "study_options", "figures_and_json"]


@main.group()
def reproduce() -> None:
    """Re-run a source paper's study and print (or plot) its figures of merit."""


def study_options(figures: str):
    """The options every study shares: ``--json`` and ``--plot DIR`` (``figures`` names what
    the directory receives, e.g. "like the paper's Figs. 4-6")."""

    def decorate(command):
        command = click.option(
            "--plot",
            "plot_dir",
            type=click.Path(file_okay=False),
            default=None,
            help=f"Write the figures ({figures}) into this directory.",
        )(command)
        return click.option(
            "--json", "as_json", is_flag=True, help="Print the results as one JSON object."
        )(command)

    return decorate


def figures_and_json(study, plot: str, plot_dir, as_json: bool) -> bool:
    """What every study does with its result before its own table: with ``--plot``, the
    figures by ``primlib.plot``'s function named ``plot`` (imported only then: matplotlib is
    slow to load), their names on stderr; with ``--json``, ``study.to_json()`` printed.
    Returns True when the JSON was printed (then no table)."""
    if plot_dir is not None:
        import primlib.plot

        for path in getattr(primlib.plot, plot)(study, plot_dir):
            click.echo(f"wrote {path}", err=True)
    if as_json:
        click.echo(json.dumps(study.to_json()))
    return as_json
