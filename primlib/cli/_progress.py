"""Progress of a long command on stderr, so stdout (a table or ``--json``) stays clean.

A computation that takes seconds accepts a plain ``progress(done, total)`` callable (the
library never prints); the CLI passes :func:`stderr_progress`.
"""

from __future__ import annotations

from collections.abc import Callable

import click

__all__ = ["stderr_progress"]


def stderr_progress(what: str) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback printing ``what: done/total`` on stderr.

    Parameters
    ----------
    what : str
        What is being counted, e.g. ``"pdccilc cases"``.

    Returns
    -------
    callable
        ``report(done, total)``: one line per call, e.g. ``pdccilc cases: 3/12``.

    Examples
    --------
    >>> report = stderr_progress("cases")
    >>> report(1, 12)  # writes "cases: 1/12" to stderr
    """

    def report(done: int, total: int) -> None:
        click.echo(f"{what}: {done}/{total}", err=True)

    return report
