"""Uniformly timed CSV tables: the one reader and writer behind path and signal files.

A table is a header line (``t,x,y`` say) and rows of numbers, comma separated, whose first
column is time: it starts at 0 and is uniformly spaced. :func:`read_uniform_table` checks
all of that and says, in one sentence naming the file (and the line where one applies),
what is wrong; :func:`write_table` writes the same format with numbers that read back
bit for bit.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from primlib._errors import InputError
from primlib.defaults import MAX_ABS_VALUE

__all__ = ["read_uniform_table", "parse_uniform_table", "write_table", "MIN_ROWS", "T_RTOL"]

MIN_ROWS = 8
"""Fewest data rows a table may have (a cubic fit needs a handful of samples)."""

T_RTOL = 1e-6
"""Relative tolerance, in units of the time step, on the start (t[0] = 0) and the spacing."""


def _fmt_header(header: Sequence[str]) -> str:
    return ",".join(header)


def _expected_headers(headers: Sequence[Sequence[str]]) -> str:
    return " or ".join(_fmt_header(h) for h in headers)


def _diagnose_rows(path: Path, body: list[str], ncol: int, first_line: int) -> None:
    """Find the first bad data line with a plain loop (only runs when the fast parse failed)."""
    for i, raw in enumerate(body):
        lineno = first_line + i
        if not raw.strip():
            raise InputError(f"{path}, line {lineno}: expected {ncol} numbers, got an empty line")
        cells = raw.split(",")
        if len(cells) != ncol:
            raise InputError(f"{path}, line {lineno}: expected {ncol} columns, got {len(cells)}")
        for j, cell in enumerate(cells):
            try:
                float(cell)
            except ValueError:
                raise InputError(
                    f"{path}, line {lineno}: expected a number in column {j + 1}, "
                    f"got {cell.strip()!r}"
                ) from None


def _read_text(path: Path, what: str) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what} file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: expected a {what} CSV file, got a directory") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: expected a {what} CSV text file, got binary data") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the {what} file ({exc.strerror})") from None


def read_uniform_table(
    path: str | os.PathLike, headers: Sequence[Sequence[str]], what: str
) -> tuple[np.ndarray, np.ndarray]:
    """Read a CSV table whose first column is a uniform time grid starting at 0.

    Parameters
    ----------
    path : str or path-like
        The CSV file.
    headers : sequence of sequence of str
        Accepted headers, e.g. ``[("t", "x", "y"), ("t", "x", "y", "z")]``. Names are
        compared after stripping blanks, case-insensitively; the first must be the time.
    what : str
        What the file holds (``"path"``, ``"signal"``), used in error messages.

    Returns
    -------
    t : array, shape (n,)
        Times as read (float64), t[0] = 0 and uniformly spaced.
    values : array, shape (n, c)
        The other columns (float64), c = len(header) - 1.

    Raises
    ------
    InputError
        One sentence naming the file (and the line where one applies) for: a missing or
        unreadable file, an empty file, a header that is not one of ``headers``, a row with
        the wrong number of columns, a cell that is not a number, NaN or inf or a magnitude
        beyond :data:`primlib.defaults.MAX_ABS_VALUE`, fewer than
        :data:`MIN_ROWS` rows, t not starting at 0, t not increasing, or t not uniform
        (every step within :data:`T_RTOL` times the mean step of the mean step).

    Examples
    --------
    >>> t, xyz = read_uniform_table("data/paths/zigzag.csv", [("t", "x", "y", "z")], "path")
    >>> xyz.shape[1], float(t[0])
    (3, 0.0)
    """
    path = Path(path)
    text = _read_text(path, what)
    return parse_uniform_table(text, headers, what, path)


def parse_uniform_table(
    text: str, headers: Sequence[Sequence[str]], what: str, label: str | os.PathLike
) -> tuple[np.ndarray, np.ndarray]:
    """Parse CSV text of a uniform time table, as :func:`read_uniform_table` reads a file.

    For text that never was a file (an HTTP request body, say): the same checks and the
    same messages, which name ``label`` where the file reader names the file.

    Parameters
    ----------
    text : str
        The whole table, header line first.
    headers, what
        As for :func:`read_uniform_table`.
    label : str or path-like
        What the text is called in error messages (``"body"``, ``"path_csv"``).

    Returns
    -------
    t : array, shape (n,)
    values : array, shape (n, c)

    Raises
    ------
    InputError
        As :func:`read_uniform_table`, for everything after the file was read.
    """
    path = label
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise InputError(f"{path}: expected a {what} CSV table, got an empty file")

    got = tuple(name.strip().lower() for name in lines[0].split(","))
    accepted = [tuple(h) for h in headers]
    if got not in accepted:
        raise InputError(
            f"{path}: expected {what} header {_expected_headers(accepted)}, got {_fmt_header(got)}"
        )
    ncol = len(got)
    body = lines[1:]

    # Fast path: numpy's C parser. It skips blank lines, so a short result means one was
    # there; any failure is located exactly by the slow diagnostic loop.
    table = None
    if body:
        try:
            table = np.loadtxt(body, delimiter=",", comments=None, dtype=np.float64, ndmin=2)
        except ValueError:
            _diagnose_rows(path, body, ncol, first_line=2)
            raise InputError(f"{path}: expected {what} rows of {ncol} numbers") from None
        if table.shape != (len(body), ncol):
            _diagnose_rows(path, body, ncol, first_line=2)
            raise InputError(f"{path}: expected {what} rows of {ncol} numbers")

    n = 0 if table is None else table.shape[0]
    if n < MIN_ROWS:
        raise InputError(f"{path}: expected at least {MIN_ROWS} {what} rows, got {n}")

    _check_values(path, table, got)
    return _check_grid(path, table)


def _check_values(path: Path, table: np.ndarray, names: Sequence[str]) -> None:
    """Every cell finite and within :data:`primlib.defaults.MAX_ABS_VALUE`."""
    bad = ~(np.abs(table) <= MAX_ABS_VALUE)  # NaN compares False
    if bad.any():
        row, col = np.argwhere(bad)[0]
        value = float(table[row, col])
        want = (
            "a finite number"
            if not np.isfinite(value)
            else f"a magnitude at most {MAX_ABS_VALUE:g} (primlib.defaults.MAX_ABS_VALUE)"
        )
        raise InputError(
            f"{path}, line {row + 2}: expected {want} in column {col + 1} "
            f"({names[col]}), got {value:g}"
        )


def _check_grid(path: Path, table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split off t and check it starts at 0 and is uniform."""
    n = table.shape[0]
    t = np.ascontiguousarray(table[:, 0])
    values = np.ascontiguousarray(table[:, 1:])
    steps = np.diff(t)
    nonincreasing = np.flatnonzero(steps <= 0)
    if nonincreasing.size:
        k = nonincreasing[0]
        raise InputError(
            f"{path}, line {k + 3}: expected t increasing, "
            f"got t = {float(t[k + 1])!r} after t = {float(t[k])!r}"
        )
    dt = (t[-1] - t[0]) / (n - 1)
    if abs(t[0]) > T_RTOL * dt:
        raise InputError(f"{path}, line 2: expected t to start at 0, got t = {float(t[0])!r}")
    off = np.flatnonzero(np.abs(steps - dt) > T_RTOL * dt)
    if off.size:
        k = off[0]
        raise InputError(
            f"{path}, line {k + 3}: expected uniformly spaced t (step {dt:.9g} within a "
            f"relative {T_RTOL:g}), got a step of {steps[k]:.9g}"
        )
    return t, values


