"""The time-uniform grid search: seeds for pieces too short in arc length to index, and for
every piece when the time scale is fixed on a small bank (one scale: the grid is then
cheaper than the index; on a large one it is not: ``_segment.seeder_for``).

Query sampled at K = ``grid_points`` (16) uniform-time points. Every primitive; every
duration D = k·(query duration) for k on a geometric grid over ``time_scale`` with ratio at
most ``scale_ratio`` (1.1, so 30 scales over 0.25–4); for each D the primitive is resampled
at the stride h = D/(K − 1) and every start m·h (m = 0, 1, ...) is a candidate whose K points
are K consecutive resampled points. The window second moments come from cumulative sums,
the cross-covariances from one product over a strided window view, and the RMSD of every
window that the radius-of-gyration bound (:func:`primlib.match._bounds.gyration_bound`)
does not already put at or above its gate from ``rmsd_from_moments`` (no rotation formed).

The index search falls back on it for (nearly) stationary or very short pieces; the tests
and benchmarks also run it on whole paths as the exhaustive reference.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import maximum_filter1d

from primlib.match._bank import BankIndex
from primlib.match._bounds import gyration_bound
from primlib.match._kabsch import rmsd_from_moments
from primlib.match._options import Candidate, PathPiece, SearchOptions, SearchStats
from primlib.match._pool import suppress

__all__ = ["GridSearch", "scale_grid"]


def scale_grid(lo: float, hi: float, ratio: float) -> np.ndarray:
    """Geometric grid over [lo, hi] with neighbouring ratio at most ``ratio``."""
    n = 1 + max(1, math.ceil(math.log(hi / lo) / math.log(ratio) - 1e-9)) if hi > lo else 1
    return np.geomspace(lo, hi, n) if n > 1 else np.array([lo])


def _coefficient_table(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Every interval's first sample p1 and Catmull-Rom coefficients (c1, c2, c3) with the
    neighbours :func:`._interp.cubic_at` takes (clamped at the curve's ends), coefficient by
    coefficient, one row per stored sample (row j: the interval j -> j + 1 of its curve;
    a curve's last row is no interval and is never read): shape (4, N, d).

    The neighbours are the rows either side (slices, not gathers), then each curve's end
    rows clamped; the coefficients are :func:`._interp.coefficients`' operations in their
    order, written in place: the same numbers to the last bit as gathering the neighbours
    of every interval (a third of the time: 1.4 s on 1,000 primitives of 2,000 samples,
    once per segmentation), and each coefficient contiguous for :meth:`GridSearch._resample`.
    """
    n, d = points.shape
    tab = np.empty((4, n, d))
    if n < 2:
        tab[:] = points
        return tab
    p0, p2, p3 = np.empty_like(points), np.empty_like(points), np.empty_like(points)
    p0[1:], p0[0] = points[:-1], points[0]
    p2[:-1], p2[-1] = points[1:], points[-1]
    p3[:-2], p3[-2:] = points[2:], points[-1]
    heads, ends = offsets[:-1], offsets[1:]
    long = ends - heads >= 2
    p0[heads[long]] = points[heads[long]]  # a curve's first interval: p0 = p1
    p3[ends[long] - 2] = points[ends[long] - 1]  # its last: p3 = p2
    tab[0] = points
    np.subtract(p2, p0, out=tab[1])  # c1 = p2 − p0
    c2 = tab[2]  # c2 = 2 p0 − 5 p1 + 4 p2 − p3, left to right
    np.multiply(p0, 2.0, out=c2)
    c2 -= 5.0 * points
    c2 += 4.0 * p2
    c2 -= p3
    c3 = tab[3]  # c3 = 3 (p1 − p2) + p3 − p0, left to right
    np.subtract(points, p2, out=c3)
    c3 *= 3.0
    c3 += p3
    c3 -= p0
    return tab


