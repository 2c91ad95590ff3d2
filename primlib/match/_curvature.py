"""A lower bound from the piece's sharpest turn against the curvature of the stored rows a
window reads: the grid's windows that cannot hold a match, left out before any is resampled.

A path that stops dead or sets off at once (a dwell in a part program, sampled without its
ramps), or turns a sharp corner, has a large second difference where it does; a smooth stored
primitive played slowly has small ones. The grid (:mod:`._grid`) searches such a piece at
every time scale, and at the slow scales, where a window is a few stored samples long, each
of millions of windows moves so little per grid step that its cell's slack keeps it near
the gate: on 1,000 primitives the edge of a rest cost 6-10 s a probe, most of it on windows
this bound rules out.

**The piece's side.** The exact check (:mod:`._segment`) compares K path samples q_i with
the window's points w_i = c(x0 + i·σ) (c the primitive's Catmull-Rom interpolant,
:func:`._interp.cubic_at`; σ stored samples per path sample: the time scale times the ratio
of the sample times). For residuals e_i = q_i − R w_i − t (any rotation R, translation t)
and a lag m, Δ²_m e_i = e_{i−m} − 2e_i + e_{i+m} = Δ²_m q_i − R Δ²_m w_i (t cancels), and by
Cauchy–Schwarz |Δ²_m e_i| ≤ √6·(|e_{i−m}|² + |e_i|² + |e_{i+m}|²)^½ ≤ √6·√K·ρ. So

    ρ ≥ (|Δ²_m q_i| − |Δ²_m w_i|) / √(6K)        for every i, m.

**The stored side.** On an interval [j, j + 1] the interpolant is p_j + ½f(c1 + f(c2 + f c3))
with c2 = 2A − B, c3 = B − A, A and B the samples' second differences centred at j and j + 1
(at a primitive's first and last sample, those with the clamped end's ghost p_{−1} = p_0:
a whole sample step), so c''(f) = (2 − 3f)A + (3f − 1)B and |c''| ≤ 3·D2, D2 the largest of
the rows' second differences the window reads. Then |c(x − δ) − 2c(x) + c(x + δ)| ≤
δ²·max|c''| (c is C¹, piecewise cubic: the second difference is ∫∫ c''), so
|Δ²_m w_i| ≤ 3·D2·(mσ)².

A window is left out when every row its grid cell reads (starts within h of the grid's,
lasting up to the cell's longest, σ up to its σ) has D2 at most
max_m (H_m − √(6K)·eps)/(3·m²·σ²) (:func:`critical`; H_m the largest |Δ²_m q_i|, with margins
for round-off): no window of that cell is within eps at the path's samples, which is what a
match is. The rows' D2 are kept as their maxima over blocks of ``_BLOCK`` rows, and the
windows left out are found as runs from the runs of blocks below the critical D2
(:meth:`Curvature.out`). A primitive that starts or ends moving keeps its windows there (its
ghost is a kink as sharp as a sudden start). On the random walks of ``bench_match_novel.py``
D2 is 0.4-2.6 eps at a primitive's sharpest and far less along most of it; a stop from 8.8
eps a sample has H_3 = 26 eps, and on a 12-sample piece 93-99 % of the windows of the time
scales up to 0.7 are out.
"""

from __future__ import annotations

import math

import numpy as np

from primlib.match._grid_blocks import Scale

__all__ = ["MARGIN", "Curvature", "lag_turns", "critical", "minus"]

MARGIN = 1e-7  # relative: the bound is taken as (1 − MARGIN) of itself against eps
_LAGS = 8  # largest lag m taken: a turn within a few samples (each lag costs a pass)
_BLOCK = 16  # rows of the bank whose curvatures one number bounds


