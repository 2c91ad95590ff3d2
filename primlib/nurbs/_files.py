"""Path files as the command line reads them: a CSV table of samples or geomdl JSON.

A file is geomdl JSON when its name ends in ``.json`` or its first non-blank character is
``{``; anything else is read as a path CSV table. Both refuse a path that does not move
(:func:`primlib.io.check_moving`): it can be neither matched nor learned.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from primlib._errors import InputError
from primlib.io import check_moving, read_path_csv
from primlib.nurbs._trajectory import Trajectory

__all__ = ["is_json_path", "read_path", "read_path_samples"]

# points along a JSON curve for the does-it-move check: a few per control point
_CHECK_POINTS = 1025


def is_json_path(path: str | os.PathLike) -> bool:
    """True for a ``.json`` name or a file whose first non-blank character is ``{``."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        return True
    try:
        with path.open("rb") as fh:
            head = fh.read(256)
    except OSError:
        return False  # the CSV reader says what is wrong with the file
    return head.lstrip(b"\xef\xbb\xbf \t\r\n").startswith(b"{")


def _read_json(path: str | os.PathLike) -> Trajectory:
    tr = Trajectory.from_json(path)
    check_moving(tr.at(np.linspace(0.0, 1.0, _CHECK_POINTS + 4 * tr.n_ctrlpts)), str(path))
    return tr


def _read_csv(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    t, points = read_path_csv(path)
    check_moving(points, str(path))
    return t, points


def read_path(path: str | os.PathLike, tol: float | None = None) -> Trajectory:
    """The path in a file: a CSV table fitted by :meth:`Trajectory.from_samples`, or a
    geomdl JSON curve taken as it is (:meth:`Trajectory.from_json`, with ``"duration"``).

    Parameters
    ----------
    path : str or path-like
        Path CSV (``t,x,y`` or ``t,x,y,z``) or geomdl JSON file.
    tol : float, optional
        Fit tolerance for a CSV file (see :meth:`Trajectory.from_samples`).

    Returns
    -------
    Trajectory

    Raises
    ------
    InputError
        A malformed file, values beyond :data:`primlib.defaults.MAX_ABS_VALUE`, or a path
        that does not move; the message names the file.
    """
    if is_json_path(path):
        return _read_json(path)
    t, points = _read_csv(path)
    dt = float(t[-1]) / (t.shape[0] - 1)
    try:
        return Trajectory.from_samples(points, dt, tol=tol)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def read_path_samples(path: str | os.PathLike, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Samples of the path in a file: a CSV table as it is, a geomdl JSON curve sampled at dt.

    Parameters
    ----------
    path : str or path-like
        Path CSV or geomdl JSON file.
    dt : float
        Sample time (s) for a JSON curve; its duration must be a whole number of steps.

    Returns
    -------
    t : array, shape (n,)
    points : array, shape (n, d)

    Raises
    ------
    InputError
        As :func:`read_path`, or a JSON curve whose duration dt does not divide.
    """
    if not is_json_path(path):
        return _read_csv(path)
    tr = _read_json(path)
    try:
        return tr.times(dt), tr.sample(dt)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None