class _Scratch:
    """Arrays kept by name from one time scale to the next (the first scale, the shortest
    stride, needs the largest): the grid's arrays of every resampled point (3.5 M points a
    scale on 1,000 primitives) written into the same memory, not fresh each scale."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}

    def __call__(self, name: str, shape: tuple[int, ...], dtype: type = float) -> np.ndarray:
        size = math.prod(shape)
        buf = self._arrays.get(name)
        if buf is None or buf.size < size:
            buf = self._arrays[name] = np.empty(size, dtype)
        return buf[:size].reshape(shape)


def _array(scratch: _Scratch | None, name: str, shape: tuple[int, ...]) -> np.ndarray:
    return np.empty(shape) if scratch is None else scratch(name, shape)


def _cumsums(x: np.ndarray, scratch: _Scratch | None = None):
    """Cumulative sums of x and x², a zero row first, shape (n + 1, d) each: views of one
    array holding each x and x² as the real and imaginary parts of a complex number, so one
    running sum adds both (complex addition adds the parts alone: the same additions in the
    same order as two sums; 52 against 91 ms on 3.5 M points in 3-D)."""
    n, d = x.shape
    both = _array(scratch, "cs", (n + 1, d, 2))
    both[0] = 0.0
    both[1:, :, 0] = x
    np.multiply(x, x, out=both[1:, :, 1])
    pairs = both.view(np.complex128)[:, :, 0]
    np.cumsum(pairs[1:], axis=0, out=pairs[1:])
    return both[:, :, 0], both[:, :, 1]


def _column_means(x: np.ndarray, scratch: _Scratch | None = None) -> np.ndarray:
    """``x.mean(axis=0)`` of an (n, d) array with contiguous rows, the same numbers: numpy
    sums down the first axis a row at a time, each column's running sum, which 1-D
    cumulative sums give, two columns at once as the parts of complex numbers (3.5 M
    points in 3-D: 23 against 50 ms)."""
    n, d = x.shape
    if x.strides[1] != x.itemsize:
        return x.mean(axis=0)
    run = _array(scratch, "tmp", (2 * n,)).view(np.complex128)  # free while res is centred
    total = np.empty(d)
    for j in range(0, d - 1, 2):
        both = np.cumsum(x[:, j : j + 2].view(np.complex128)[:, 0], out=run)[-1]
        total[j], total[j + 1] = both.real, both.imag
    if d % 2:
        total[-1] = np.cumsum(x[:, -1], out=run.view(float)[:n])[-1]
    return total / n


def _window_moments(
    cs: np.ndarray,
    cs2: np.ndarray,
    starts: np.ndarray,
    k: int,
    per_axis: bool,
    scratch: _Scratch | None = None,
):
    """Σ|p − p̄|² of the windows [m, m + k) from cumulative sums (per axis if asked).

    Taken at every position with slices, then gathered at ``starts`` (once, after the sum
    over the axes): the same operations on the same numbers as on the gathered sums, four
    (m, d) gathers fewer (the windows are nearly every position: 37 M a query on 1,000
    primitives, a third of the grid's time). With ``scratch``, the moments are written
    over the cumulative sums of x (no longer read once sx is formed) and their sum over
    sx: no more memory than the fresh arrays took (at the largest scale, 3.5 M points on
    1,000 primitives, the query's peak is the same)."""
    n, d = cs.shape[0] - k, cs.shape[1]
    sx = np.subtract(cs[k:], cs[:-k], out=_array(scratch, "tmp", (n, d)))
    sp = np.subtract(cs2[k:], cs2[:-k], out=None if scratch is None else cs[:n])
    sx *= sx
    sx /= k
    sp -= sx  # sxx − sx·sx / k, in place
    if per_axis:
        return sp[starts]
    # the sum over the axes column by column: sum(axis=1)'s additions, in its order (a
    # reduction over 2-3 numbers a row took 1.6x as long)
    tot = np.add(sp[:, 0], sp[:, 1], out=_array(scratch, "tmp", (n,)))
    for j in range(2, d):
        tot += sp[:, j]
    return tot[starts]


@dataclass
class GridSearch:
    """Exhaustive search on the documented (start, time scale) grid, vectorised."""

    bank: BankIndex
    opts: SearchOptions
    stats: SearchStats = field(default_factory=SearchStats)
    name: ClassVar[str] = "grid"
    _table: np.ndarray | None = field(default=None, init=False, repr=False)

    def _windows(
        self, path: PathPiece, a: float, b: float, scratch: _Scratch | None = None
    ) -> Iterator[tuple]:
        """Yield, per time scale, the resampled bank and its valid windows (the resampled
        bank in ``scratch``'s memory when given: valid until the next scale)."""
        bank, k = self.bank, self.opts.grid_points
        dq = (b - a) * path.duration / bank.dt
        counts = bank.counts
        for scale in scale_grid(*self.opts.time_scale, self.opts.scale_ratio):
            dur = scale * dq
            h = dur / (k - 1)
            ok = np.flatnonzero(counts - 1 >= dur - 1e-9)
            if ok.size == 0 or h <= 0:
                continue
            n_start = np.floor((counts[ok] - 1 - dur) / h + 1e-9).astype(np.int64) + 1
            n_res = n_start + k - 1
            base = np.concatenate([[0], np.cumsum(n_res)])
            prim = np.repeat(ok, n_res)
            local = np.arange(base[-1]) - np.repeat(base[:-1], n_res)
            res = self._resample(prim, local * h, scratch)
            first = np.concatenate([[0], np.cumsum(n_start)])
            s_local = np.arange(first[-1]) - np.repeat(first[:-1], n_start)
            starts = np.repeat(base[:-1], n_start) + s_local
            s_prim = np.repeat(ok, n_start)
            yield res, starts, s_prim, s_local * h, dur

    def _resample(
        self, prim: np.ndarray, x: np.ndarray, scratch: _Scratch | None = None
    ) -> np.ndarray:
        """:func:`._interp.cubic_at` of primitives ``prim`` at sample indices ``x``, from a
        table of every interval's Catmull-Rom coefficients (:func:`_coefficient_table`,
        built on the first call, kept): no neighbour gathers and no coefficient arithmetic
        per point (each scale resamples the whole bank), the same numbers to the last bit."""
        if self._table is None:
            self._table = _coefficient_table(self.bank.points, self.bank.offsets)
        p1, c1, c2, c3 = self._table
        count = self.bank.counts[prim]
        x = np.clip(x, 0.0, count - 1)
        i = np.minimum(np.floor(x).astype(np.int64), count - 2)
        f = (x - i)[:, None]
        rows = self.bank.offsets[prim] + i
        # p1 + 0.5 f (c1 + f (c2 + f c3)), its operations in their order, in place, each
        # coefficient gathered contiguous (one (m, 4, d) gather and arithmetic on its
        # strided columns took 2.7x as long)
        shape = (rows.size, p1.shape[1])
        val = np.take(c3, rows, axis=0, out=_array(scratch, "res", shape), mode="clip")
        tmp = _array(scratch, "tmp", shape)  # mode "clip": no buffer (rows are in range)
        val *= f
        val += np.take(c2, rows, axis=0, out=tmp, mode="clip")
        val *= f
        val += np.take(c1, rows, axis=0, out=tmp, mode="clip")
        val *= 0.5 * f
        val += np.take(p1, rows, axis=0, out=tmp, mode="clip")
        return val

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]:
        """Best distinct grid candidates that a continuous move within their cell could
        bring below eps (Lipschitz gate, see :meth:`_slack`), best first."""
        k, rotation = self.opts.grid_points, self.opts.rotation
        q = path.at(np.linspace(a, b, k))
        qc = q - q.mean(axis=0)
        sq = (qc * qc).sum(axis=0) if rotation == "z" else float((qc * qc).sum())
        pool: list[Candidate] = []
        self.stats.queries += 1
        scratch = _Scratch()
        for res, starts, s_prim, x0, dur in self._windows(path, a, b, scratch):
            gate = eps + self._slack(s_prim, x0, dur, k)
            rmsd = self._score(res, starts, q, qc, sq, k, rotation, gate, scratch)
            self.stats.windows += starts.size
            ok = np.flatnonzero(rmsd < gate)
            top = ok[np.argsort(rmsd[ok])[: 8 * self.opts.seeds]]
            pool += [
                Candidate(int(s_prim[t]), float(x0[t]), float(x0[t] + dur), float(rmsd[t]))
                for t in top
            ]
        return suppress(pool, self.opts.seeds)

    def _slack(self, prim: np.ndarray, x0: np.ndarray, dur: float, k: int) -> np.ndarray:
        """Bound on how much the RMSD can drop inside a grid cell.

        Moving the start by up to h/2 and the duration to a neighbouring scale (factor
        √ratio) moves each of the K points by at most c = h/2 + D(√ratio − 1) samples along
        the stored curve, i.e. by at most c times the largest step between the samples it
        crosses (×1.25 for the cubic interpolation's overshoot; its stencil reaches one
        sample either side); the RMSD against a fixed query is 1-Lipschitz in the RMS point
        displacement. The largest step is taken over the window's own stretch, [x0 − c,
        x0 + D + c] and the stencil (:meth:`_local_steps`), not the whole primitive: a slow
        piece of a fast primitive got the fast parts' slack, which let nearly every window
        past the radius-of-gyration bound (a 34-sample piece too short in arc length to
        index, on 1,000 primitives: 32.8 M of 37 M windows scored, 42 s). A fixed time scale
        (one duration) has no neighbouring scale: only the start moves.
        """
        lo, hi = self.opts.time_scale
        spread = math.sqrt(self.opts.scale_ratio) - 1.0 if hi > lo else 0.0
        cell = dur / (k - 1) / 2.0 + dur * spread
        at = self.bank.offsets[prim] + np.floor(x0).astype(np.int64)
        return 1.25 * self._local_steps(dur, cell)[at] * cell

    def _local_steps(self, dur: float, cell: float) -> np.ndarray:
        """Per stored sample j, the largest step between consecutive samples of its
        primitive over [j − ⌈c⌉ − 1, j + ⌈D⌉ + ⌈c⌉ + 2] (c = ``cell``): every sample a grid
        point of a window starting in [j, j + 1) reaches, moved within its cell, with the
        cubic's stencil (:meth:`BankIndex.steps`: the steps across primitives count 0)."""
        back = math.ceil(cell) + 1
        size = back + math.ceil(dur) + math.ceil(cell) + 3
        # the window [j − back, j − back + size − 1]: origin back − size // 2
        steps = self.bank.steps()
        return maximum_filter1d(steps, size=size, origin=back - size // 2, mode="constant")

    def _score(self, res, starts, q, qc, sq, k, rotation, gate, scratch=None) -> np.ndarray:
        """RMSD of every window that can pass ``gate``; +inf for the others, which the
        radius-of-gyration bound |g(P) − g(Q)| ≤ rmsd proves to be at or above it. ``res``
        is centred in place."""
        # centre per window via cumulative sums; the cross term needs no centring (Σ q̃ = 0)
        res -= _column_means(res, scratch)
        res_c = res
        cs, cs2 = _cumsums(res_c, scratch)
        per_axis = rotation == "z"
        sp = _window_moments(cs, cs2, starts, k, per_axis, scratch)
        tot = sp.sum(axis=1) if per_axis else sp
        live = np.flatnonzero(gyration_bound(tot, float(np.sum(sq)), k) < gate)
        out = np.full(starts.size, np.inf)
        self.stats.scored += live.size
        if live.size:
            win = sliding_window_view(res_c, k, axis=0)[starts[live]]  # (m, d, k), contiguous
            s = win @ qc  # one (m·d, k) by (k, d) product: no copy, unlike einsum's reshape
            sp_l = sp[live]
            out[live] = rmsd_from_moments(s, sp_l, np.broadcast_to(sq, sp_l.shape), k, rotation)
        return out
