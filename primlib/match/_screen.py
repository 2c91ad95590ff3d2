"""A lower bound on the RMSD of every piece of every primitive against a short piece of the
path, from the pieces' first and second time moments: the starts from which no prefix can
match, rejected before any window is scored (:meth:`._segment._Segmenter._screened`).

The exact check (:mod:`._segment`) compares the path's k = ℓ + 1 samples q_i of a piece
with a stored piece sampled at x_i = x0 + D·i/ℓ (D = x1 − x0 stored samples, within the
time-scale range), after the best rotation R and translation. For orthonormal vectors φ1,
φ2 over the k samples orthogonal to the constants, Bessel's inequality on the centred
residual e_i = q_i − R p(x_i) gives

    k·rmsd² ≥ |Q1 − R P1|² + |Q2 − R P2|²,   Q_m = Σ φ_m,i q_i,   P_m = Σ φ_m,i p(x_i).

With φ1 ∝ i − ℓ/2, summation by parts writes P1 = Σ w_i (p(x_{i+1}) − p(x_i)) with
w_i = −Σ_{j≤i} φ1_j ≥ 0, and each increment is h = D/ℓ times the mean of p' over
[x_i, x_{i+1}] (the Catmull-Rom interpolant is C¹): P1 lies in D·c1·B', c1 = Σw/ℓ, B' any
box holding p' over [x0, x0 + D]. With φ2 ∝ (i − ℓ/2)² − mean (orthogonal to i by
symmetry), summing by parts twice gives P2 = Σ W_i (p(x_{i+2}) − 2p(x_{i+1}) + p(x_i)) with
W the double partial sums of φ2 (of one sign, made >= 0), and each second difference is h²
times a mean of p'' over [x_i, x_{i+2}]: P2 lies in D²·c2·B'', c2 = ΣW/ℓ². Per axis, with
[l, u] the ranges over the sample intervals a piece of duration D can touch:

    none:  k·rmsd² ≥ min_t Σ_a dist(Q1_a, t·[l'_a, u'_a])² + min_s Σ_a dist(Q2_a, s·[l''_a, u''_a])²
    z:     the xy parts by norms (a turn about z keeps |P_xy|), z as for none
    full:  by norms alone (|Q − R P| ≥ ||Q| − |P||)

over t = D·c1 and s = D²·c2 in the time-scale range (cut at powers of two of D, each part
with the ranges over runs of intervals as long as its longest piece); each term is convex
in its variable and quadratic between breakpoints, minimised exactly (the two apart: their
sum is at most the joint minimum). p' on a sample interval is a quadratic in the fraction f
(:func:`._interp.coefficients`): its range is taken at f = 0, 1 and its vertex; p'' = c2 + 3fc3
is linear. Empty intervals after each primitive keep a run inside its primitive.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from primlib.match._interp import coefficients
from primlib.match._refine import duration_range

if TYPE_CHECKING:
    from primlib.match._options import PathPiece, SearchOptions

__all__ = ["SlopeRanges", "min_bound", "screens", "prefixes_fail"]

_SAFE = 1e-6  # relative slack against round-off, on both sides of the comparison
PAD = 256  # empty intervals after each primitive: the longest run (intervals) screened
_BLOCK = 64  # runs per block of the coarse first pass
_RATIO = 2.0**0.5  # of the duration sub-ranges (shorter runs: tighter ranges of p', p'')


class SlopeRanges:
    """Range of each coordinate of the interpolant's derivative p' on every sample
    interval of the bank (shape (N − 1, d): ``lo``, ``hi``; a join between primitives is
    empty: +inf / −inf), and running ranges over windows of 2ʲ intervals, built on demand
    (kept on this object: one segmentation's cache)."""

    def __init__(self, points: np.ndarray, offsets: np.ndarray) -> None:
        n = points.shape[0]
        first = np.repeat(offsets[:-1], np.diff(offsets))  # each sample's primitive start
        last = np.repeat(offsets[1:] - 1, np.diff(offsets))
        i = np.arange(n - 1)
        inside = last[:-1] > i  # interval i → i + 1 within one primitive
        p0 = points[np.maximum(i - 1, first[:-1])]
        p1 = points[i]
        p2 = points[i + 1]
        p3 = points[np.minimum(i + 2, last[:-1])]
        c1, c2, c3 = coefficients(p0, p1, p2, p3)
        # p'(f) = (c1 + 2 f c2 + 3 f² c3) / 2: ends and vertex f* = −c2 / (3 c3)
        d0, d1 = 0.5 * c1, 0.5 * (c1 + 2.0 * c2 + 3.0 * c3)
        with np.errstate(divide="ignore", invalid="ignore"):
            fv = -c2 / (3.0 * c3)
            ok = (fv > 0.0) & (fv < 1.0)
            dv = np.where(ok, 0.5 * (c1 + fv * (2.0 * c2 + 3.0 * fv * c3)), d0)
        lo = np.minimum(np.minimum(d0, d1), dv)
        hi = np.maximum(np.maximum(d0, d1), dv)
        # p''(f) = c2 + 3 f c3: linear on the interval
        lo2 = np.minimum(c2, c2 + 3.0 * c3)
        hi2 = np.maximum(c2, c2 + 3.0 * c3)
        # PAD empty intervals after each primitive: a run of ``width`` <= PAD intervals
        # then exists from every real interval and never reaches into the next primitive
        at = np.repeat(offsets[1:] - 1, PAD)  # insert before each primitive's last sample row
        cols = []
        for a, b in ((lo, hi), (lo2, hi2)):
            pad = _SAFE * (np.abs(a) + np.abs(b)) + 1e-300
            a, b = a - pad, b + pad
            a[~inside] = np.inf
            b[~inside] = -np.inf
            a = np.concatenate([a, np.full((1, a.shape[1]), np.inf)])  # the last join
            b = np.concatenate([b, np.full((1, b.shape[1]), -np.inf)])
            cols += [np.insert(a, at, np.inf, axis=0), np.insert(b, at, -np.inf, axis=0)]
        self._levels = [np.concatenate(cols, axis=1)]  # (N − 1 + PAD, 4d): lo, hi, lo2, hi2
        self._d = points.shape[1]
        self._runs: dict = {}

    @staticmethod
    def rows(bank) -> int:
        """Rows of the tables for ``bank`` (a :class:`~._bank.BankIndex`): its samples and
        the padding after each primitive (each of the up to 8 levels and each run width
        kept holds this many rows of 4d numbers)."""
        return int(bank.points.shape[0]) + PAD * int(bank.k)

    def over(self, width: int) -> tuple[np.ndarray, ...]:
        """Ranges of p' (lo, hi) and of p'' (lo2, hi2) over every run of ``width``
        consecutive intervals inside one primitive, indexed by the first, shape (M, d)
        each (runs from the padding left out)."""
        j = max(int(width).bit_length() - 1, 0)
        d = self._d
        while len(self._levels) <= j:
            t = self._levels[-1]
            s = 1 << (len(self._levels) - 1)
            nxt = np.empty((t.shape[0] - s, 4 * d))
            np.minimum(t[:-s, :d], t[s:, :d], out=nxt[:, :d])
            np.maximum(t[:-s, d : 2 * d], t[s:, d : 2 * d], out=nxt[:, d : 2 * d])
            np.minimum(t[:-s, 2 * d : 3 * d], t[s:, 2 * d : 3 * d], out=nxt[:, 2 * d : 3 * d])
            np.maximum(t[:-s, 3 * d :], t[s:, 3 * d :], out=nxt[:, 3 * d :])
            self._levels.append(nxt)
        t = self._levels[j]
        s = width - (1 << j)
        m = max(t.shape[0] - s, 0)
        a, b = t[:m], t[s : s + m]
        lo, hi = np.minimum(a[:, :d], b[:, :d]), np.maximum(a[:, d : 2 * d], b[:, d : 2 * d])
        keep = np.all(lo <= hi, axis=1)
        return (lo[keep], hi[keep], np.minimum(a[keep, 2 * d : 3 * d], b[keep, 2 * d : 3 * d]),
                np.maximum(a[keep, 3 * d :], b[keep, 3 * d :]))  # fmt: skip

    def runs(self, width: int, rotation: str) -> tuple[tuple, tuple]:
        """:meth:`over` in the rotation family's axes (:func:`_axes`), and the same for
        blocks of ``_BLOCK`` consecutive runs (their union: a first, coarse pass), kept
        per width and family."""
        key = (width, rotation)
        hit = self._runs.get(key)
        if hit is None:
            lo, hi, lo2, hi2 = self.over(width)
            fine = (*_box_axes(lo, hi, rotation), *_box_axes(lo2, hi2, rotation))
            m = fine[0].shape[0]
            starts = np.arange(0, m, _BLOCK)
            coarse = tuple(
                (np.minimum if i % 2 == 0 else np.maximum).reduceat(c, starts, axis=0) if m else c
                for i, c in enumerate(fine)
            )
            hit = self._runs[key] = (fine, coarse)
        return hit


def _box_axes(lo: np.ndarray, hi: np.ndarray, rotation: str):
    """The ranges the bound compares per "axis" (module notes): the coordinates' for
    ``none``; the range of |P_xy| over the box, then z's, for ``z``; |P|'s for ``full``."""
    if rotation == "none":
        return lo, hi
    if rotation == "z":
        near, far = _norm_range(lo[:, :2], hi[:, :2])
        return np.stack([near, lo[:, 2]], axis=1), np.stack([far, hi[:, 2]], axis=1)
    near, far = _norm_range(lo, hi)
    return near[:, None], far[:, None]


def _q_axes(qv: np.ndarray, rotation: str) -> np.ndarray:
    """The path moment in the axes of :func:`_box_axes`."""
    if rotation == "none":
        return qv
    if rotation == "z":
        return np.array([math.hypot(qv[0], qv[1]), qv[2]])
    return np.array([math.sqrt(float(qv @ qv))])


def _norm_range(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest norm of a vector in the boxes [lo, hi] (rows)."""
    gap = np.maximum(np.maximum(lo, -hi), 0.0)  # per axis distance of 0 from [lo, hi]
    far = np.maximum(np.abs(lo), np.abs(hi))
    return np.sqrt((gap * gap).sum(axis=1)), np.sqrt((far * far).sum(axis=1))


def _min_over_t(q: np.ndarray, lo: np.ndarray, hi: np.ndarray, t0: float, t1: float):
    """min over t in [t0, t1] of Σ_a dist(q_a, t·[lo_a, hi_a])², per row (exactly: the
    function is convex and quadratic between the breakpoints t = q_a / lo_a, q_a / hi_a)."""
    q = np.broadcast_to(q, lo.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        bp = np.concatenate([q / lo, q / hi], axis=1)
    bp = np.where(np.isfinite(bp), np.clip(bp, t0, t1), t0)
    bp = np.sort(np.concatenate([np.full((q.shape[0], 1), t0), bp,
                                 np.full((q.shape[0], 1), t1)], axis=1), axis=1)  # fmt: skip
    a, b = bp[:, :-1], bp[:, 1:]
    mid = 0.5 * (a + b)
    # on each piece, the axes whose interval lies above q (t·lo > q) or below it (t·hi < q)
    m = mid[:, :, None]
    alpha = np.where(m * lo[:, None] > q[:, None], lo[:, None],
                     np.where(m * hi[:, None] < q[:, None], hi[:, None], 0.0))  # fmt: skip
    qa = np.where(alpha != 0.0, q[:, None], 0.0)
    aa = (alpha * alpha).sum(axis=2)
    ab = (alpha * qa).sum(axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = np.where(aa > 0, ab / aa, mid)
    ts = np.clip(ts, a, b)[:, :, None]
    gap = np.maximum(np.maximum(ts * lo[:, None] - q[:, None], q[:, None] - ts * hi[:, None]), 0.0)
    return (gap * gap).sum(axis=2).min(axis=1)


def _moments(q: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, float]:
    """The first and second unit moments of the path samples q (k, d), Q1 = Σ φ1_i q_i and
    Q2 = Σ φ2_i q_i, and the factors c1, c2 with P1 ∈ D·c1·B' and P2 ∈ D²·c2·B''
    (module notes: φ2 ⟂ 1, i, with the sign that makes its double partial sums >= 0)."""
    k, ell = q.shape[0], q.shape[0] - 1
    i = np.arange(k) - 0.5 * ell
    phi1 = i / math.sqrt(float(i @ i))
    phi2 = i * i - float(np.mean(i * i))  # ⟂ 1; ⟂ i by symmetry
    phi2 /= math.sqrt(float(phi2 @ phi2))
    w1 = -np.cumsum(phi1)[:-1]  # >= 0: φ1 increases and sums to 0
    w2 = np.cumsum(np.cumsum(phi2)[:-1])[:-1]
    if w2.sum() < 0:
        phi2, w2 = -phi2, -w2
    c1 = float(np.sum(np.maximum(w1, 0.0))) / ell
    c2 = float(np.sum(np.maximum(w2, 0.0))) / (ell * ell)
    return phi1 @ q, c1, phi2 @ q, c2


def _sub_ranges(d_lo: float, d_hi: float):
    """[d_lo, d_hi] cut at the powers of ``_RATIO``, each piece with the run width
    (intervals) that holds a piece of its longest duration ``_RATIO``^(m+1): a few
    widths, kept."""
    m = math.floor(math.log(max(d_lo, 1e-300), _RATIO))
    while True:
        top = _RATIO ** (m + 1)
        yield max(d_lo, _RATIO**m), min(d_hi, top), math.ceil(top) + 1
        if top >= d_hi:
            return
        m += 1


def _loose(q, lo, hi, t0, t1) -> np.ndarray:
    """Σ_a min over t in [t0, t1] of dist(q_a, t·[lo_a, hi_a])², each axis its own t
    (at most the coupled minimum: a cheap first pass)."""
    gap = np.maximum(np.minimum(t0 * lo, t1 * lo) - q, q - np.maximum(t0 * hi, t1 * hi))
    np.maximum(gap, 0.0, out=gap)
    return np.einsum("ij,ij->i", gap, gap)


def _bound(q1, q2, c1, c2, box, bottom: float, top: float, exact: bool) -> np.ndarray:
    """Lower bound of k·rmsd² per run (or block) ``box`` = (l1, u1, l2, u2) for durations
    in [bottom, top]: the first moment's term plus the second's, each minimised over the
    sub-range on its own (their sum is then at most the joint minimum)."""
    l1, u1, l2, u2 = box
    f = _min_over_t if exact else _loose
    return f(q1, l1, u1, bottom * c1, top * c1) + f(
        q2, l2, u2, bottom * bottom * c2, top * top * c2
    )


def _too_long(d_hi: float) -> bool:
    """Whether the longest run of :func:`_sub_ranges` is longer than the padding covers
    (such durations are not screened)."""
    return math.ceil(_RATIO ** math.ceil(math.log(max(d_hi, 1.0), _RATIO))) + 1 > PAD


def min_bound(slopes: SlopeRanges, q: np.ndarray, d_lo: float, d_hi: float,
              rotation: str) -> float:  # fmt: skip
    """Lower bound of min k·rmsd² over every stored piece of duration D in [d_lo, d_hi]
    (stored samples) against the path's k samples ``q`` (k, d) (module notes)."""
    if _too_long(d_hi):
        return 0.0
    q1, c1, q2, c2 = _moments(q)
    q1, q2 = _q_axes(q1, rotation), _q_axes(q2, rotation)
    best = np.inf
    for bottom, top, width in _sub_ranges(d_lo, d_hi):
        if width > PAD:
            return 0.0
        fine, _ = slopes.runs(width, rotation)
        if fine[0].shape[0]:
            g = _bound(q1[None], q2[None], c1, c2, fine, bottom, top, True)
            best = min(best, float(g.min()))
    return best


def screens(slopes: SlopeRanges, q: np.ndarray, d_lo: float, d_hi: float, rotation: str,
            eps: float) -> bool:  # fmt: skip
    """True when no stored piece of duration in [d_lo, d_hi] can be within ``eps`` of the
    path samples ``q`` (k, d): the bound is at least k·eps² (with round-off slack).

    Blocks of runs first, then the runs of the blocks left, each with t free per axis
    (cheap, and lower still); only the runs left get the exact minima over a common t,
    and the first of those below k·eps² ends the screen."""
    if d_hi < d_lo:
        return True
    if _too_long(d_hi):
        return False
    k = q.shape[0]
    need = k * eps * eps * (1.0 + _SAFE) / (1.0 - _SAFE)
    q1, c1, q2, c2 = _moments(q)
    q1, q2 = _q_axes(q1, rotation)[None], _q_axes(q2, rotation)[None]
    for bottom, top, width in _sub_ranges(d_lo, d_hi):
        if width > PAD:
            return False
        fine, coarse = slopes.runs(width, rotation)
        blocks = np.flatnonzero(_bound(q1, q2, c1, c2, coarse, bottom, top, False) < need)
        if blocks.size == 0:
            continue
        rows = (blocks[:, None] * _BLOCK + np.arange(_BLOCK)).ravel()
        rows = rows[rows < fine[0].shape[0]]
        box = tuple(c[rows] for c in fine)
        near = np.flatnonzero(_bound(q1, q2, c1, c2, box, bottom, top, False) < need)
        if near.size == 0:
            continue
        box = tuple(c[near] for c in box)
        if _bound(q1, q2, c1, c2, box, bottom, top, True).min() < need:
            return False
    return True


def prefixes_fail(slopes: SlopeRanges, path: PathPiece, a: float, ends, bank_dt: float,
                  opts: SearchOptions, eps: float) -> bool:  # fmt: skip
    """True when :func:`screens` rejects the path's piece [a, b] for every normalised end b
    in ``ends`` (stopping at the first it does not), at the samples and over the durations
    the exact check uses (its points, :func:`._refine.duration_range`)."""
    for b in ends:
        q = path.at(np.linspace(a, b, path.confirm_points(a, b)))
        d_lo, d_hi = duration_range(math.inf, (b - a) * path.duration / bank_dt, opts)
        if not screens(slopes, q, d_lo, float(d_hi), opts.rotation, eps):
            return False
    return True
