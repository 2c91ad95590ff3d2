"""Checks shared by every entry point of the matcher: a path's samples, a time-scale range."""

from __future__ import annotations

import math

import numpy as np

from primlib._errors import InputError
from primlib.defaults import MAX_ABS_VALUE, MIN_EXTENT_REL

__all__ = ["check_path_samples", "check_time_scale"]


def check_path_samples(points: np.ndarray, where: str = "path") -> None:
    """Refuse path samples that cannot be matched (non-finite, out of range, or not moving).

    Run before any work, so a bad path costs nothing.

    Parameters
    ----------
    points : array, shape (n, d)
        The path's samples.
    where : str
        What to name in the message (a file name).

    Raises
    ------
    InputError
        A value that is not finite or beyond :data:`primlib.defaults.MAX_ABS_VALUE`
        (its second moments would overflow), or an extent (largest distance from the
        centroid) below :data:`primlib.defaults.MIN_EXTENT_REL` of the largest coordinate
        magnitude (or of 1 unit): a constant path, whose tolerance would be round-off.
    """
    pts = np.asarray(points, dtype=float)
    finite = np.isfinite(pts)
    if not finite.all():
        i, j = np.argwhere(~finite)[0]
        raise InputError(f"{where}: expected finite coordinates, got {pts[i, j]} at sample {i}")
    with np.errstate(over="ignore"):
        mag = np.abs(pts)
    if pts.size and mag.max() > MAX_ABS_VALUE:
        i, j = np.unravel_index(np.argmax(mag), mag.shape)
        raise InputError(
            f"{where}: expected coordinates within ±{MAX_ABS_VALUE:.0e}, "
            f"got {pts[i, j]:.3g} at sample {i}"
        )
    scale = max(float(mag.max()) if pts.size else 0.0, 1.0)
    extent = float(np.sqrt(((pts - pts.mean(axis=0)) ** 2).sum(axis=1)).max()) if pts.size else 0.0
    if extent <= MIN_EXTENT_REL * scale:
        raise InputError(
            f"{where}: the path does not move (largest distance from its centroid "
            f"{extent:.3g}, at most {MIN_EXTENT_REL:g} of its coordinates' size {scale:.3g}), "
            "nothing to match"
        )


def check_time_scale(time_scale: tuple[float, float], name: str = "time_scale") -> None:
    """Refuse a time-scale range that is not finite 0 < low <= high (an :class:`InputError`
    under ``name``: the argument's, or the CLI's option)."""
    lo, hi = time_scale
    if not (0 < lo <= hi and math.isfinite(hi)):
        raise InputError(f"{name}: expected finite bounds 0 < low <= high, got {lo:g} {hi:g}")
