"""Output-file checks every command runs before it computes anything.

A command that would fail only when it writes its result (a missing folder, a figure format
matplotlib cannot write, an output that is one of its own inputs) is refused up front with
one sentence and exit 2, so no long computation is thrown away.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from pathlib import Path

from primlib._errors import InputError

__all__ = ["check_output", "segment_lines", "FIGURE_FORMATS", "TABLE_FORMATS"]

# What matplotlib's Agg-based savefig writes without extra packages.
FIGURE_FORMATS = (".png", ".pdf", ".svg", ".jpg", ".jpeg", ".eps", ".ps", ".tif", ".tiff")
TABLE_FORMATS = (".csv",)


def check_output(
    option: str,
    path: Path | str | None,
    formats: Iterable[str] | None = None,
    inputs: Iterable[Path | str] = (),
) -> None:
    """Refuse an output path that cannot be written, before any work is done.

    Parameters
    ----------
    option : str
        The option's name as the user typed it (``"--plot"``), for the message.
    path : path or None
        The output file; None means the option was not given (nothing to check).
    formats : iterable of str, optional
        Accepted suffixes (lower case, with the dot); None accepts any.
    inputs : iterable of paths
        The command's input files: writing over one of them is refused.

    Raises
    ------
    InputError
        The folder does not exist or is not writable, the path is a folder, the suffix is
        not one of ``formats``, or the path is one of ``inputs``.
    """
    if path is None:
        return
    p = Path(path)
    if formats is not None:
        formats = tuple(formats)
        if p.suffix.lower() not in formats:
            raise InputError(
                f"{option} {p}: expected a file ending in {', '.join(formats)}, "
                f"got {p.suffix or 'no suffix'}"
            )
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{option} {p}: folder {parent} does not exist")
    if p.is_dir():
        raise InputError(f"{option} {p}: is a folder, expected a file")
    if not os.access(parent, os.W_OK) or (p.exists() and not os.access(p, os.W_OK)):
        raise InputError(f"{option} {p}: not writable")
    for f in inputs:
        if f is not None and Path(f).exists() and p.exists() and p.resolve() == Path(f).resolve():
            raise InputError(f"{option} {p}: is also an input of this command; choose another file")


def segment_lines(sources: tuple[str, ...]) -> list[str]:
    """The warm start's per-segment sources, numbered from 1 like ``primlib match``."""
    return [f"segment {j}: " + re.sub(r"^segment \d+: ", "", s) for j, s in enumerate(sources, 1)]
