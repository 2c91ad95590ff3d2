"""A lower bound from a piece's roughness, for every primitive at once: a noisy piece that
nothing matches is rejected before any window is scored (issue 13: failing probes cheap).

The check (:meth:`._segment._Segmenter.probe`) asks whether some window of a stored
primitive -- K points W_i = c(x0 + i·h), c its Catmull-Rom interpolant (:func:`._interp.cubic_at`),
0 ≤ x0, x0 + (K − 1)·h ≤ n − 1, h = duration / (K − 1) in the time-scale range
(:func:`._refine.clamp_many`) -- lies within eps of the piece's K samples q once rotated and
translated: ρ = ‖q − W Rᵀ − 1 tᵀ‖ / √K below eps.

**The query's side.** Let P be the orthogonal projector onto the polynomials of degree ≤ 3 in
the sample index, applied to each coordinate (K × K, acting on the samples). I − P removes
the translation (a constant) and commutes with R (which mixes coordinates, not samples), so
for every R and t

    √K·ρ ≥ ‖(I − P)(q − W Rᵀ)‖ ≥ ‖(I − P) q‖ − ‖(I − P) W‖.

White noise of σ per coordinate leaves (K − 4)·d·σ² of energy in ‖(I − P) q‖²; a window of a
smooth primitive at a modest time scale keeps little in ‖(I − P) W‖.

**The stored side: ‖(I − P) W‖ ≤ R_j over every window of primitive j**, h in a bin
[h0, h1]. Catmull-Rom with its ends clamped is the cardinal interpolation
c(x) = Σ_m p̃_m φ(x − m) of the samples extended by a ghost at each end (p̃_−1 = p_0,
p̃_n = p_n−1), with the kernel φ(t) = 1.5|t|³ − 2.5t² + 1 (|t| ≤ 1), −0.5|t|³ + 2.5t² − 4|t| + 2
(1 ≤ |t| ≤ 2), 0 beyond. The points of a window starting in [i, i + 1) read the samples
S = i − 1, ..., ⌊i + 1 + (K − 1)·h1⌋ + 2 (L of them): W = Φ p̃_S, Φ_km = φ(x_k − m). Split
p̃_S = Q + r with Q the least-squares cubic over S (leading coefficient a, a d-vector) and r
its residual. φ reproduces quadratics exactly and m³ up to a periodic error,
Σ_m m³ φ(x − m) = x³ + g(x − ⌊x⌋) with g(f) = f(1 − f)(1 − 2f), |g| ≤ √3/18, so
W = Q(x) + a·g(frac x) + Φ r, and I − P removes Q(x) (a cubic in k):

    ‖(I − P) W‖ ≤ ‖Φ‖₂·‖r‖ + |a|·(√3/18)·√K,   ‖Φ‖₂ ≤ √(‖Φ‖₁·‖Φ‖∞),

‖Φ‖∞ = max Σ_m |φ(x − m)| = 1 + f(1 − f) ≤ 1.25 (the outer weights sum to −f(1 − f)/2, the
inner to 1 + f(1 − f)/2), and ‖Φ‖₁ ≤ ⌈2/h0⌉ + 0.0741·2·(⌊1/h0⌋ + 1) (a column m: at most ⌈2/h⌉
points within 1 of m, where |φ| ≤ 1, and 2·(⌊1/h⌋ + 1) between 1 and 2 from it, where
|φ| ≤ 2/27 < 0.0741). Any S holding a window's samples will do, so a support running past a
primitive's extended samples is replaced by its last L (or all of them, on a short primitive).
R_j is the largest such bound over the supports of the primitive, with a margin for
round-off; the bins are a fixed geometric grid in h (octaves, their edges 1 % above the
powers of 2), each computed once per K and kept.

**The probe fails** where every primitive that can hold the piece has
(‖(I − P) q‖ − R_j)/√K ≥ eps (:func:`._reject.rejects`): what the check would find, sooner.
Tried only on pieces of 5 to ``K_MAX`` samples (longer ones smooth a primitive's curvature into
R_j, and the check seldom fails there for noise alone), where ‖(I − P) q‖/√K ≥ eps (else no
primitive can be excluded), and on banks of at most ``BANK_MAX`` samples (each bin reads every
window of the bank: ~5 ms on the 8,400 bundled samples, seconds on 2 million; larger banks
bound R_j from each primitive's differences instead, :mod:`._rough_diff`). A tighter R_j
(:mod:`._rough_tight`, a quintic per support) rejects the shortest probes, where a failure
searched or not changes nothing else in the segmentation.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match._rough_tight import tight_bin

__all__ = ["Roughness", "block_roughness", "query_roughness", "rough_bounds", "rough_scales",
           "bin_edges", "scales_kept", "K_MAX", "BANK_MAX"]  # fmt: skip

K_MAX = 16  # samples of the longest piece tried
BANK_MAX = 1 << 17  # stored samples of the largest bank tried
_G = math.sqrt(3.0) / 18.0  # max |f (1 − f)(1 − 2 f)| on [0, 1]
_FAR = 2.0 / 27.0 * (1.0 + 1e-9)  # max |φ| on 1 ≤ |t| ≤ 2 (at |t| = 4/3)
_BINS = 1  # bins per octave of h (the largest bound is the top bin's: 4 gave the same, 5x the time)
_U = 1e-9  # round-off margin, relative to the coordinates' magnitude
_EDGE = 1e-10  # log2(1 + 1e-9) > 1.4e-9: a bin covers h a relative 1e-9 past its edges
# the bins' edges 1 % above the powers of 2, where the counts of points near a sample jump
# (2/h and 1/h whole: the bin [2, 4] would take the 2 points of h just below 2)
_SHIFT = 1.01


def query_roughness(q: np.ndarray, p: int = 3) -> float:
    """‖(I − P) q‖ of the piece's K samples (K, d), less a margin for round-off (0 for
    K ≤ p + 1: every sequence is then a polynomial of degree p; P the polynomials of degree
    ≤ ``p``, cubics here, :mod:`._rough_diff` also quadratics): :func:`block_roughness` of the
    one piece."""
    return float(block_roughness(q[None], p)[0])


def block_roughness(blocks: np.ndarray, p: int = 3) -> np.ndarray:
    """‖(I − P) q‖ of each of m pieces of K samples, (m, K, d) → (m,), less a margin for
    round-off (relative ``_U`` of the piece's largest coordinate; 0 for K ≤ p + 1)."""
    m, k, d = blocks.shape
    if k <= p + 1:
        return np.zeros(m)
    basis = _basis(k, p)
    qc = blocks - blocks.mean(axis=1, keepdims=True)
    res = qc - np.einsum("kj,mjd->mkd", basis, np.einsum("kj,mkd->mjd", basis, qc))
    norm = np.sqrt(np.einsum("mkd,mkd->m", res, res))
    return np.maximum(norm - _U * np.abs(blocks).max(axis=(1, 2)) * math.sqrt(k * d), 0.0)


@functools.lru_cache(maxsize=64)
def _basis(k: int, p: int = 3) -> np.ndarray:
    """Orthonormal basis (k, p + 1) of the polynomials of degree ≤ p (cubics) in the sample
    index (kept per k: every short probe asks)."""
    t = np.arange(k, dtype=float) - 0.5 * (k - 1)
    return np.linalg.qr(np.vander(t / max(k - 1, 1), p + 1, increasing=True))[0]


def bin_edges(h_lo: float, h_hi: float) -> list[tuple[int, float, float]]:
    """(number, h0, h1) of each bin of the fixed geometric grid in h (module notes) that h in
    [h_lo, h_hi] falls in, lowest first. Each bin holds h up to a relative 1e-9 past its
    edges: a range that ends on a bin's edge but for round-off (h at time scale 4 is
    4·(1 + ε) when the path's dt is the bank's) asks for no bin beyond, whose supports are
    twice as long."""
    b0 = math.floor(_BINS * math.log2(h_lo / _SHIFT) + _EDGE)
    b1 = max(math.ceil(_BINS * math.log2(h_hi / _SHIFT) - _EDGE), b0 + 1)
    return [(b, _SHIFT * 2.0 ** (b / _BINS), _SHIFT * 2.0 ** ((b + 1) / _BINS))
            for b in range(b0, b1)]  # fmt: skip


def scales_kept(keep: np.ndarray, edges: list[tuple[float, float]], per: float,
                time_scale: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Per primitive, the hull [lo_j, hi_j] within ``time_scale`` of the bins ``keep``
    (bins, k) keeps, in time scales (h / ``per``; ``edges`` the bins' (h0, h1)); lo_j > hi_j
    where it keeps none."""
    lo, hi = time_scale
    # the first and last bin each primitive keeps (argmax on a column of False: 0, masked)
    first, last = keep.argmax(axis=0), keep.shape[0] - 1 - keep[::-1].argmax(axis=0)
    h0 = np.array([e[0] for e in edges]) * (1.0 - 1e-9)
    h1 = np.array([e[1] for e in edges]) * (1.0 + 1e-9)
    none = ~keep.any(axis=0)
    s_lo = np.where(none, np.inf, np.maximum(h0[first] / per, lo))
    s_hi = np.where(none, -np.inf, np.minimum(h1[last] / per, hi))
    return s_lo, s_hi


class Roughness:
    """Per primitive, R_j (module notes) of K-sample windows over a range of h, each bin
    computed once and kept."""

    def __init__(self, points: np.ndarray, offsets: np.ndarray) -> None:
        offsets = np.asarray(offsets, dtype=np.int64)
        counts = np.diff(offsets)
        size = counts + 2  # the extended samples: a ghost before and after each primitive
        self.ext_off = np.concatenate([[0], np.cumsum(size)])
        local = np.arange(self.ext_off[-1]) - np.repeat(self.ext_off[:-1], size) - 1
        last = np.repeat(np.maximum(counts - 1, 0), size)
        rows = np.repeat(offsets[:-1], size) + np.clip(local, 0, last)
        self.ext = np.ascontiguousarray(points[rows])
        self.scale = float(np.abs(points).max()) if points.size else 0.0
        self._bins: dict[tuple[int, int], np.ndarray] = {}
        self._tight: dict[tuple[int, float], np.ndarray] = {}

    def bound(self, k: int, h_lo: float, h_hi: float, tight: bool = False,
              above: float = -math.inf) -> np.ndarray:  # fmt: skip
        """R_j of every primitive for K = ``k`` samples and h in [h_lo, h_hi], shape (k,);
        ``tight``: each support's smaller of this and :mod:`._rough_tight`'s bound, taken
        (and kept) only for the primitives and bins where this one is above ``above`` (a
        few times the time: a fresh index asks for those a probe needs, not every bin's)."""
        bins = self.bins(k, h_lo, h_hi)
        if not tight:
            return np.maximum.reduce([r for _, _, r in bins])
        out = []
        for h0, h1, coarse in bins:
            # a bin's bottom edge is computed the same way each time: with K it names the bin
            kept = self._tight.setdefault((k, h0), np.full(coarse.size, np.nan))
            need = np.flatnonzero((coarse > above) & np.isnan(kept))
            if need.size:
                phi = _phi(h0 * (1.0 - 1e-9))
                kept[need] = tight_bin(self.ext, self.ext_off, k, h0, h1, phi, self.scale, need)
            out.append(np.where(coarse > above, kept, coarse))
        return np.maximum.reduce(out)

    def bins(self, k: int, h_lo: float, h_hi: float) -> list[tuple[float, float, np.ndarray]]:
        """(h0, h1, R_j of every primitive) of each bin [h0, h1] that h in [h_lo, h_hi]
        falls in, lowest first (:func:`bin_edges`)."""
        out = []
        for b, h0, h1 in bin_edges(h_lo, h_hi):
            if (k, b) not in self._bins:
                self._bins[(k, b)] = self._bin(k, h0, h1)
            out.append((h0, h1, self._bins[(k, b)]))
        return out

    def _bin(self, k: int, h0: float, h1: float) -> np.ndarray:
        """R_j for h in [h0, h1] (module notes)."""
        ell = math.floor(1.0 + (k - 1) * h1 * (1.0 + 1e-9)) + 4
        phi = _phi(h0 * (1.0 - 1e-9))  # the bin's bottom, a little below (:meth:`bound`)
        sizes = np.diff(self.ext_off)
        out = np.zeros(sizes.size)
        for size in np.unique(np.minimum(sizes, ell)):
            prims = np.flatnonzero(np.minimum(sizes, ell) == size)
            out[prims] = self._supports(prims, int(size), phi, k)
        margin = _U * self.scale * (phi * math.sqrt(ell * self.ext.shape[1]) + math.sqrt(k))
        return out + margin

    def _supports(self, prims: np.ndarray, size: int, phi: float, k: int) -> np.ndarray:
        """Largest ‖Φ‖·‖r‖ + |a|·g·√K over every support of ``size`` samples of each
        primitive of ``prims`` (their extended samples at least ``size`` long)."""
        if size <= 4:
            return np.zeros(prims.size)  # every sequence of 4 samples is a cubic
        t = np.arange(size, dtype=float) - 0.5 * (size - 1)
        vander = np.vander(t, 4, increasing=True)
        lead = np.linalg.pinv(vander)[3]  # the t³ coefficient of the least-squares cubic
        basis = _basis(size)
        windows = sliding_window_view(self.ext, size, axis=0)  # (rows − size + 1, d, size)
        first = self.ext_off[prims]
        count = self.ext_off[prims + 1] - first - size + 1
        starts = np.repeat(first - np.cumsum(count) + count, count) + np.arange(count.sum())
        ids = np.repeat(np.arange(prims.size), count)
        out = np.zeros(prims.size)
        d = self.ext.shape[1]
        for g0 in range(0, starts.size, 1 << 14):  # blocks of windows: bounded temporaries
            # one (m·d, size) matrix: each product one BLAS call (the cubics hold the
            # constants, so the residual and the leading coefficient need no centring)
            w = windows[starts[g0 : g0 + (1 << 14)]].reshape(-1, size)
            res = (w @ basis) @ basis.T
            np.subtract(w, res, out=res)  # in place: a fresh (m·d, size) array cost 5x more
            res *= res
            val = phi * np.sqrt(res.reshape(-1, d * size).sum(axis=1))
            val += _G * math.sqrt(k) * np.linalg.norm((w @ lead).reshape(-1, d), axis=1)
            seg = ids[g0 : g0 + val.size]
            cut = np.concatenate([[0], np.flatnonzero(np.diff(seg)) + 1])
            np.maximum.at(out, seg[cut], np.maximum.reduceat(val, cut))
        return out


def rough_bounds(rough: Roughness | None, q: np.ndarray, steps: float,
                 time_scale: tuple[float, float], eps: float,
                 tight: bool = False) -> np.ndarray | None:  # fmt: skip
    """(‖(I − P) q‖ − R_j)/√K for every primitive j (module notes): a lower bound on the
    RMSD of any of its windows against the piece ``q`` (K, d), which lasts ``steps`` sample
    steps of the bank, at time scales in ``time_scale``; None where it cannot exclude any
    (no bank table, K outside 5 ... ``K_MAX``, or a piece smooth to within eps). ``tight``:
    R_j of :meth:`Roughness.bound` with ``tight``."""
    k, rq = q.shape[0], _rough_query(rough, q, eps)
    if rq is None:
        return None
    per = steps / (k - 1)  # h of a window at time scale 1
    # tight: only where the plain R_j leaves the primitive in (rq − R_j < eps·√K)
    above = rq - eps * math.sqrt(k) * (1.0 + 1e-9)
    r = rough.bound(k, time_scale[0] * per, time_scale[1] * per, tight, above)
    return (rq - r) / math.sqrt(k)


def _phi(low: float) -> float:
    """The bound on ‖Φ‖₂ for steps h >= ``low`` (module notes)."""
    col = math.ceil(2.0 / low) + _FAR * 2.0 * (math.floor(1.0 / low) + 1.0)
    return math.sqrt(1.25 * col)


def rough_scales(rough: Roughness | None, q: np.ndarray, steps: float,
                 time_scale: tuple[float, float],
                 eps: float) -> tuple[np.ndarray, np.ndarray] | None:  # fmt: skip
    """Per primitive j, the time scales [lo_j, hi_j] within ``time_scale`` where one of its
    windows may lie within eps of the piece ``q``: the hull of the bins of h where
    (‖(I − P) q‖ − R_j)/√K < eps (module notes; lo_j > hi_j where there is none). None
    where :func:`rough_bounds` is. A rough primitive keeps its slow windows, whose steps are
    short, and loses the fast ones, whose supports are long."""
    k, rq = q.shape[0], _rough_query(rough, q, eps)
    if rq is None:
        return None
    per = steps / (k - 1)  # h of a window at time scale 1
    lo, hi = time_scale
    bins = rough.bins(k, lo * per, hi * per)
    keep = np.array([(rq - r) / math.sqrt(k) < eps * (1.0 + 1e-9) for _, _, r in bins])
    return scales_kept(keep, [b[:2] for b in bins], per, time_scale)


def _rough_query(rough: Roughness | None, q: np.ndarray, eps: float) -> float | None:
    """‖(I − P) q‖ of the piece, or None where no primitive can be excluded by it (no bank
    table, K outside 5 ... ``K_MAX``, or a piece smooth to within eps)."""
    if rough is None or not 5 <= q.shape[0] <= K_MAX:
        return None
    rq = query_roughness(q)
    return None if rq < eps * math.sqrt(q.shape[0]) else rq
