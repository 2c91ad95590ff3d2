"""Scores of arc windows given by their points, and the windows at a primitive's end.

An index window (:mod:`._index_search`) is ``k`` points of a level, ``dil`` apart. The gates
(:class:`._gates.Gates`) let a window run past its primitive's last point as far as
:func:`._gates.overrun` allows: a copy of the query may reach the primitive's very end while
the query's arc is longer (chords under-estimate arc, a noisy path smoothed keeps some of its
noise's arc, hand-drawn copies of one shape differ in arc by 10-20 %). Such a window's last
points belong to the next primitive. Scored from them it matched nothing: a whole noisy
line, its smoothed arc 1–2 % longer than the stored line's, was found nowhere in the index
while the exhaustive grid matched it (``benchmarks/bench_match_noisy.py``, joined paths at
1 % noise: two of ten cut elsewhere). Those windows, a few per primitive, are scored here
ending at the primitive's last point, their points evenly spaced
(:meth:`._arc_index.ArcQuery.at_starts`), and offered to the pool before the best-first
search, which leaves them out (:attr:`._gates.Gates.fits` holds the windows inside their
primitive only). The pool does not depend on the order windows are offered in.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from primlib.match._kabsch import rmsd_from_moments

if TYPE_CHECKING:
    from primlib.match._arc_index import ArcQuery
    from primlib.match._gates import Gates
    from primlib.match._index_search import IndexSearch
    from primlib.match._pool import CandidatePool

__all__ = ["combine", "score_points", "offer_overrun"]


def combine(aq: ArcQuery, shape: np.ndarray, xw: np.ndarray) -> np.ndarray:
    """Shape RMSD combined with ℓ·(RMS normalised-time error at the arc samples).

    A normalised-time error δτ at an arc sample moves the uniform-time sample by about
    ℓ·δτ along the curve: adding it ranks pieces of the same shape traversed with another
    speed profile below the right one (never below the shape RMSD, so the lower bounds
    still hold). ``xw`` (m, k): each window's sample index at its arc samples.
    """
    tau_q = aq.tau
    dur = xw[:, -1] - xw[:, 0]
    still = dur <= 1e-9  # a stationary stretch: no speed profile to compare
    tau_w = (xw - xw[:, :1]) / np.where(still, 1.0, dur)[:, None]
    tau_w[still] = tau_q
    return np.hypot(shape, aq.ell * np.sqrt(np.mean((tau_w - tau_q) ** 2, axis=1)))


def score_points(
    aq: ArcQuery, win: np.ndarray, xw: np.ndarray, rotation: str
) -> tuple[np.ndarray, np.ndarray]:
    """(combined score, shape RMSD) of windows given by their points ``win`` (m, d, k),
    centred in place, and sample indices ``xw`` (m, k), float64: one matrix product for
    all cross-covariances (no centring needed for them: Σ q̃ = 0)."""
    k, d = aq.k, aq.qc.shape[1]
    s_ = (win.reshape(-1, k) @ aq.qc).reshape(win.shape[0], d, d)
    win -= win.mean(axis=2, keepdims=True)  # centred in place, once s_ is formed
    sp = np.einsum("mak,mak->ma", win, win)
    if not aq.per_axis:
        sp = sp.sum(axis=1)
    sq_ = np.broadcast_to(aq.sq, (win.shape[0], 3)) if aq.per_axis else aq.sq
    shape = rmsd_from_moments(s_, sp, sq_, k, rotation)
    return combine(aq, shape, xw), shape


def offer_overrun(search: IndexSearch, aq: ArcQuery, gates: Gates, pool: CandidatePool) -> None:
    """Score the windows of ``gates.over`` ending at their primitive's last point and offer
    those below their gate and in the time-scale range to ``pool`` (module notes)."""
    ws, lv = gates.over, aq.level
    search.stats.windows += ws.size
    in_range, x_end = search.in_range(aq, ws)  # first: it keeps ~15 % (novel paths)
    ws, x_end = ws[in_range], x_end[in_range]
    if ws.size == 0:
        return
    pts, xw, ok = aq.at_starts(ws.astype(float), gates.need)
    r, shape = score_points(aq, pts.transpose(0, 2, 1), xw, search.opts.rotation)
    search.stats.scored += ws.size
    ok &= shape < gates.at(ws)
    pool.offer_arrays(r[ok], lv.prim[ws[ok]], lv.x[ws[ok]], x_end[ok], ws[ok])
