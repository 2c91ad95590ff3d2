"""Path CSV files: header ``t,x,y`` or ``t,x,y,z``, t from 0 on a uniform grid."""

from __future__ import annotations

import os

import numpy as np

from primlib._errors import InputError
from primlib.io._csv import read_uniform_table, write_table

__all__ = ["PATH_HEADERS", "read_path_csv", "write_path_csv"]

PATH_HEADERS = [("t", "x", "y"), ("t", "x", "y", "z")]
"""Accepted path CSV headers, 2-D and 3-D."""


def read_path_csv(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read a path CSV file.

    Parameters
    ----------
    path : str or path-like
        CSV file with header ``t,x,y`` or ``t,x,y,z``.

    Returns
    -------
    t : array, shape (n,)
        Times, starting at 0, uniformly spaced.
    points : array, shape (n, d)
        Positions, d = 2 or 3.

    Raises
    ------
    InputError
        For any malformed file (see :func:`primlib.io._csv.read_uniform_table`).
    """
    return read_uniform_table(path, PATH_HEADERS, "path")


def write_path_csv(path: str | os.PathLike, t: np.ndarray, points: np.ndarray) -> None:
    """Write a path CSV file with header ``t,x,y`` or ``t,x,y,z``.

    Parameters
    ----------
    path : str or path-like
        Output file (replaced atomically).
    t : array, shape (n,)
        Times.
    points : array, shape (n, d)
        Positions, d = 2 or 3.

    Raises
    ------
    InputError
        If points is not (n, 2) or (n, 3), or the shapes or values are bad.
    """
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise InputError(
            f"{path}: expected path points of shape (n, 2) or (n, 3), got {points.shape}"
        )
    write_table(path, PATH_HEADERS[points.shape[1] - 2], t, points)
