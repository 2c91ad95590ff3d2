"""``primlib reproduce``: the source papers' studies, re-run on primlib's own code.

Each study registers a subcommand on :data:`reproduce` from its own module.
"""

from __future__ import annotations

import click

from primlib.cli import main

__all__ = ["reproduce"]


@main.group()
def reproduce() -> None:
    """Re-run a source paper's study and print (or plot) its figures of merit."""
