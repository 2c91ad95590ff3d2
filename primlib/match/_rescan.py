"""The index's best seeds moved to the best window near each on the time-uniform grid's score.

The arc-length index places a seed by its shape (:mod:`._arc_index`); a match is judged on
uniform-time samples (the RMSD of the path's samples against the stored piece at one time
scale). Where the two disagree -- a hand-drawn copy whose speed along its shape differs from
the stored one's -- the uniform-time optimum can lie far from the seed, beyond what the
refinement's local steps reach: on the LASA handwriting (``benchmarks/bench_match_real.py``)
the index held the exhaustive grid's primitive among its seeds 74-80 samples (about a quarter
of the piece) before the grid's optimum, and its refinement stopped in a local minimum at
1.06-1.22 eps where the grid's reached 0.68-0.99 eps.

So each of the index's best seeds (the first 2·``seeds``, best first; the rest are near ties
kept for safety) of duration D about the centre m is scored, like a grid window
(:class:`._grid.GridSearch`: K = ``grid_points`` uniform-time points, Kabsch RMSD from the
centred moments), at the durations D·r^j (r = ``scale_ratio``, |j| ≤ ``SCALES``, inside the
time-scale range) and the starts m − D'/2 + i·D'/(K − 1) (|i| ≤ ``SHIFTS``: a little over
half the piece either way, the grid's own stride), and replaced by the best of those windows
(its own among them, so a seed only moves to a window that scores lower). The windows of one
duration share their points (a lattice of K + 2·SHIFTS points), so each point is
interpolated once; the moments come from running sums, and only windows that the
radius-of-gyration bound leaves below the seed's own score reach the eigenvalue.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match._bank import BankIndex
from primlib.match._bounds import gyration_bound
from primlib.match._grid import _Query
from primlib.match._interp import cubic_at
from primlib.match._kabsch import rmsd_from_moments
from primlib.match._options import Candidate, PathPiece, SearchOptions

__all__ = ["rescan"]

SCALES = 3  # neighbouring durations either way: r³ = 1.33 at the grid's ratio 1.1
SHIFTS = 8  # grid strides either way: a little over half the piece at K = 16


def rescan(bank: BankIndex, seeds: list[Candidate], path: PathPiece, a: float, b: float,
           opts: SearchOptions) -> list[Candidate]:  # fmt: skip
    """``seeds``, each moved to its best window nearby on the grid's score (module notes);
    the score is the window's RMSD on K points (a candidate's ``score``). Order kept."""
    if not seeds:
        return seeds
    k = opts.grid_points
    query = _Query.of(path.at(np.linspace(a, b, k)), opts.rotation)
    prim = np.fromiter((c.prim for c in seeds), np.int64, len(seeds))
    x0 = np.fromiter((c.x0 for c in seeds), float, len(seeds))
    x1 = np.fromiter((c.x1 for c in seeds), float, len(seeds))
    lo, hi = opts.time_scale
    scale = opts.scale_ratio ** np.arange(-SCALES, SCALES + 1) if hi > lo else np.ones(1)
    dur = (x1 - x0)[:, None] * scale  # (seeds, scales)
    h = dur / (k - 1)
    shift = np.arange(-SHIFTS, SHIFTS + 1)
    first = 0.5 * (x0 + x1)[:, None] - 0.5 * dur  # each scale's window without shift
    r = _scores(bank, prim, first - SHIFTS * h, h, query, opts.rotation)  # (seeds, scales, shifts)
    start = first[:, :, None] + shift * h[:, :, None]
    steps = (b - a) * path.duration / bank.dt
    last = (bank.counts[prim] - 1.0)[:, None, None]
    d = dur[:, :, None]
    ok = (start >= 0.0) & (start + d <= last)
    ok &= (d >= lo * steps * (1 - 1e-12)) & (d <= hi * steps * (1 + 1e-12))
    own = (len(scale) // 2, SHIFTS)  # the seed's own window: kept whatever its range
    ok[:, own[0], own[1]] = True
    r = np.where(ok, r, np.inf).reshape(len(seeds), -1)
    at = np.argmin(r, axis=1)
    rows = np.arange(len(seeds))
    s0 = start.reshape(len(seeds), -1)[rows, at]
    d0 = np.broadcast_to(d, start.shape).reshape(len(seeds), -1)[rows, at]
    return [Candidate(c.prim, float(s), float(s + w), float(v))
            for c, s, w, v in zip(seeds, s0, d0, r[rows, at], strict=True)]  # fmt: skip


def _scores(bank: BankIndex, prim: np.ndarray, base: np.ndarray, h: np.ndarray, query: _Query,
            rotation: str) -> np.ndarray:  # fmt: skip
    """Kabsch RMSD against the query's K points (centred, with their energy: the grid's
    :class:`._grid._Query`) of every window of K consecutive points of
    the lattice base + t·h (t = 0, ..., K − 1 + 2·SHIFTS) of each seed and scale, shape
    (seeds, scales, 2·SHIFTS + 1): the windows of one scale share their points, so each
    lattice point is interpolated once (not once per window that holds it)."""
    qc, sq = query.qc, query.sq
    k, dim = qc.shape
    span = k + 2 * SHIFTS
    x = base[..., None] + h[..., None] * np.arange(span)  # (s, j, span)
    rows = np.broadcast_to(prim[:, None, None], x.shape).ravel()
    p = cubic_at(bank.points, bank.offsets[rows], bank.counts[rows], x.ravel())
    p = p.reshape(*x.shape, dim)
    p -= p.mean(axis=2, keepdims=True)  # moments from sums below: keep their magnitudes small
    zero = np.zeros((*p.shape[:2], 1, dim))
    c1 = np.concatenate([zero, np.cumsum(p, axis=2)], axis=2)
    c2 = np.concatenate([zero, np.cumsum(p * p, axis=2)], axis=2)
    s1 = c1[:, :, k:] - c1[:, :, :-k]  # each window's Σp and Σp² per axis: (s, j, shifts, d)
    sp = (c2[:, :, k:] - c2[:, :, :-k]) - s1 * s1 / k  # Σ|p̃|² per axis
    if rotation != "z":
        sp = sp.sum(axis=-1)
    # S = P̃ᵀ Q̃ = Pᵀ Q̃ (Q̃ sums to 0): the windows' points against the centred query
    cross = (sliding_window_view(p, k, axis=2) @ qc).reshape(*s1.shape[:3], dim, dim)
    return _pruned_rmsd(cross, sp, sq, k, rotation)


def _pruned_rmsd(cross: np.ndarray, sp: np.ndarray, sq, k: int, rotation: str) -> np.ndarray:
    """Kabsch RMSD of every window (seeds, scales, shifts) from its moments, inf where the
    radius-of-gyration bound (:func:`._bounds.gyration_bound`) is at or above the seed's own
    window's RMSD: such a window cannot be the seed's best (its own is always a candidate).
    That left 5-16 % of the windows to the eigenvalue on the novel paths of
    ``bench_match_novel.py`` (1,000 and the bundled primitives, every seed scanned)."""
    seeds, scales, shifts = cross.shape[:3]
    own = (slice(None), scales // 2, SHIFTS)

    def rmsd(c, e):
        return rmsd_from_moments(c, e, np.broadcast_to(sq, e.shape), k, rotation)

    r_own = rmsd(cross[own], sp[own])
    energy = sp.sum(axis=-1) if rotation == "z" else sp
    live = gyration_bound(energy, float(np.sum(sq)), k) < r_own[:, None, None]
    live[own] = False
    r = np.full(live.shape, np.inf)
    r[own] = r_own
    r[live] = rmsd(cross[live], sp[live])
    return r
