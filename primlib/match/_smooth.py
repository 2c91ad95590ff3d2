"""The query as the arc-length index sees it: smoothed within a bound tied to its noise and eps.

White noise of σ per axis adds about d·σ² to the square of every sample step, so the arc
length of a noisy path is far longer than its noise-free copy's (×4 at σ = 1 % of the
extent on a few hundred samples) and the arc-length index looks at windows of the wrong
length. The index therefore measures arc length on a smoothed copy S of the samples Q:

* the noise is estimated from the third differences, which a smooth path sampled densely
  barely has and white noise has with variance 20σ² per axis: σ̂ = MAD/0.6745/√20, robust
  to the few large values at corners;
* S is Q filtered by a Gaussian of std w samples (the path extended past each end by its
  point reflection, which keeps straight lines straight), w the largest (bisection) whose
  RMS deviation from Q is at most the target δ* = min(1.1·σ̂·√d, eps) — the discrepancy
  principle: remove what looks like noise, no more (the factor 1.1 because the RMS residual
  only approaches the noise RMS as w grows), never more than eps;
* w below half a sample smooths nothing: S is then Q itself;
* a smooth wiggle of a few eps with a period of tens of samples (a hand-drawn path near a
  stored shape) the noise estimate barely sees: a piece whose arc on S is more than 3 %
  longer than along chords of 16 samples (:func:`wiggly`; a smooth curve turning by θ
  over a chord is only θ²/24 longer) is measured on Q smoothed to the target eps instead
  (:func:`smooth_to`). A clean smooth path is never wiggly and is measured as it is;
* a piece the whole path's smoothing moved by more than 1.5 times its bound (the rounded
  corner of a join of two shapes) is smoothed alone (:func:`piece_view`).

Every piece [a, b] knows its own RMS deviation δ (:meth:`Smoothed.deviation`, over the path
samples in it, ≤ δ* over the whole path). For any rigid motion (R, t),
‖S − P·Rᵀ − t‖ ≤ ‖S − Q‖ + ‖Q − P·Rᵀ − t‖ per sample, so in RMS: a stored piece within eps
of Q is within eps + δ of S. The index's gate, stated for a copy within eps of the query it
searches, is applied with eps + δ (:mod:`._index_search`). The exact RMSD check stays on Q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match._options import PathPiece

__all__ = ["Smoothed", "noise_sigma", "gaussian_smooth", "smooth_path", "smooth_bank", "piece_view"]

_MAD = 0.6745  # median |N(0, 1)|
_SLACK = 1.1  # target residual over the estimated noise RMS
_MIN_WIDTH = 0.5  # samples: a narrower Gaussian changes nothing worth the bookkeeping
_BISECTIONS = 12
_CHORD = 16  # samples per chord of :func:`wiggly`
ARC_RTOL = 0.03  # a piece whose arc chords shorten by more is wiggly
_FFT_TAPS = 129  # wider kernels go through the FFT
_CORNER = 1.5  # a piece moved by more than this times the path's bound: smoothed alone


def noise_sigma(points: np.ndarray) -> float:
    """Estimated std σ̂ of white noise per axis in uniformly timed samples (module notes).

    Parameters
    ----------
    points : array, shape (n, d)

    Returns
    -------
    float
        0 for fewer than 8 samples.
    """
    if points.shape[0] < 8:
        return 0.0
    d3 = np.diff(points, 3, axis=0)
    return float(np.median(np.abs(d3))) / _MAD / math.sqrt(20.0)


def gaussian_smooth(points: np.ndarray, width: float) -> np.ndarray:
    """``points`` (n, d) filtered by a Gaussian of std ``width`` samples, each end extended
    by its point reflection 2·p₀ − p_i (so a straight line is unchanged), truncated at 4
    std and renormalised; through the FFT for wide kernels (O(n log n), not O(n·width):
    on a noisy straight line the width grows to n/4)."""
    n = points.shape[0]
    half = max(1, min(int(math.ceil(4.0 * width)), n - 1))
    x = np.arange(-half, half + 1, dtype=float)
    kern = np.exp(-0.5 * (x / width) ** 2)
    kern /= kern.sum()
    ext = np.concatenate(
        [
            2.0 * points[0] - points[half:0:-1],
            points,
            2.0 * points[-1] - points[-2 : -half - 2 : -1],
        ]
    )
    if kern.size > _FFT_TAPS:
        size = 1 << int(ext.shape[0] + kern.size - 2).bit_length()
        spec = np.fft.rfft(ext, size, axis=0) * np.fft.rfft(kern, size)[:, None]
        return np.fft.irfft(spec, size, axis=0)[kern.size - 1 : ext.shape[0]]
    out = np.empty_like(points)
    for j in range(points.shape[1]):
        out[:, j] = np.convolve(ext[:, j], kern, mode="valid")
    return out


@dataclass(frozen=True)
class Smoothed:
    """A path's smoothed copy (module notes) and its deviation from the samples.

    Attributes
    ----------
    path : PathPiece
        The smoothed samples, same duration.
    width : float
        Gaussian std in samples (0: not smoothed, ``path`` is the original).
    target : float
        The bound δ* on the whole path's RMS deviation.
    cum : array, shape (n + 1,)
        Prefix sums of |s_i − q_i|², for :meth:`deviation`.
    """

    path: PathPiece
    width: float
    target: float
    cum: np.ndarray

    def deviation(self, a: float, b: float) -> float:
        """RMS of |s_i − q_i| over the path samples i in the piece [a, b] (normalised time)."""
        n = self.cum.size - 1
        if self.width == 0.0:
            return 0.0
        i0, i1 = _samples(n, a, b)
        return math.sqrt(max(self.cum[i1 + 1] - self.cum[i0], 0.0) / (i1 + 1 - i0))


def _samples(n: int, a: float, b: float) -> tuple[int, int]:
    """The first and last of n path samples in the piece [a, b] (normalised time)."""
    i0 = min(max(int(math.floor(a * (n - 1) + 1e-9)), 0), n - 1)
    return i0, min(max(int(math.ceil(b * (n - 1) - 1e-9)), i0), n - 1)


def wiggly(points: np.ndarray, a: float, b: float) -> bool:
    """Whether the piece [a, b] of ``points`` is more than ``ARC_RTOL`` longer along its
    samples than along chords of ``_CHORD`` samples: wiggles shorter than a chord make its
    arc (a smooth curve turning by θ over a chord is only 1 − θ²/24 longer than it)."""
    n = points.shape[0]
    i0, i1 = _samples(n, a, b)
    if i1 - i0 < 4 * _CHORD:
        return False
    p = points[i0 : i1 + 1]
    fine = float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))
    idx = np.append(np.arange(0, i1 - i0, _CHORD), i1 - i0)
    coarse = float(np.sum(np.linalg.norm(np.diff(p[idx], axis=0), axis=1)))
    return coarse < (1.0 - ARC_RTOL) * fine


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return math.sqrt(float(np.mean(np.sum((a - b) ** 2, axis=1))))


def smooth_path(path: PathPiece, eps: float) -> Smoothed:
    """The smoothed copy of ``path`` the index measures arc length on (module notes).

    Parameters
    ----------
    path : PathPiece
    eps : float
        The match tolerance: the smoothing never moves the samples by more than eps RMS.

    Returns
    -------
    Smoothed
    """
    q = path.points
    n, d = q.shape
    return smooth_to(path, min(_SLACK * noise_sigma(q) * math.sqrt(d), eps))


def smooth_to(path: PathPiece, target: float) -> Smoothed:
    """``path`` filtered by the widest Gaussian within ``target`` RMS of its samples."""
    q = path.points
    n = q.shape[0]
    width = _width(q, target)
    if width == 0.0:
        return Smoothed(path, 0.0, 0.0, np.zeros(n + 1))
    s = gaussian_smooth(q, width)
    dev2 = np.sum((s - q) ** 2, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(dev2)])
    return Smoothed(PathPiece(s, path.duration), width, target, cum)


def _width(q: np.ndarray, target: float) -> float:
    """The largest Gaussian std (bisection, samples) whose RMS deviation from ``q`` is at
    most ``target``; 0 when even half a sample's is above it."""
    n = q.shape[0]
    if not target > 0 or n < 8 or _rms(gaussian_smooth(q, _MIN_WIDTH), q) > target:
        return 0.0
    lo, hi = _MIN_WIDTH, max(_MIN_WIDTH, (n - 1) / 4.0)
    if _rms(gaussian_smooth(q, hi), q) <= target:
        return hi
    for _ in range(_BISECTIONS):  # geometric: the residual grows about like log w
        mid = math.sqrt(lo * hi)
        if _rms(gaussian_smooth(q, mid), q) <= target:
            lo = mid
        else:
            hi = mid
    return lo


