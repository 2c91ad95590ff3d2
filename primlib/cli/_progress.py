"""Progress of a long command on stderr, so stdout (a table or ``--json``) stays clean.

A computation that takes seconds accepts a plain ``progress(done, total)`` callable (the
library never prints); the CLI passes :func:`stderr_progress`. The matcher also passes
a third count, the segments found so far.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import click

__all__ = ["stderr_progress", "match_progress"]


def stderr_progress(
    what: str, after: float = 0.0, every: float = 0.0, *, bar: int = 0, found: str = ""
) -> Callable[..., None]:
    """A ``progress(done, total[, count])`` callback printing ``what: done/total`` on stderr.

    Parameters
    ----------
    what : str
        What is being counted, e.g. ``"pdccilc cases"``.
    after : float
        Seconds before the first line: a command that finishes sooner prints nothing.
    every : float
        Seconds at least between two lines (the final call, done = total, always prints
        once ``after`` has passed).
    bar : int
        Width of a bar drawn before the counts (0: none); with the percentage done.
    found : str
        What the optional third count is (``"segments"``), printed after the counts.

    Returns
    -------
    callable
        ``report(done, total, count=None)``: one line per call, e.g. ``pdccilc cases:
        3/12``; on a terminal each line overwrites the last until done = total.

    Examples
    --------
    >>> report = stderr_progress("cases")
    >>> report(1, 12)  # writes "cases: 1/12" to stderr
    >>> report = stderr_progress("match", bar=10, found="segments")
    >>> report(6, 12, 3)  # writes "match: [#####.....] 6/12 (50 %), 3 segments"
    """
    start = time.monotonic()
    last = [-float("inf")]
    tty = sys.stderr.isatty()

    def report(done: int, total: int, count: int | None = None) -> None:
        now = time.monotonic()
        if now - start < after:
            return
        if now - last[0] < every and done < total:
            return
        last[0] = now
        line = f"{what}: {done}/{total}"
        if bar > 0:
            frac = min(max(done / total, 0.0), 1.0) if total > 0 else 1.0
            full = int(frac * bar)
            line = f"{what}: [{'#' * full}{'.' * (bar - full)}] {done}/{total} ({100 * frac:.0f} %)"
        if found and count is not None:
            line += f", {count} {found}"
        if tty:
            click.echo(f"\r{line}", err=True, nl=done >= total)
        else:
            click.echo(line, err=True)

    return report


def match_progress() -> Callable[..., None]:
    """The matcher's progress (``match`` and ``learn``): a bar a second on stderr once
    matching has taken 2 s, with the path samples covered and the segments found."""
    return stderr_progress("match: path samples", after=2.0, every=1.0, bar=20, found="segments")
