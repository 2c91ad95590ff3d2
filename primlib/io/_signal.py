"""Signal CSV files: header ``t,ux,uy`` or ``t,ux,uy,uz``, on the time grid of their path.

A signal is a feedforward input, one column per axis, sampled at t = 0, dt, ..., T: the
same grid as the path it was learned for (docs/api.rst). These functions read and write that
format on top of :func:`primlib.io._csv.read_uniform_table`, which checks the header, the
numbers and the time grid; :func:`read_signal_csv` can also check the grid against the
path's.
"""

from __future__ import annotations

import os

import numpy as np

from primlib._errors import InputError
from primlib.io._csv import T_RTOL, parse_uniform_table, read_uniform_table, write_table

__all__ = ["SIGNAL_HEADERS", "read_signal_csv", "parse_signal_csv", "write_signal_csv"]

SIGNAL_HEADERS = [("t", "ux", "uy"), ("t", "ux", "uy", "uz")]
"""Accepted signal CSV headers, 2 and 3 axes."""


def read_signal_csv(
    path: str | os.PathLike, t: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Read a signal CSV file, optionally checking it lies on a given time grid.

    Parameters
    ----------
    path : str or path-like
        CSV file with header ``t,ux,uy`` or ``t,ux,uy,uz``.
    t : array, shape (n,), optional
        The path's time grid. When given, the signal must have the same number of samples
        and the same times (within a relative 1e-6 of the step).

    Returns
    -------
    t : array, shape (n,)
        Times, starting at 0, uniformly spaced.
    u : array, shape (n, d)
        The input, one column per axis, d = 2 or 3.

    Raises
    ------
    InputError
        For a malformed file (see :func:`primlib.io._csv.read_uniform_table`), or a grid
        that differs from ``t``.

    Examples
    --------
    >>> t, u = read_signal_csv("data/library/circle.signal.csv")
    >>> u.shape == (len(t), 3)
    True
    """
    ts, u = read_uniform_table(path, SIGNAL_HEADERS, "signal")
    _check_grid(path, ts, t)
    return ts, u


def parse_signal_csv(
    text: str, label: str, t: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Parse signal CSV text (a request body, say) as :func:`read_signal_csv` reads a file.

    Errors name ``label`` where :func:`read_signal_csv` names the file.
    """
    ts, u = parse_uniform_table(text, SIGNAL_HEADERS, "signal", label)
    _check_grid(label, ts, t)
    return ts, u


def _check_grid(path: str | os.PathLike, ts: np.ndarray, t: np.ndarray | None) -> None:
    if t is not None:
        t = np.asarray(t, dtype=np.float64)
        dt = (t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 0.0
        dts = (ts[-1] - ts[0]) / (len(ts) - 1)
        if len(ts) != len(t) or np.max(np.abs(ts - t)) > T_RTOL * dt:
            raise InputError(
                f"{path}: expected the path's time grid ({len(t)} samples, dt = {dt:.9g} s, "
                f"T = {t[-1]:.9g} s), got {len(ts)} samples, dt = {dts:.9g} s, "
                f"T = {ts[-1]:.9g} s"
            )


def write_signal_csv(path: str | os.PathLike, t: np.ndarray, u: np.ndarray) -> None:
    """Write a signal CSV file with header ``t,ux,uy`` or ``t,ux,uy,uz``.

    Numbers read back bit for bit; the file is replaced atomically.

    Parameters
    ----------
    path : str or path-like
        Output file.
    t : array, shape (n,)
        Times (the path's grid).
    u : array, shape (n, d)
        The input, d = 2 or 3.

    Raises
    ------
    InputError
        If u is not (n, 2) or (n, 3), the shapes disagree, or a value is NaN or inf.
    """
    u = np.asarray(u, dtype=np.float64)
    if u.ndim != 2 or u.shape[1] not in (2, 3):
        raise InputError(
            f"{path}: expected a signal of shape (n, 2) or (n, 3) to write, got {u.shape}"
        )
    write_table(path, SIGNAL_HEADERS[u.shape[1] - 2], t, u)
