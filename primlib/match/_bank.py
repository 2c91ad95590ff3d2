"""Array views of a machine's primitives and cubic evaluation on uniform samples."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from primlib._errors import InputError, NoMatchError

__all__ = ["BankArrays", "as_bank", "cubic_at", "linear_at"]


@dataclass(frozen=True)
class BankArrays:
    """All primitives of one machine on its sample grid, concatenated.

    Attributes
    ----------
    points : array, shape (N, d)
        Every primitive's samples at t = 0, dt, ..., T, one after another.
    offsets : array of int, shape (k + 1,)
        Primitive i is ``points[offsets[i]:offsets[i + 1]]``.
    dt : float
        Sample time (s).
    ids : array of int, shape (k,)
    names : tuple of str or None, length k
    """

    points: np.ndarray
    offsets: np.ndarray
    dt: float
    ids: np.ndarray
    names: tuple

    @property
    def k(self) -> int:
        return len(self.offsets) - 1

    @property
    def dim(self) -> int:
        return self.points.shape[1]

    @property
    def counts(self) -> np.ndarray:
        return np.diff(self.offsets)

    @property
    def durations(self) -> np.ndarray:
        return (self.counts - 1) * self.dt

    def points_of(self, i: int) -> np.ndarray:
        return self.points[self.offsets[i] : self.offsets[i + 1]]

    @classmethod
    def from_list(cls, pieces: list[np.ndarray], dt: float, ids=None, names=None) -> BankArrays:
        """Build from a list of (n_i, d) sample arrays (tests and benchmarks)."""
        counts = [len(p) for p in pieces]
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        ids = np.arange(len(pieces)) if ids is None else np.asarray(ids)
        names = tuple(names) if names is not None else tuple(f"p{i}" for i in ids)
        return cls(np.concatenate(pieces).astype(float), offsets, float(dt), ids, names)


def as_bank(bank: Any) -> BankArrays:
    """Accept a :class:`BankArrays` or any object with the store's Bank attributes.

    Raises
    ------
    NoMatchError
        The bank holds no primitive (an empty library for this machine).
    """
    if isinstance(bank, BankArrays):
        out = bank
    else:
        points = np.asarray(bank.points, dtype=float)
        offsets = np.asarray(bank.offsets, dtype=np.int64)
        names = tuple(getattr(bank, "names", None) or (None,) * (len(offsets) - 1))
        out = BankArrays(points, offsets, float(bank.dt), np.asarray(bank.ids), names)
    if out.k == 0:
        raise NoMatchError("library: no primitive stored for this machine, nothing to match")
    if np.any(out.counts < 2):
        raise InputError("bank: every primitive needs at least 2 samples")
    return out


def cubic_at(
    points: np.ndarray,
    start: np.ndarray,
    count: np.ndarray,
    x: np.ndarray,
    derivative: bool = False,
):
    """Catmull-Rom interpolation of uniformly sampled curves at fractional sample indices.

    Parameters
    ----------
    points : array, shape (N, d)
        Concatenated samples.
    start, count : array of int, broadcastable to x
        First row and number of samples of the curve each query belongs to.
    x : array, shape (m,)
        Fractional sample index within its curve, clipped to [0, count - 1].

    Returns
    -------
    array, shape (m, d)
        Exact at samples, C¹ between them, third-order accurate (end neighbours clamped).
    (array, array)
        With ``derivative=True``: the values and d/dx (per sample index).
    """
    count = np.asarray(count)
    x = np.clip(np.asarray(x, dtype=float), 0.0, count - 1)
    i = np.minimum(np.floor(x).astype(np.int64), count - 2)
    f = (x - i)[:, None]
    last = count - 1
    i0 = start + np.maximum(i - 1, 0)
    i1 = start + i
    i2 = start + i + 1
    i3 = start + np.minimum(i + 2, last)
    p0, p1, p2, p3 = points[i0], points[i1], points[i2], points[i3]
    c1 = p2 - p0
    c2 = 2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
    c3 = 3.0 * (p1 - p2) + p3 - p0
    val = p1 + 0.5 * f * (c1 + f * (c2 + f * c3))
    if not derivative:
        return val
    return val, 0.5 * (c1 + f * (2.0 * c2 + 3.0 * f * c3))


def linear_at(points: np.ndarray, start: np.ndarray, count: np.ndarray, x: np.ndarray):
    """Linear interpolation, same arguments as :func:`cubic_at` (cheap, for indexing)."""
    count = np.asarray(count)
    x = np.clip(np.asarray(x, dtype=float), 0.0, count - 1)
    i = np.minimum(np.floor(x).astype(np.int64), count - 2)
    f = (x - i)[:, None]
    p1 = points[start + i]
    return p1 + f * (points[start + i + 1] - p1)
