"""Input checks of the Trajectory constructors: numbers, sample arrays, knot vectors.

Each raises :class:`primlib.InputError` with one sentence naming the argument, what was
expected and what was received.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.defaults import MAX_ABS_VALUE

__all__ = ["frozen", "positive", "degree_of", "points_of", "clamped_knots", "radius", "ULPS"]

ULPS = 8
"""End knots within this many units in the last place of the end value count as equal."""


def frozen(a: np.ndarray) -> np.ndarray:
    """A read-only float64 copy."""
    a = np.array(a, dtype=np.float64, copy=True)
    a.setflags(write=False)
    return a


def positive(value: Any, name: str, unit: str = "") -> float:
    """``value`` as a positive finite float."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a positive number{unit}, got {value!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise InputError(f"{name}: expected a positive finite number{unit}, got {value!r}")
    return x


def degree_of(degree: Any) -> int:
    """``degree`` as an int >= 1 (bool refused)."""
    if isinstance(degree, bool) or not isinstance(degree, int | np.integer) or degree < 1:
        raise InputError(f"degree: expected an integer >= 1, got {degree!r}")
    return int(degree)


def points_of(points: Any, name: str = "points") -> np.ndarray:
    """(n, 2) or (n, 3) float64 array of finite values within ``MAX_ABS_VALUE``.

    Beyond :data:`primlib.defaults.MAX_ABS_VALUE` the sums every later stage forms (second
    moments, squared distances) lose their resolution or overflow, so such values are refused
    here rather than poisoning a library.
    """
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a numeric array of shape (n, 2) or (n, 3)") from None
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise InputError(f"{name}: expected shape (n, 2) or (n, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        row = int(np.argwhere(~np.isfinite(arr))[0, 0])
        raise InputError(f"{name}: expected finite values, got NaN or inf in row {row}")
    big = np.abs(arr) > MAX_ABS_VALUE
    if big.any():
        row, col = np.argwhere(big)[0]
        raise InputError(
            f"{name}: expected values of magnitude at most {MAX_ABS_VALUE:g} "
            f"(primlib.defaults.MAX_ABS_VALUE), got {float(arr[row, col]):g} in row {int(row)}"
        )
    return arr


def radius(points: np.ndarray) -> float:
    """Largest distance of the points from their centroid: a size that rotation keeps."""
    centred = points - points.mean(axis=0)
    return float(np.sqrt(np.einsum("ij,ij->i", centred, centred).max()))


def clamped_knots(knots: Any, m: int, p: int) -> np.ndarray:
    """The knot vector of m control points of degree p, checked and mapped onto [0, 1].

    Knots within :data:`ULPS` units in the last place of an end knot are taken as that end
    knot: geomdl's own ``split_curve`` writes end knots one or two ulps below 1.
    """
    try:
        kv = np.array(knots, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("knots: expected a numeric array") from None
    if kv.shape != (m + p + 1,):
        raise InputError(
            f"knots: expected shape ({m + p + 1},) for {m} control points of degree {p}, "
            f"got {kv.shape}"
        )
    if not np.isfinite(kv).all() or np.any(np.diff(kv) < 0):
        raise InputError("knots: expected finite non-decreasing values, got otherwise")
    for end in (kv[0], kv[-1]):
        slack = ULPS * np.spacing(max(abs(kv[0]), abs(kv[-1]), kv[-1] - kv[0], 1e-300))
        kv[np.abs(kv - end) <= slack] = end
    if (
        kv[0] == kv[-1]
        or np.any(kv[: p + 1] != kv[0])
        or np.any(kv[-p - 1 :] != kv[-1])
        or kv[p + 1] == kv[0]
        or kv[-p - 2] == kv[-1]
    ):
        raise InputError(
            f"knots: expected a clamped vector (exactly {p + 1} equal knots at each end) "
            f"spanning a non-empty interval, got {kv[: p + 1].tolist()} ... "
            f"{kv[-p - 1 :].tolist()}"
        )
    interior = kv[p + 1 : -p - 1]
    if interior.size:
        _, counts = np.unique(interior, return_counts=True)
        if counts.max() > p:
            raise InputError(
                f"knots: expected interior multiplicity at most the degree {p} "
                f"(a continuous path), got {int(counts.max())}"
            )
    if kv[0] != 0.0 or kv[-1] != 1.0:
        kv = (kv - kv[0]) / (kv[-1] - kv[0])
        kv[: p + 1] = 0.0
        kv[-p - 1 :] = 1.0
    return kv
