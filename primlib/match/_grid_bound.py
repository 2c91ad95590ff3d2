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

Block bound. On the interval i, |P(x) − p_i| ≤ Λ_i (the speed bound above over at most one
sample), so P over the intervals of a block of W consecutive ones (numbered through the whole
bank) lies in the box [min (p_i − Λ_i), max (p_i + Λ_i)] per axis (:func:`block_boxes`,
:func:`halved_boxes`). A window's computed start m·h lies on the interval i0 = ⌊m·h⌋ and its
computed end, D later up to round-off, on i1 with i1 − i0 ∈ [⌊D⌋ − 1, ⌊D⌋ + 1] (P at an
integer x is p_x, in the box of x's own block, also at a primitive's last sample): from the
block X of i0 the end lies in the blocks X + ⌊(⌊D⌋ − 1)/W⌋ to X + 1 + ⌊⌊D⌋/W⌋, and the chord
in the box difference E − B_X (E those blocks' union, :func:`chord_boxes`), whose distance
from c_q (``"none"``) or the distance of |c_q| from the box's range of lengths (``"full"``;
``"z"`` too, whose g is at least the full family's) is at or below g(c_w)
(:func:`box_gaps`). Neighbouring blocks' boxes touch (the interpolant is continuous), so
the end's blocks must be 2 or more on: the search takes W at or below (⌊D⌋ − 1)/3, the end
3 to 7 blocks on, and a union over all of 3 to 7 (a wider box, a smaller gap) screens the
blocks first (:func:`chord_radii`, kept per W). A block of starts is then proven out of a
limit with one bound, before anything of it is resampled (a block may straddle two
primitives: its box holds both, a bound all the same).

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
    "block_boxes",
    "halved_boxes",
    "below32",
    "above32",
    "chord_boxes",
    "chord_radii",
    "box_gaps",
    "spare",
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


def window_energies(rows: np.ndarray, k: int, big: float) -> tuple[np.ndarray, np.ndarray]:
    """Σ|w_i − w̄|² of every window of K = ``k`` consecutive points of each stretch ``rows``
    (n, m, d) (window t: rows t .. t + K − 1, t ≤ m − K), from running sums in the stretch's
    own coordinates (its first point at 0), and a bound on how far each is from the sum the
    windows centred on their own means give (``GridSearch._score``): both (n, m − K + 1).

    The running sums of T = Σ_j |l_j|² (l_j the local points, m ≤ 20 terms) and of the l_j
    each carry at most m·u of their terms' sums, the local points u of theirs; Σ|w − w̄|² =
    S₂ − |S₁|²/K with |S₁|² ≤ K·S₂ ≤ K·T then errs by a few hundred u·T. The centred sums
    err by K·u of theirs (at most T) and by K·|e|² for a mean off by e ≤ K·u·|w| (the
    first-order term is Σ(w_i − w̄)·e = 0), |w| ≤ ``big`` (the coordinates' magnitude):
    1e-12·T (~4,500 u) and 1e-25·big² (~10⁶ K³u²) hold both."""
    n, m, d = rows.shape
    local = rows - rows[:, :1]
    run = np.zeros((n, m + 1, d + 1))
    run[:, 1:, :d] = local
    run[:, 1:, d] = np.einsum("nmd,nmd->nm", local, local)
    np.cumsum(run, axis=1, out=run)
    sums = run[:, k:] - run[:, :-k]
    energy = sums[..., d] - np.einsum("ntd,ntd->nt", sums[..., :d], sums[..., :d]) / k
    err = 1e-12 * run[:, -1:, d] + 1e-25 * d * big * big
    return energy, np.broadcast_to(err, energy.shape)


def gyration_below(energy: np.ndarray, err: np.ndarray, query_energy: float,
                   k: int) -> np.ndarray:  # fmt: skip
    """A bound at or below the radius-of-gyration bound |√(E/K) − √(E_q/K)|
    (:func:`primlib.match._bounds.gyration_bound`) as computed from every E within ``err`` of
    ``energy``: the interval's least, less 1e-12 of the radii for the rounding of either."""
    lo = np.sqrt(np.maximum(energy - err, 0.0) / k)
    hi = np.sqrt(np.maximum(energy + err, 0.0) / k)
    rg_q = math.sqrt(query_energy / k)
    gap = np.maximum(np.maximum(lo - rg_q, rg_q - hi), 0.0)
    return gap - 1e-12 * (hi + rg_q)


def block_boxes(points: np.ndarray, speeds: np.ndarray,
                chunk: int = 1 << 17) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Per block of 2 consecutive intervals of the bank (the last one alone where N is odd),
    the box that holds the interpolant over them: the least p_i − Λ_i and the greatest
    p_i + Λ_i per axis (``speeds`` Λ_i, :func:`speed_bounds`; module notes), in float32
    rounded outwards (a box that holds the float64 one; half the memory), ``chunk`` samples
    at a time. Shapes (⌈N/2⌉, d); wider blocks by :func:`halved_boxes`."""
    n, d = points.shape
    nb = -(-n // 2)
    lo, hi = np.empty((nb, d), np.float32), np.empty((nb, d), np.float32)
    for i0 in range(0, n, chunk):  # chunk is even: blocks do not straddle two
        i1 = min(n, i0 + chunk)
        p, v = points[i0:i1], speeds[i0:i1, None]
        low, high = p - v, p + v
        even = (i1 - i0) // 2 * 2
        b0, b1 = i0 // 2, i0 // 2 + even // 2
        lo[b0:b1] = below32(np.minimum(low[0:even:2], low[1:even:2]))
        hi[b0:b1] = above32(np.maximum(high[0:even:2], high[1:even:2]))
        if even < i1 - i0:  # the last sample alone
            lo[b1], hi[b1] = below32(low[-1:])[0], above32(high[-1:])[0]
    return lo, hi


def halved_boxes(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boxes of blocks twice as wide: each pair of blocks' union (a last one alone;
    float32 minima and maxima are exact)."""
    if lo.shape[0] % 2:
        lo, hi = np.concatenate([lo, lo[-1:]]), np.concatenate([hi, hi[-1:]])
    return np.minimum(lo[0::2], lo[1::2]), np.maximum(hi[0::2], hi[1::2])


def below32(x: np.ndarray) -> np.ndarray:
    """float32 values at or below the float64 ``x``."""
    y = x.astype(np.float32)
    above = y.astype(np.float64) > x
    y[above] = np.nextafter(y[above], np.float32(-np.inf))
    return y


def above32(x: np.ndarray) -> np.ndarray:
    """float32 values at or above the float64 ``x``."""
    y = x.astype(np.float32)
    below = y.astype(np.float64) < x
    y[below] = np.nextafter(y[below], np.float32(np.inf))
    return y


def chord_boxes(lo: np.ndarray, hi: np.ndarray, first: int, last: int, start: int = 0,
                stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Per block X in [``start``, ``stop``), the box of the chords from a point of block X to
    one of the blocks X + ``first`` .. X + ``last``: their union's box less X's, in float64
    (+inf / -inf where none of those blocks is in the bank: no chord)."""
    nb, d = lo.shape
    stop = nb if stop is None else stop
    end_lo, end_hi = np.full((stop - start, d), np.inf), np.full((stop - start, d), -np.inf)
    for off in range(first, last + 1):  # slices: X reads X + off
        a, b = max(start, -off), min(stop, nb - off)
        if b > a:
            np.minimum(end_lo[a - start : b - start], lo[a + off : b + off],
                       out=end_lo[a - start : b - start])  # fmt: skip
            np.maximum(end_hi[a - start : b - start], hi[a + off : b + off],
                       out=end_hi[a - start : b - start])  # fmt: skip
    return end_lo - hi[start:stop], end_hi - lo[start:stop]


def chord_radii(c_lo: np.ndarray, c_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least and greatest length of a chord in each box of :func:`chord_boxes`."""
    near = np.maximum(np.maximum(c_lo, -c_hi), 0.0)
    far = np.maximum(np.abs(c_lo), np.abs(c_hi))
    return np.sqrt(np.einsum("ij,ij->i", near, near)), np.sqrt(np.einsum("ij,ij->i", far, far))


def box_gaps(c_lo: np.ndarray, c_hi: np.ndarray, q_chord: np.ndarray,
             rotation: str) -> np.ndarray:  # fmt: skip
    """A lower bound on g(c) (:func:`endpoint_gap`) over the chords c of each box: its
    distance from c_q (``"none"``), or that of |c_q| from the box's range of lengths
    (``"full"``; ``"z"`` too, whose g is at least the full family's); inf for no chord."""
    if rotation == "none":
        off = np.maximum(np.maximum(c_lo - q_chord, q_chord - c_hi), 0.0)
        gap = np.sqrt(np.einsum("ij,ij->i", off, off))
    else:
        near, far = chord_radii(c_lo, c_hi)
        length = float(np.linalg.norm(q_chord))
        gap = np.maximum(np.maximum(near - length, length - far), 0.0)
    return np.where(np.isnan(gap), np.inf, gap)


def beyond(bound: np.ndarray, limit: np.ndarray | float, rg_q: float, slack: float) -> np.ndarray:
    """Where a lower bound on ρ proves the computed RMSD above ``limit``: bound² > limit²
    plus the round-off of ρ² (relative to Σ|q̃|²/K = rg_q² and to limit²), and ``bound``
    past an absolute ``slack`` for the round-off of the chords (coordinates' magnitude)."""
    return bound - slack > spare(limit, rg_q)


def spare(limit: np.ndarray | float, rg_q: float) -> np.ndarray:
    """The greatest ρ :func:`beyond` takes as not above ``limit`` (before its ``slack``)."""
    limit = np.asarray(limit, dtype=float)
    return np.sqrt(limit * limit * (1.0 + _REL) + _REL * rg_q * rg_q)


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
