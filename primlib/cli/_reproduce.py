"""``primlib reproduce``: the source papers' studies, re-run on primlib's own code.

Each study registers a subcommand on :data:`reproduce` from its own module.
"""

from __future__ import annotations

import click

from primlib.cli import main

__all__ = ["reproduce", "study_options"]


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
