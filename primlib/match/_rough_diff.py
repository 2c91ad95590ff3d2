"""The roughness bound (:mod:`._rough`) on banks too large for its table: R_j from each
primitive's largest differences, its inside apart from its two ends.

:mod:`._rough` bounds ‖(I − P) W‖ for every window of a primitive by reading every support
of the bank, ~0.2-1 s a bin of h on 2 million samples, and its R_j is dominated by the
windows that reach a primitive's first or last sample interval: the ghost the clamped
Catmull-Rom repeats there (p̃_−1 = p_0) is a kink of the size of the first step, where a
primitive does not start at rest. On 1,000 random primitives whose ends move, R_j was 0.28 by
the median (K = 8, h in [1, 2]), above the roughness of the noise it was to reject; the inside
windows' own is ~1e-5 (design log, stop 53). Here both parts are bounded from numbers kept
per primitive, O(k) a bin:

**Inside** (windows whose points all lie in [1, n − 2]: they read no ghost). Let P_p project
onto the polynomials of degree ≤ p in the sample index (p = 3 as in :mod:`._rough`, or
p = 2). Any L samples x of a support are T + Σ_j (Δ^(p+1) x)_j G_j, T the polynomial of degree
p through the first p + 1 of them and G_j the sequence whose (p+1)-th differences are the unit
impulse at j (G_j(m) = C(m − j − 1, p) for m > j + p, else 0). I − P_p removes T, so

    ‖(I − P_p) x‖ ≤ D_(p+1) · c_p(L),   c_p(L) = Σ_j ‖(I − P_p) G_j‖,

D_(p+1) the largest |Δ^(p+1)| of the primitive's samples (per coordinate, then the norm over
coordinates), and the least-squares cubic's leading coefficient is at most D_3/6 +
D_4·Σ_j |lead·G_j| (T's is Δ³/3!). With these in place of ‖r‖ and |a| the bound of
:mod:`._rough` holds as written for p = 3; for p = 2 the interpolant reproduces the support's
quadratic exactly, so ‖(I − P_2) W‖ ≤ ‖Φ‖₂·D_3·c_2(L), with no periodic term.

**Ends.** A window reaching the first interval reads the ghost. Write it as the polynomial of
degree p through p_0 ... p_p continued one sample back, plus δ = p_0 − that value: the
continued sequence has no (p+1)-th difference at the ghost (its p-th is the next one's), so
the inside bound holds for it, and the ghost's column of Φ adds ‖Φ e‖·‖δ‖, ‖Φ e‖ ≤ (2/27)·
√(⌊1/h⌋ + 1) (the points in [0, 1) weigh it by φ on [1, 2]). The last interval likewise. So
R_j of every window is the inside bound plus both ends' terms.

The query's side is :mod:`._rough`'s, with P_p: the bound per primitive is the larger of the
two degrees'. A primitive whose inside is excluded but not its ends keeps only the windows
near its ends (:class:`._gates.Gates`); one excluded whole is skipped, and a probe none of
whose primitives can hold the piece fails unsearched (:func:`._reject.rejects`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import comb

from primlib.match._rough import (
    _G,
    _U,
    K_MAX,
    _basis,
    _phi,
    bin_edges,
    query_roughness,
    scales_kept,
)

__all__ = ["DiffRoughness", "diff_scales"]

_FAR = 2.0 / 27.0 * (1.0 + 1e-9)  # max |φ| on 1 ≤ |t| ≤ 2
_DEGREES = (2, 3)


@functools.lru_cache(maxsize=256)
def constants(size: int, p: int) -> tuple[float, float]:
    """(c_p(L), Σ_j |lead·G_j|) for supports of at most ``size`` samples (module notes): the
    largest over L ≤ size (a short primitive's support is all of it); (0, 0) below p + 2."""
    best = (0.0, 0.0)
    for n in range(p + 2, size + 1):
        basis = _basis.__wrapped__(n, p)  # not kept: the probes' bases stay in the cache
        m = np.arange(n)
        j = np.arange(n - p - 1)[:, None]
        green = np.where(m >= j + p + 1, comb(m - j - 1, p), 0.0)  # (n − p − 1, n)
        res = green - (green @ basis) @ basis.T
        c = float(np.sqrt(np.einsum("jm,jm->j", res, res)).sum())
        lead = 0.0
        if p == 3:
            t = np.arange(n, dtype=float) - 0.5 * (n - 1)
            lead = float(np.abs(green @ np.linalg.pinv(np.vander(t, 4, increasing=True))[3]).sum())
        best = (max(best[0], c), max(best[1], lead))
    return best[0] * (1.0 + 1e-9), best[1] * (1.0 + 1e-9)


class DiffRoughness:
    """Per primitive, its largest third and fourth differences and its ends' ghost terms
    (module notes); R_j of a bin of h from them."""

    def __init__(self, points: np.ndarray, offsets: np.ndarray) -> None:
        self.points = points
        self.offsets = np.asarray(offsets, dtype=np.int64)
        # the largest |coordinate|, without an (N, d) temporary
        self.scale = max(float(points.max()), -float(points.min())) if points.size else 0.0
        self._dmax: dict[int, np.ndarray] | None = None
        self._ghost: dict[int, np.ndarray] | None = None

    @property
    def dmax(self) -> dict[int, np.ndarray]:
        """Per primitive, the norm over coordinates of its largest |Δ³| and |Δ⁴| (inf for one
        of fewer than 5 samples: never excluded), computed at the first probe that needs them
        (a clean path never does: 0.1-0.2 s on 2 million samples)."""
        if self._dmax is None:
            self._dmax = _largest_differences(self.points, self.offsets)
        return self._dmax

    @property
    def ghost(self) -> dict[int, np.ndarray]:
        """Per primitive, ‖δ‖ at its first sample plus at its last (module notes), for the
        degrees 2 and 3 (inf for one of fewer than 5 samples)."""
        if self._ghost is None:
            off, pts = self.offsets, self.points
            ok = np.diff(off) >= 5
            first, last = off[:-1][ok], off[1:][ok] - 1
            # the polynomial of degree p through p + 1 samples, one sample on
            back = {2: np.array([3.0, -3.0, 1.0]), 3: np.array([4.0, -6.0, 4.0, -1.0])}
            ghost = {}
            for p, w in back.items():
                head = sum(w[i] * pts[first + i] for i in range(p + 1))
                tail = sum(w[i] * pts[last - i] for i in range(p + 1))
                ghost[p] = np.full(off.size - 1, np.inf)
                ghost[p][ok] = np.linalg.norm(pts[first] - head, axis=1)
                ghost[p][ok] += np.linalg.norm(pts[last] - tail, axis=1)
            self._ghost = ghost  # whole, at once: a server's readers share the bank
        return self._ghost

    def bins(self, k: int, h_lo: float, h_hi: float,
             p: int) -> list[tuple[float, float, np.ndarray, np.ndarray]]:  # fmt: skip
        """(h0, h1, inside R_j, every window's R_j) of each bin [h0, h1] of :mod:`._rough`'s
        grid that h in [h_lo, h_hi] falls in, lowest first, for K = ``k`` and degree ``p``."""
        return [(h0, h1, *self._bin(k, h0, h1, p)) for _, h0, h1 in bin_edges(h_lo, h_hi)]

    def bound(self, k: int, h_lo: float, h_hi: float, p: int) -> tuple[np.ndarray, np.ndarray]:
        """(inside, every window) R_j of every primitive over h in [h_lo, h_hi]: the largest
        of the bins'."""
        bins = self.bins(k, h_lo, h_hi, p)
        return tuple(np.maximum.reduce([b[i] for b in bins]) for i in (2, 3))

    def _bin(self, k: int, h0: float, h1: float, p: int) -> tuple[np.ndarray, np.ndarray]:
        size = math.floor(1.0 + (k - 1) * h1 * (1.0 + 1e-9)) + 4  # as :mod:`._rough`'s supports
        phi = _phi(h0 * (1.0 - 1e-9))
        c, lead = constants(size, p)
        d4, d3 = self.dmax[4], self.dmax[3]
        with np.errstate(invalid="ignore"):  # inf · 0 on primitives too short
            if p == 3:
                inside = phi * c * d4 + _G * math.sqrt(k) * (d3 / 6.0 + lead * d4)
            else:
                inside = phi * c * d3
        # round-off: each difference errs by ≤ 2^(p+1)·(p + 1)·u·scale per coordinate
        inside = inside + _U * self.scale * (phi * (c + lead) * 2.0 ** (p + 1) * 3.0 + math.sqrt(k))
        ends = _FAR * math.sqrt(math.floor(1.0 / (h0 * (1.0 - 1e-9))) + 1.0) * self.ghost[p]
        return inside, inside + ends


def diff_scales(table: DiffRoughness, q: np.ndarray, steps: float,
                time_scale: tuple[float, float],
                eps: float) -> tuple[np.ndarray, ...] | None:  # fmt: skip
    """Per primitive j, the time scales [lo_j, hi_j] within ``time_scale`` where one of its
    inside windows may lie within eps of the piece ``q`` (K, d), which lasts ``steps`` sample
    steps of the bank, and those where one of any of its windows may: (lo_in, hi_in, lo_all,
    hi_all), lo_j > hi_j where there is none. A bin of h is left out where either degree's
    (‖(I − P_p) q‖ − R_j)/√K reaches eps. None where no bin can be (K outside 5 ...
    ``K_MAX``, or a piece within eps of its own polynomials of both degrees)."""
    k = q.shape[0]
    if not 5 <= k <= K_MAX:
        return None
    per = steps / (k - 1)  # h of a window at time scale 1
    lo, hi = time_scale
    keep = None  # (2, bins, k): inside, every
    for p in _DEGREES:
        rq = query_roughness(q, p)
        if rq < eps * math.sqrt(k):
            continue
        bins = table.bins(k, lo * per, hi * per, p)
        kept = np.array([[(rq - r) / math.sqrt(k) < eps * (1.0 + 1e-9) for r in b[2:]]
                         for b in bins]).transpose(1, 0, 2)  # fmt: skip
        keep = kept if keep is None else keep & kept
    if keep is None:
        return None
    edges = [b[:2] for b in bins]
    return (*scales_kept(keep[0], edges, per, time_scale),
            *scales_kept(keep[1], edges, per, time_scale))  # fmt: skip


def _largest_differences(points: np.ndarray, offsets: np.ndarray) -> dict[int, np.ndarray]:
    """{3: D_3, 4: D_4} per primitive (:attr:`DiffRoughness.dmax`): the differences of the
    whole bank a coordinate at a time (bounded temporaries), those that cross a primitive's
    end dropped, the largest of each primitive's run (it starts at its first sample)."""
    counts = np.diff(offsets)
    ok = counts >= 5
    first = offsets[:-1][ok]
    local = np.arange(points.shape[0]) - np.repeat(offsets[:-1], counts)
    out = {}
    for order in (3, 4):
        limit = np.where(ok, counts - order - 1, -1)  # a short one's own rows too
        drop = local[:-order] > np.repeat(limit, counts)[:-order]
        top = np.zeros((first.size, points.shape[1]))
        for c in range(points.shape[1]):
            col = np.abs(np.diff(points[:, c], order))
            col[drop] = -np.inf
            if first.size:
                top[:, c] = np.maximum.reduceat(col, first)
        out[order] = np.full(counts.size, np.inf)
        out[order][ok] = np.linalg.norm(top, axis=1)
    return out