_BLOCK = 16  # rows of one block of the screen


def _screen(points: np.ndarray, offsets: np.ndarray, period: int):
    """Per primitive: Σ|Δ³p|², Σ|half-sample Gaussian residual|² (its 3 middle taps; the
    outer two are 3e-4) and the count of third differences, over blocks of 16 consecutive
    rows starting every ``period`` rows that lie in one primitive (a strided view: a sparse
    screen reads only the rows it uses)."""
    n = points.shape[0]
    k = offsets.size - 1
    first = np.arange(0, n - _BLOCK + 1, period)
    prim = np.searchsorted(offsets, first, side="right") - 1
    keep = prim == np.searchsorted(offsets, first + _BLOCK - 1, side="right") - 1
    first, prim = first[keep], prim[keep]
    g = np.exp(-0.5 * (np.arange(-1, 2) / _MIN_WIDTH) ** 2)
    g /= g.sum()
    view = sliding_window_view(points, _BLOCK, axis=0)
    en3, en1 = np.empty(first.size), np.empty(first.size)
    for c0 in range(0, first.size, 1024):  # 1,024 blocks at a time: temporaries in cache
        blk = view[first[c0 : c0 + 1024]]  # (blocks, d, 16)
        d3 = blk[..., 3:] - blk[..., :-3] + 3.0 * (blk[..., 1:-2] - blk[..., 2:-1])
        res = g[0] * (blk[..., :-2] - blk[..., 1:-1]) + g[2] * (blk[..., 2:] - blk[..., 1:-1])
        en3[c0 : c0 + 1024] = np.einsum("bij,bij->b", d3, d3)
        en1[c0 : c0 + 1024] = np.einsum("bij,bij->b", res, res)
    e3 = np.bincount(prim, en3, minlength=k)
    # per third difference: the residual's mean over its block rescaled to the same count
    e1 = np.bincount(prim, en1 * (_BLOCK - 3) / (_BLOCK - 2), minlength=k)
    return e3, e1, np.bincount(prim, minlength=k) * (_BLOCK - 3)


