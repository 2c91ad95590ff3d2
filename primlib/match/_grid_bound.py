"""Lower bounds that drop stretches of the time-uniform grid's windows before they are
resampled (:class:`primlib.match._grid.GridSearch`), and the best windows of one time scale.

Notation: K grid points, stride h = D/(K − 1) samples at the duration D, window m of a
primitive the points w_i = P((m + i)·h), i < K, P the Catmull-Rom interpolant of its
samples (:func:`._interp.cubic_at`); q_i the query's K points; chords c_w = w_K − w_1 and
c_q = q_K − q_1; ρ the window's RMSD over the rotation family (eq. (2), ``_kabsch``).

Endpoint bound. With e_i = R w_i + t − q_i for the best motion (R, t),

    K ρ² = Σ |e_i|² ≥ |e_1|² + |e_K|² ≥ |e_K − e_1|² / 2,   e_K − e_1 = R c_w − c_q

(|a|² + |b|² ≥ |a − b|²/2), so ρ ≥ g(c_w)/√(2K) with g(c) = min_R |R c − c_q|:
|c − c_q| (``"none"``), ||c| − |c_q|| (``"full"``: a rotation turns c onto c_q's direction),
hypot(|c_xy| − |c_q,xy|, c_z − c_q,z) (``"z"``). Each g is 1-Lipschitz in c. A slow piece
against fast primitives: every chord far longer than the query's, nearly every window out.

Stretch bound. With d_j = p_{j+1} − p_j the stored steps, on the interval i (fraction
f) P − p_i = α d_{i−1} + β d_i + γ d_{i+1}, α = f(1 − f)²/2, β = (f + 3f² − 2f³)/2,
γ = −f²(1 − f)/2 (Catmull-Rom's weights of the steps; clamped ends: a missing step is 0).
α' + β' + γ' = 1, so P' = d_i + α'(d_{i−1} − d_i) + γ'(d_{i+1} − d_i) and, |α'| + |γ'| ≤ 1/2,

    |P'| ≤ |d_i| + max(|d_{i−1} − d_i|, |d_{i+1} − d_i|)/2    (:func:`speed_bounds`)

(1.5 max |d| with the steps alone, at f = 1/2; near |d_i| on smooth curves). So
|P(x) − P(y)| ≤ Λ|x − y| with Λ the largest such bound over the intervals between x and y.
Start and end of window m move by h per window, so |g(c_w(m)) − g(c_w(m'))| ≤ 2Λ|m − m'|h,
and on the stretch js ≤ m ≤ (j + 1)s

    g(c_w(m)) ≥ max(v_j − 2Λ(m − js)h, v_{j+1} − 2Λ((j + 1)s − m)h) ≥ (v_j + v_{j+1})/2 − Λsh

(v_j = g at the anchor window js; the larger of two lines is at least their mean), and on
its windows m ≤ js + s − 1 also g ≥ v_j − 2Λ(s − 1)h (v_j itself at s = 1), Λ over
every interval that the stretch's starts and ends cross (clipped past a primitive's end, P
is constant there: no faster). With s a divisor of K − 1, the anchor windows' ends
(js + K − 1)h are anchor starts too: one resampled point in s·h per primitive gives every
anchor's chord (:func:`anchor_values`).

A window is dropped only when its bound exceeds its gate (it cannot be a candidate) or the
scale's ``top``-th best RMSD found so far (:class:`Best`: it cannot be among the scale's
best, which are all the search keeps of a scale), each with a margin for round-off
(:func:`beyond`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "endpoint_gap",
    "speed_bounds",
    "stretch_length",
    "anchor_values",
    "stretch_bounds",
    "beyond",
    "Best",
]

# Relative slack in ρ² for round-off: RMSDs from moments lose ~u·(Σ|p̃|² + Σ|q̃|²) to
# cancellation; 1e-9 is ~10⁷ ulps of it
_REL = 1e-9


def endpoint_gap(chord: np.ndarray, q_chord: np.ndarray, rotation: str) -> np.ndarray:
    """g(c) = min over the rotation family of |R c − c_q| for chords c of shape (m, d)."""
    if rotation == "none":
        diff = chord - q_chord
        return np.sqrt(np.einsum("ij,ij->i", diff, diff))
    if rotation == "full":
        return np.abs(np.sqrt(np.einsum("ij,ij->i", chord, chord)) - np.linalg.norm(q_chord))
    flat = np.hypot(chord[:, 0], chord[:, 1]) - math.hypot(q_chord[0], q_chord[1])
    return np.hypot(flat, chord[:, 2] - q_chord[2])


def speed_bounds(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Per stored sample i, |d_i| + max(|d_{i−1} − d_i|, |d_{i+1} − d_i|)/2 ≥ |P'| on the
    interval i (module notes; steps beyond a primitive's ends count 0, as the clamped
    stencil's): shape (N,), 0 at a primitive's last sample (no interval)."""
    n = points.shape[0]
    d = np.zeros((n + 1, points.shape[1]))  # row i + 1: d_i; row 0 and the ends' rows: 0
    d[1:n] = points[1:] - points[:-1]
    d[offsets[1:]] = 0.0  # no step from one primitive to the next
    step = np.sqrt(np.einsum("ij,ij->i", d, d))
    bend = d[1:] - d[:-1]  # row i: d_i − d_{i−1}
    bend = np.sqrt(np.einsum("ij,ij->i", bend, bend))
    out = step[1:] + 0.5 * np.maximum(bend, np.append(bend[1:], 0.0))
    out[offsets[1:] - 1] = 0.0
    return out


