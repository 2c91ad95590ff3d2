"""Path CSV files: header ``t,x,y`` or ``t,x,y,z``, t from 0 on a uniform grid."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.defaults import MIN_EXTENT_REL
from primlib.io._csv import parse_uniform_table, read_uniform_table, write_table, write_text_atomic

__all__ = [
    "PATH_HEADERS",
    "read_path_csv",
    "parse_path_csv",
    "write_path_csv",
    "read_path_json",
    "write_path_json",
    "check_moving",
]

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
        For any malformed file (see :func:`primlib.io.read_uniform_table`).
    """
    return read_uniform_table(path, PATH_HEADERS, "path")


def parse_path_csv(text: str, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Parse path CSV text (a request body, say) as :func:`read_path_csv` reads a file.

    Errors name ``label`` where :func:`read_path_csv` names the file.
    """
    return parse_uniform_table(text, PATH_HEADERS, "path", label)


def check_moving(points: np.ndarray, source: str) -> None:
    """Refuse a path that does not move: nothing to match, nothing to learn.

    Its extent (largest distance of a point from the centroid) must be at least
    :data:`primlib.defaults.MIN_EXTENT_REL` times its largest coordinate magnitude (or
    times 1 unit, whichever is larger): below that the points differ only by rounding.

    Parameters
    ----------
    points : array, shape (n, d)
        Finite positions.
    source : str
        Where they came from (a file name), for the message.

    Raises
    ------
    InputError
        If the path does not move.
    """
    centred = points - points.mean(axis=0)
    extent = float(np.sqrt(np.einsum("ij,ij->i", centred, centred).max()))
    floor = MIN_EXTENT_REL * max(1.0, float(np.abs(points).max()))
    if not extent >= floor:
        raise InputError(
            f"{source}: expected a path that moves (extent at least {floor:.3g}), got one "
            f"that stays within {extent:.3g} of its centre"
        )


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


def read_path_json(path: str | os.PathLike) -> Any:
    """Parse a path JSON file (geomdl's exchange format; see ``Trajectory.from_json``).

    Raises
    ------
    InputError
        If the file is missing, unreadable, or not valid JSON (with the line of the fault).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: no such path JSON file") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: expected a path JSON text file, got binary data") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the path JSON file ({exc.strerror})") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}, line {exc.lineno}: expected JSON, got {exc.msg.lower()}"
        ) from None


def write_path_json(path: str | os.PathLike, data: Any) -> None:
    """Write a JSON document atomically (temporary file in the same folder, then rename)."""
    path = Path(path)
    write_text_atomic(path, json.dumps(data, indent=1) + "\n")