def smooth_bank(points: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every stored primitive smoothed like a query with no eps (its own noise only).

    Most libraries hold clean primitives: a vectorised screen (on one block of samples in
    8 on long primitives) first keeps only those whose RMS residual after a half-sample
    Gaussian (its 3 middle taps, interior samples) is at most 3·RMS(Δ³)·√d/√20 (RMS(Δ³)
    per axis), which the target of :func:`smooth_path` never exceeds (median |x| ≤
    √2·RMS(x) by Markov's inequality, and 1.1·√2/0.6745 = 2.31 < 3); only those are
    smoothed, one by one.

    Parameters
    ----------
    points : array, shape (N, d)
        The primitives' samples laid end to end.
    offsets : array, shape (k + 1,)

    Returns
    -------
    smoothed : array, shape (N, d)
        ``points`` itself when no primitive is smoothed.
    deviation : array, shape (N,)
        |s_i − p_i| per sample (zeros where not smoothed).
    """
    n, d = points.shape
    dev = np.zeros(n)
    starts, counts = offsets[:-1], np.diff(offsets)
    if n < 8:
        return points, dev
    # one block in 8 is plenty on long primitives (their noise is white and even)
    period = _BLOCK * int(np.clip(counts.min() // 256, 1, 8))
    e3, e1, m = _screen(points, offsets, period)
    # target² ≤ (3 · RMS(Δ³ per axis) / √20)² · d = 9 · (e3 / (m d)) / 20 · d
    maybe = np.flatnonzero((counts >= 8) & ((m < 2 * _BLOCK) | (e1 <= 9.0 * e3 / 20.0)))
    if maybe.size == 0:
        return points, dev
    out = points.copy()
    for i in maybe:
        q = points[starts[i] : starts[i] + counts[i]]
        width = _width(q, _SLACK * noise_sigma(q) * math.sqrt(d))
        if width > 0.0:
            s = gaussian_smooth(q, width)
            out[starts[i] : starts[i] + counts[i]] = s
            dev[starts[i] : starts[i] + counts[i]] = np.linalg.norm(s - q, axis=1)
    return out, dev


def piece_view(sm: Smoothed, path: PathPiece, a: float, b: float,
               eps: float) -> tuple[PathPiece, float, float, float]:  # fmt: skip
    """The piece [a, b] of ``path`` as the index sees it: on ``sm``, the whole path smoothed,
    unless that moved the piece's samples by more than 1.5 times its bound (RMS); then the
    piece's own samples smoothed alone (:func:`smooth_path`). Returns the path it lies on,
    a and b in that path's normalised time, and the piece's RMS deviation.

    The whole path's width is set by its noise (or, for a wiggly piece, by eps); the
    Gaussian rounds every corner it spans. Where a piece holds the join of two shapes, the
    rounded corner shortened its arc and bent its shape (a noisy path of three random
    primitives at 1 %: the copy smoothed to eps = 3.2, the piece being wiggly, moved it by
    6.8 RMS): its copy in the library was left out of the pool, while the piece alone,
    whose smoothing stops at its ends, was matched as the grid matches it. White
    noise moves a piece of k samples by δ* give or take 1/√(6k) of it (d = 3): 1.5 is
    3.5 standard deviations at k = 8.
    """
    dev = sm.deviation(a, b)
    n = path.n
    i0, i1 = _samples(n, a, b)
    if sm.width == 0.0 or dev <= _CORNER * sm.target or i1 - i0 < 7:
        return sm.path, a, b, dev
    span = i1 - i0
    own = smooth_path(PathPiece(path.points[i0 : i1 + 1], path.duration * span / (n - 1)), eps)
    a1, b1 = (a * (n - 1) - i0) / span, (b * (n - 1) - i0) / span
    return own.path, a1, b1, own.deviation(a1, b1)