def stretch_length(k: int, h: float, span: float) -> int:
    """The largest divisor s of K − 1 with s·h <= ``span`` samples (at least 1)."""
    fits = [s for s in range(1, k) if (k - 1) % s == 0 and s * h <= span]
    return max(fits, default=1)


def anchor_values(anchors: np.ndarray, n_anchor: np.ndarray, lag: int, q_chord: np.ndarray,
                  rotation: str) -> np.ndarray:  # fmt: skip
    """g of every anchor window's chord, primitive by primitive, concatenated.

    ``anchors`` (``n_anchor[p]`` rows per primitive p, in order) are P at every s-th grid
    point; the window at anchor l ends ``lag`` = (K − 1)/s anchors later: the first
    n_anchor − lag anchors of each primitive are windows' starts.
    """
    gap = endpoint_gap(anchors[lag:] - anchors[:-lag], q_chord, rotation)
    ends = np.cumsum(n_anchor)
    cross = (ends[:, None] - np.arange(lag, 0, -1)).ravel()  # chords across primitives
    return np.delete(gap, cross[cross < gap.size])


def stretch_bounds(values: np.ndarray, n_stretch: np.ndarray, reach: np.ndarray,
                   s: int) -> np.ndarray:  # fmt: skip
    """A lower bound on g(c_w) over the windows js .. js + s − 1 of every stretch j of every
    primitive: max((v_j + v_{j+1})/2 − reach, v_j − 2·reach·(s − 1)/s) (module notes;
    ``reach`` = Λ·s·h per stretch; the second is the anchor's own line over the stretch, v_j
    itself at s = 1). ``values`` holds n_stretch[p] + 1 anchor values per primitive."""
    ends = np.cumsum(n_stretch + 1)
    left = np.delete(np.arange(values.size), ends - 1)  # every value but each one's last
    mean = 0.5 * (values[left] + values[left + 1]) - reach
    return np.maximum(mean, values[left] - reach * (2.0 * (s - 1) / s))


def beyond(bound: np.ndarray, limit: np.ndarray | float, rg_q: float, slack: float) -> np.ndarray:
    """Where a lower bound on ρ proves the computed RMSD above ``limit``: bound² > limit²
    plus the round-off of ρ² (relative to Σ|q̃|²/K = rg_q² and to limit²), and ``bound``
    past an absolute ``slack`` for the round-off of the chords (coordinates' magnitude)."""
    limit = np.asarray(limit, dtype=float)
    spare = np.sqrt(limit * limit * (1.0 + _REL) + _REL * rg_q * rg_q)
    return bound - slack > spare


class Best:
    """The ``top`` best windows of one time scale below their gates, by (RMSD, primitive,
    start): the order in which the exhaustive grid ranks them (ties by window)."""

    def __init__(self, top: int) -> None:
        self.top = top
        self.rmsd = np.empty(0)
        self.prim = np.empty(0, dtype=np.int64)
        self.x0 = np.empty(0)

    def add(self, rmsd: np.ndarray, prim: np.ndarray, x0: np.ndarray) -> None:
        """Offer windows (already below their gates)."""
        r = np.concatenate([self.rmsd, rmsd])
        p = np.concatenate([self.prim, prim])
        x = np.concatenate([self.x0, x0])
        if r.size > self.top:  # those at or below the top-th RMSD, ties included
            near = np.flatnonzero(r <= np.partition(r, self.top - 1)[self.top - 1])
            r, p, x = r[near], p[near], x[near]
        keep = np.lexsort((x, p, r))[: self.top]
        self.rmsd, self.prim, self.x0 = r[keep], p[keep], x[keep]

    def limit(self) -> float:
        """The ``top``-th best RMSD so far (+inf while fewer): no window above it enters."""
        return float(self.rmsd[-1]) if self.rmsd.size >= self.top else math.inf