class Curvature:
    """The bank's curvatures: per row j, |p_{j−1} − 2p_j + p_{j+1}| of its primitive with the
    clamped ends' ghosts (the first row |p_1 − p_0|, the last |p_{n−2} − p_{n−1}|: what the
    interpolant's first and last intervals read), the largest of every ``_BLOCK`` rows kept,
    raised by a relative 1e-12 and an absolute 8u of ``big``, the largest |coordinate|
    (round-off; the grid keeps it: ``GridSearch._magnitude``)."""

    def __init__(self, points: np.ndarray, offsets: np.ndarray, big: float) -> None:
        n = points.shape[0]
        sq = np.zeros(-(-n // _BLOCK) * _BLOCK)  # squared: the square root of the maxima only
        for c0 in range(1, n - 1, 1 << 16):  # bounded temporaries
            c1 = min(c0 + (1 << 16), n - 1)
            dd = points[c0 - 1 : c1 - 1] + points[c0 + 1 : c1 + 1]
            dd -= points[c0:c1]
            dd -= points[c0:c1]
            sq[c0:c1] = np.einsum("ij,ij->i", dd, dd)
        first, last = offsets[:-1], offsets[1:] - 1
        two = last > first
        for row, other in ((first[two], first[two] + 1), (last[two], last[two] - 1)):
            step = points[other] - points[row]
            sq[row] = np.einsum("ij,ij->i", step, step)
        sq[first[~two]] = 0.0
        self.block = np.sqrt(sq.reshape(-1, _BLOCK).max(axis=1)) * (1.0 + 1e-12)
        self.block += 8.0 * np.finfo(float).eps * big
        self.offsets, self.rows = offsets, n

    def out(self, sc: Scale, crit: float, span: float) -> Scale | None:
        """The windows of scale ``sc`` (``m0`` None) every continuous window of whose grid
        cell (start within h of it, lasting up to ``span``) reads only rows of curvature at
        most ``crit``: runs sorted by primitive and start (None for none)."""
        good = np.concatenate([[False], self.block <= crit, [False]])
        edge = np.flatnonzero(good[1:] != good[:-1])
        r0 = edge[::2] * _BLOCK
        r1 = np.minimum(edge[1::2] * _BLOCK, self.rows)
        off = self.offsets
        p0 = np.searchsorted(off, r0, side="right") - 1
        p1 = np.searchsorted(off, r1 - 1, side="right") - 1
        cnt = p1 - p0 + 1  # a run of good rows split at the primitives' ends
        at = np.repeat(np.arange(cnt.size), cnt)
        p = p0[at] + np.arange(at.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        a = np.maximum(r0[at], off[p]) - off[p]
        b = np.minimum(r1[at], off[p + 1]) - off[p]
        row = np.full(off.size - 1, -1)
        row[sc.prim] = np.arange(sc.prim.size)
        keep = row[p] >= 0
        p, a, b = p[keep], a[keep], b[keep]
        h = sc.h
        # centres ⌊m·h − h⌋ ... ⌈m·h + h + span⌉ within [a, b − 1]
        m_lo = np.maximum(np.ceil((a + h) / h), 0).astype(np.int64)
        m_hi = np.minimum(np.floor((b - 1.0 - h - span) / h), sc.n_start[row[p]] - 1)
        m_hi = m_hi.astype(np.int64)
        ok = m_hi >= m_lo
        if not ok.any():
            return None
        return Scale(p[ok], (m_hi - m_lo + 1)[ok], sc.dur, sc.h, sc.cell, m_lo[ok])


def lag_turns(q: np.ndarray) -> np.ndarray:
    """H_m = max_i |q_{i−m} − 2q_i + q_{i+m}| for m = 1, ..., min((K − 1) // 2, _LAGS),
    lowered by a relative 1e-12 and an absolute 8u of the largest coordinate (round-off)."""
    k = q.shape[0]
    top = min((k - 1) // 2, _LAGS)
    out = np.zeros(top)
    for m in range(1, top + 1):
        dd = q[: k - 2 * m] - 2.0 * q[m : k - m] + q[2 * m :]
        out[m - 1] = math.sqrt(float(np.einsum("ij,ij->i", dd, dd).max()))
    big = float(np.abs(q).max()) if q.size else 0.0
    return np.maximum(out * (1.0 - 1e-12) - 8.0 * np.finfo(float).eps * big, 0.0)


def critical(turns: np.ndarray, sigma: float, k: int, eps: float) -> float:
    """The largest curvature D2 at which no window of up to ``sigma`` stored samples per
    path sample is within ``eps`` of a piece of ``k`` samples with lag turns ``turns``:
    max_m (H_m − √(6K)·eps)/(3·m²·σ²) (module notes); negative where none is."""
    if turns.size == 0 or sigma <= 0.0:
        return -1.0
    need = math.sqrt(6.0 * k) * eps / (1.0 - MARGIN)
    m2 = (np.arange(1, turns.size + 1, dtype=float) * sigma) ** 2
    return float(((turns - need) / (3.0 * (1.0 + 1e-12) * m2)).max())


def minus(part: Scale | None, out: Scale | None, whole: Scale) -> Scale | None:
    """The windows of ``part`` (a :class:`Scale` of ``whole``'s windows, whole or in runs)
    not in ``out`` (runs of ``whole``), as runs sorted by primitive and start; None for
    none."""
    if part is None or out is None:
        return part
    base = np.concatenate([[0], np.cumsum(whole.n_start)])
    a0 = base[np.searchsorted(whole.prim, part.prim)] + part.first()
    a1 = a0 + part.n_start
    b0 = base[np.searchsorted(whole.prim, out.prim)] + out.m0
    b1 = b0 + out.n_start
    c0 = np.concatenate([[0], b1])  # the gaps between the windows left out
    c1 = np.concatenate([b0, [base[-1]]])
    j0 = np.searchsorted(c1, a0, side="right")
    j1 = np.searchsorted(c0, a1, side="left")
    cnt = np.maximum(j1 - j0, 0)
    at = np.repeat(np.arange(cnt.size), cnt)
    j = j0[at] + np.arange(at.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    lo, hi = np.maximum(a0[at], c0[j]), np.minimum(a1[at], c1[j])
    ok = hi > lo
    if not ok.any():
        return None
    lo, hi = lo[ok], hi[ok]
    row = np.searchsorted(base, lo, side="right") - 1
    return Scale(whole.prim[row], hi - lo, whole.dur, whole.h, whole.cell, lo - base[row])