def write_table(
    path: str | os.PathLike, header: Sequence[str], t: np.ndarray, values: np.ndarray
) -> None:
    """Write a CSV table: a header line, then t and the value columns, one row per time.

    Numbers are written in Python's shortest round-trip form, so reading the file back with
    :func:`read_uniform_table` returns bit-identical arrays. The file is written to a
    temporary name in the same directory and renamed, so a failure never leaves half a file.

    Parameters
    ----------
    path : str or path-like
        The CSV file (replaced if it exists).
    header : sequence of str
        Column names, time first; ``len(header) == 1 + values.shape[1]``.
    t : array, shape (n,)
        Times.
    values : array, shape (n, c)
        One column per name after the time.

    Raises
    ------
    InputError
        If the shapes disagree with each other or with the header, or a value is NaN or inf.
    """
    path = Path(path)
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    header = [str(h) for h in header]
    if t.ndim != 1 or values.ndim != 2 or values.shape[0] != t.shape[0]:
        raise InputError(
            f"{path}: expected t of shape (n,) and values of shape (n, c), "
            f"got {t.shape} and {values.shape}"
        )
    if len(header) != values.shape[1] + 1:
        raise InputError(
            f"{path}: expected a header of {values.shape[1] + 1} names, got {_fmt_header(header)}"
        )
    table = np.column_stack([t, values])
    if not np.isfinite(table).all():
        raise InputError(f"{path}: expected finite values to write, got NaN or inf")
    rows = "\n".join(",".join(map(repr, row)) for row in table.tolist())
    write_text_atomic(path, _fmt_header(header) + "\n" + rows + ("\n" if rows else ""))


def write_text_atomic(path: Path, content: str) -> None:
    """Write ``content`` (UTF-8, ``\\n`` line ends, mode 0644) to a temporary file in the same
    folder, then rename it to ``path``: a failure never leaves half a file."""
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        os.fchmod(fd, 0o644)  # mkstemp makes 0600; a data file should be readable like any other
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(content)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
