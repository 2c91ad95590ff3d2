"""Progress of a long command on stderr, so stdout (a table or ``--json``) stays clean.

A computation that takes seconds accepts a plain ``progress(done, total)`` callable (the
library never prints); the CLI passes :func:`stderr_progress`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import click

__all__ = ["stderr_progress"]


def stderr_progress(
    what: str, after: float = 0.0, every: float = 0.0
) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback printing ``what: done/total`` on stderr.

    Parameters
    ----------
    what : str
        What is being counted, e.g. ``"pdccilc cases"``.
    after : float
        Seconds before the first line: a command that finishes sooner prints nothing.
    every : float
        Seconds at least between two lines (the final call, done = total, always prints
        once ``after`` has passed).

    Returns
    -------
    callable
        ``report(done, total)``: one line per call, e.g. ``pdccilc cases: 3/12``.

    Examples
    --------
    >>> report = stderr_progress("cases")
    >>> report(1, 12)  # writes "cases: 1/12" to stderr
    """
    start = time.monotonic()
    last = [-float("inf")]

    def report(done: int, total: int) -> None:
        now = time.monotonic()
        if now - start < after:
            return
        if now - last[0] < every and done < total:
            return
        last[0] = now
        click.echo(f"{what}: {done}/{total}", err=True)

    return report
