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
* w below half a sample smooths nothing: S is then Q itself.

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

from primlib.match._options import PathPiece

__all__ = ["Smoothed", "noise_sigma", "gaussian_smooth", "smooth_path"]

_MAD = 0.6745  # median |N(0, 1)|
_SLACK = 1.1  # target residual over the estimated noise RMS
_MIN_WIDTH = 0.5  # samples: a narrower Gaussian changes nothing worth the bookkeeping
_BISECTIONS = 12


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
    std and renormalised."""
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
        i0 = min(max(int(math.floor(a * (n - 1) + 1e-9)), 0), n - 1)
        i1 = min(max(int(math.ceil(b * (n - 1) - 1e-9)), i0), n - 1)
        return math.sqrt(max(self.cum[i1 + 1] - self.cum[i0], 0.0) / (i1 + 1 - i0))


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
    target = min(_SLACK * noise_sigma(q) * math.sqrt(d), eps)
    none = Smoothed(path, 0.0, 0.0, np.zeros(n + 1))
    if not target > 0 or n < 8 or _rms(gaussian_smooth(q, _MIN_WIDTH), q) > target:
        return none
    lo, hi = _MIN_WIDTH, max(_MIN_WIDTH, (n - 1) / 4.0)
    if _rms(gaussian_smooth(q, hi), q) <= target:
        lo = hi
    else:
        for _ in range(_BISECTIONS):  # geometric: the residual grows about like log w
            mid = math.sqrt(lo * hi)
            if _rms(gaussian_smooth(q, mid), q) <= target:
                lo = mid
            else:
                hi = mid
    s = gaussian_smooth(q, lo)
    dev2 = np.sum((s - q) ** 2, axis=1)
    cum = np.concatenate([[0.0], np.cumsum(dev2)])
    return Smoothed(PathPiece(s, path.duration), lo, target, cum)
