"""Interpolation of uniformly sampled curves at fractional sample indices (vectorised)."""

from __future__ import annotations

import numpy as np

__all__ = ["coefficients", "cubic_at", "cubic_rows", "CurveTable"]


def coefficients(p0, p1, p2, p3):
    """Catmull-Rom's (c1, c2, c3) on the interval p1 -> p2 (neighbours p0, p3): the value
    is p1 + f (c1 + f (c2 + f c3)) / 2 at the fraction f, the derivative (per sample)
    (c1 + 2 f c2 + 3 f² c3) / 2."""
    return p2 - p0, 2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3, 3.0 * (p1 - p2) + p3 - p0


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
    p0, p1, p2, p3 = (points.take(j, axis=0) for j in (i0, i1, i2, i3))  # take: ~4x faster
    c1, c2, c3 = coefficients(p0, p1, p2, p3)
    val = p1 + 0.5 * f * (c1 + f * (c2 + f * c3))
    if not derivative:
        return val
    return val, 0.5 * (c1 + f * (2.0 * c2 + 3.0 * f * c3))


def cubic_rows(points: np.ndarray, start: np.ndarray, last: np.ndarray, x: np.ndarray):
    """:func:`cubic_at` with its derivative for m rows of queries, coordinates apart.

    Parameters
    ----------
    points : array, shape (N, d)
        Concatenated samples (C-contiguous).
    start, last : array of int, shape (m, 1)
        First row and last sample index (count − 1) of each row's curve.
    x : array, shape (m, k)
        Fractional sample indices, clipped to [0, last].

    Returns
    -------
    (array, array), shapes (m, d, k)
        Values and d/dx, the numbers :func:`cubic_at` gives, each coordinate a contiguous
        run of k: the weights of a point then broadcast along it, not across d (a broadcast
        over a last axis of 2 or 3 costs several times a contiguous one).
    """
    d = points.shape[1]
    flat = points.reshape(-1)
    x = np.minimum(np.maximum(x, 0.0), last)
    i = np.minimum(x.astype(np.int64), last - 1)  # floor: x >= 0
    f = (x - i)[:, None, :]
    i1 = ((start + i) * d)[:, None, :] + np.arange(d)[:, None]  # flat index, (m, d, k)
    p1 = flat.take(i1)
    p0 = flat.take(i1 - (d * (i > 0))[:, None, :])  # the neighbours clamped at the ends
    i1 += d
    p2 = flat.take(i1)
    i1 += (d * (i + 2 <= last))[:, None, :]
    p3 = flat.take(i1)
    # coefficients()'s operations in their order (the same numbers to the last bit), in
    # place: fewer temporaries
    c1 = p2 - p0
    c2 = 2.0 * p0
    c2 -= 5.0 * p1
    c2 += 4.0 * p2
    c2 -= p3  # 2 p0 − 5 p1 + 4 p2 − p3
    c3 = p1 - p2
    c3 *= 3.0
    c3 += p3
    c3 -= p0  # 3 (p1 − p2) + p3 − p0
    return _horner(p1, c1, c2, c3, f)


def _horner(p1, c1, c2, c3, f):
    """Value and d/dx from the coefficients at the fractions ``f``, in place on c2 and c3
    (they are spent): ``p1 + 0.5 f (c1 + f (c2 + f c3))`` and
    ``0.5 (c1 + f (2 c2 + 3 f c3))``, the factors 0.5·f and 3·f formed once on f's shape."""
    val = f * c3
    val += c2
    val *= f
    val += c1
    val *= 0.5 * f
    val += p1
    c3 *= 3.0 * f
    c2 *= 2.0
    c2 += c3
    c2 *= f
    c2 += c1
    c2 *= 0.5
    return val, c2


class CurveTable:
    """:func:`cubic_rows` from a table of every interval's (p1, c1, c2, c3) (Catmull-Rom's
    :func:`coefficients` at the interval's start sample): one gather of each and the value
    and derivative's Horner steps, no neighbour indices and no coefficient arithmetic per
    query (half the time of :func:`cubic_rows` or less), the same numbers to the last bit
    (the table holds what :func:`cubic_rows` computes, with its operations in their order).

    A curve's rows are formed the first time a query asks for it: the table's arrays are
    allocated empty, so only the curves a search refines on take memory.

    Parameters
    ----------
    points : array, shape (N, d)
        Concatenated samples of the curves.
    offsets : array of int, shape (k + 1,)
        Curve i is ``points[offsets[i]:offsets[i + 1]]``.
    """

    def __init__(self, points: np.ndarray, offsets: np.ndarray) -> None:
        self.points = np.ascontiguousarray(points, dtype=float)
        self.offsets = np.asarray(offsets)
        spans = np.maximum(np.diff(self.offsets) - 1, 0)  # intervals of each curve
        self.first = np.concatenate([[0], np.cumsum(spans)])[:-1]  # its first table row
        self.done = np.zeros(spans.size, dtype=bool)
        self.d = self.points.shape[1]
        self.flat = [np.empty(int(spans.sum()) * self.d) for _ in range(4)]  # p1, c1, c2, c3
        self._dims = np.arange(self.d)[:, None]

    def _build(self, curves: np.ndarray) -> None:
        d = self.d
        for c in curves.tolist():
            q = self.points[self.offsets[c] : self.offsets[c + 1]]
            if q.shape[0] >= 2:
                # interval i's neighbours clamped at the ends, as cubic_rows takes them
                p0, p1 = np.concatenate([q[:1], q[:-2]]), q[:-1]
                p2, p3 = q[1:], np.concatenate([q[2:], q[-1:]])
                r0 = int(self.first[c]) * d
                for out, v in zip(self.flat, (p1, *coefficients(p0, p1, p2, p3)), strict=True):
                    out[r0 : r0 + v.size] = v.ravel()
            self.done[c] = True

    def rows(self, curve: np.ndarray, last: np.ndarray, x: np.ndarray):
        """:func:`cubic_rows` for rows of queries ``x`` (m, k) on curves ``curve`` (m,) of
        ``last`` + 1 samples (m, 1): values and d/dx, shapes (m, d, k)."""
        return self.rows_from(self.bases(curve), last, x)

    def bases(self, curve: np.ndarray) -> np.ndarray:
        """The flat offsets of curves ``curve``'s first rows, shape (m, 1), their rows formed
        if not yet: what :meth:`rows_from` takes (a refinement asks for the same curves at
        every step: it finds them once)."""
        need = curve[~self.done[curve]]
        if need.size:
            self._build(np.unique(need))
        return self.first[curve][:, None] * self.d

    def rows_from(self, base: np.ndarray, last: np.ndarray, x: np.ndarray):
        """:meth:`rows` of the curves whose :meth:`bases` are ``base`` (m, 1)."""
        d = self.d
        x = np.minimum(np.maximum(x, 0.0), last)
        i = np.minimum(x.astype(np.int64), last - 1)  # floor: x >= 0
        f = (x - i)[:, None, :]
        at = (base + i * d)[:, None, :] + self._dims  # (first + i)·d + axis: the same integers
        return _horner(*(t.take(at) for t in self.flat), f)
