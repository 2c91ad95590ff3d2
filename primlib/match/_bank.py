"""A machine's primitives made ready for matching: :class:`BankIndex`."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from primlib._errors import NoMatchError
from primlib.defaults import MAX_ABS_VALUE
from primlib.match._arc_index import ArcIndex, ArcSamples
from primlib.match._reject import Envelope
from primlib.match._rough import BANK_MAX, Roughness
from primlib.match._rough_diff import DiffRoughness

if TYPE_CHECKING:
    from primlib.store import Bank

__all__ = ["BankIndex", "as_index"]

# Finer arc-length indexes kept hold at most this many points in all (memory ~ 80 B a point
# with the prefix sums their queries keep beside them).
_FINE_CAP = 4e6
# Points of the base arc-length index per stored sample.
_BASE_PPS = 0.25


class BankIndex:
    """The primitives of one bank that can be matched, and the search's index over them.

    Build it once per bank and pass it to :func:`primlib.match.match_path` (or
    :func:`primlib.match.segment_path`) for every path matched against that bank: the
    arc-length index (built on first use, ~0.2 s for 1,000 primitives of 2,000 samples), the
    finer indexes for short pieces and the time-uniform grid's tables (:attr:`grid_tables`:
    ~0.7 s and ~300 MB there, made when a piece at rest is first searched) are kept on this
    object, nowhere else. Not thread-safe while it builds them; give each thread its own, or
    build them first.

    A primitive that cannot be compared with others — a non-finite value, a coordinate
    beyond :data:`primlib.defaults.MAX_ABS_VALUE` (so its second moments could overflow) or
    fewer than 2 samples — is left out, with the reason in :attr:`skipped`, so one bad stored
    primitive cannot break matching against the others.

    Parameters
    ----------
    bank : primlib.store.Bank
        A machine's primitives as flat arrays (``points`` (N, d), ``offsets`` (k + 1,),
        ``dt``, ``ids``, ``names``; ``machine`` optional).

    Attributes
    ----------
    bank : primlib.store.Bank
        The bank it was built from.
    points, offsets, ids, names, dt
        The usable primitives only, in the bank's order (``offsets`` re-based).
    skipped : dict of int to str
        Id of every left-out primitive and why.
    grid_tables : dict
        The time-uniform grid's tables of these primitives (``_grid.GridSearch``), filled by
        the first search that needs each.

    Examples
    --------
    >>> import numpy as np
    >>> from primlib.store import Bank
    >>> t = np.linspace(0.0, 1.0, 50)[:, None]
    >>> good = np.hstack([t, t**2, 0 * t])
    >>> bank = Bank.from_samples([good, np.full((50, 3), 1e300)], dt=0.01)
    >>> index = BankIndex(bank)
    >>> index.k, index.skipped
    (1, {1: 'coordinates beyond 1e+09 (largest magnitude 1e+300)'})
    """

    def __init__(self, bank: Bank | Any) -> None:
        self.bank = bank
        self.dt = float(bank.dt)
        self.machine: str = getattr(bank, "machine", "") or ""
        points = np.asarray(bank.points, dtype=float)
        offsets = np.asarray(bank.offsets, dtype=np.int64)
        ids = np.asarray(bank.ids, dtype=np.int64)
        names = tuple(getattr(bank, "names", None) or (None,) * (len(offsets) - 1))
        self._dim = int(points.shape[1]) if points.ndim == 2 else int(getattr(bank, "dim", 0))
        reasons = _screen(points, offsets)
        self.skipped: dict[int, str] = {int(ids[i]): reasons[i] for i in sorted(reasons)}
        if reasons:
            keep = np.array([i not in reasons for i in range(len(ids))])
            counts = np.diff(offsets)[keep]
            rows = np.repeat(keep, np.diff(offsets))
            points = points[rows]
            offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
            ids = ids[keep]
            names = tuple(n for n, k in zip(names, keep, strict=True) if k)
        self.points = points
        self.offsets = offsets
        self.ids = ids
        self.names = names
        self._arc: ArcIndex | None = None
        self._fine: dict[int, ArcIndex] = {}
        self._arc_samples: ArcSamples | None = None
        self._samples_seconds = 0.0
        self._vmax: np.ndarray | None = None
        self._steps: np.ndarray | None = None
        self._envelope: Envelope | None = None
        self._roughness: Roughness | DiffRoughness | None = None
        # the time-uniform grid's tables of these primitives (``_grid.GridSearch``: their
        # interpolants' coefficients, speed bounds and blocks of starts), made on first use
        # and shared by every search on this index
        self.grid_tables: dict[str, Any] = {}
        self.index_seconds = 0.0

    @property
    def k(self) -> int:
        """Number of usable primitives."""
        return len(self.offsets) - 1

    @property
    def dim(self) -> int:
        return self._dim

    @property
    def counts(self) -> np.ndarray:
        return np.diff(self.offsets)

    @property
    def durations(self) -> np.ndarray:
        return (self.counts - 1) * self.dt

    def points_of(self, i: int) -> np.ndarray:
        """Samples of usable primitive i (a row of this index, not an id), a view."""
        return self.points[self.offsets[i] : self.offsets[i + 1]]

    def require(self) -> None:
        """Raise :class:`NoMatchError` when nothing can be matched against this bank."""
        if self.k > 0:
            return
        who = f"machine {self.machine!r}" if self.machine else "bank"
        if not self.skipped:
            raise NoMatchError(f"{who}: no primitive stored, nothing to match against")
        pid, why = next(iter(self.skipped.items()))
        raise NoMatchError(
            f"{who}: no usable primitive, nothing to match against "
            f"({len(self.skipped)} skipped; #{pid}: {why})"
        )

    def arc_index(self) -> ArcIndex:
        """The arc-length index of the usable primitives (built on first call, then kept)."""
        if self._arc is None:
            self.arc_samples()
            t0 = time.perf_counter()
            self._arc = ArcIndex.build(self, points_per_sample=_BASE_PPS)
            # with the samples it is built from, wherever they were computed first
            self.index_seconds = self._samples_seconds + time.perf_counter() - t0
        return self._arc

    def arc_samples(self) -> ArcSamples:
        """What every arc-length index of this bank is built from
        (:class:`~primlib.match._arc_index.ArcSamples`), computed once."""
        if self._arc_samples is None:
            t0 = time.perf_counter()
            self._arc_samples = ArcSamples.of(self.points, self.offsets, _BASE_PPS)
            self._samples_seconds = time.perf_counter() - t0
        return self._arc_samples

    def fine_arc_index(self, j: int) -> ArcIndex:
        """An index 2ʲ times finer than :meth:`arc_index` (for pieces short in arc length),
        its level 0 only, built once and kept while the finer indexes kept hold at most ~4
        million points in all (the least recently used are dropped first; j is capped so one
        alone holds at most that)."""
        base = self.arc_index()
        n0 = base.levels[0].pts.shape[0]
        j = min(j, _finest(n0))
        if j <= 0:
            return base
        hit = self._fine.pop(j, None)
        if hit is None:
            # the least recently used ones go first: all of them together stay within the cap
            kept = sum(f.n_points for f in self._fine.values())
            while self._fine and n0 * 2**j + kept > _FINE_CAP:
                kept -= self._fine.pop(next(iter(self._fine))).n_points
            pps = n0 / max(self.points.shape[0], 1)
            # a query on a finer index has 16-31 of its steps: only its level 0 is searched
            hit = ArcIndex.build(self, points_per_sample=pps * 2**j, max_levels=1)
        self._fine[j] = hit
        return hit

    def finest_step(self) -> float:
        """A lower bound on the arc step of every index :meth:`fine_arc_index` can return.

        A piece shorter in arc length than a few such steps cannot be indexed at any
        resolution (the search then uses the time-uniform grid): asking this first spares
        building a fine index (up to ~4 million points) for a (nearly) stationary piece.
        """
        base = self.arc_index()
        n0 = base.levels[0].pts.shape[0]
        # ArcIndex.build: step0 = total arc / max(points per sample · N, 1); the finest
        # index has n0·2ʲ points in all, the base max(_BASE_PPS · N, 1)
        total = base.step0 * max(_BASE_PPS * self.points.shape[0], 1.0)
        return total / max(n0 * 2.0 ** max(_finest(n0), 0), 1.0) * (1.0 - 1e-9)

    def max_step(self) -> np.ndarray:
        """Largest distance between consecutive samples, per primitive, shape (k,)."""
        if self._vmax is None and self.k > 0:
            # the arc-length index measures the same steps (computed once for both)
            self._vmax = self.arc_samples().max_step
        if self._vmax is None:
            self._vmax = np.maximum.reduceat(self.steps(), self.offsets[:-1])
        return self._vmax

    def steps(self) -> np.ndarray:
        """Distance from each stored sample to the next one of its primitive, shape (N,)
        (0 at a primitive's last sample), computed once."""
        if self._steps is None:
            pts = self.points
            step = np.zeros(pts.shape[0])
            for c0 in range(0, step.size - 1, 1 << 16):  # chunks: no (N, d) temporary
                c1 = min(c0 + (1 << 16), step.size - 1)
                dif = pts[c0 + 1 : c1 + 1] - pts[c0:c1]
                step[c0:c1] = np.sqrt(np.einsum("ij,ij->i", dif, dif))
            step[self.offsets[1:] - 1] = 0.0
            self._steps = step
        return self._steps

    def envelope(self) -> Envelope:
        """Per-primitive bounding balls and boxes (:mod:`._reject`), built once."""
        if self._envelope is None:
            self._envelope = Envelope.of(self.points, self.offsets, self.max_step())
        return self._envelope

    def roughness(self) -> Roughness | DiffRoughness:
        """Per-primitive roughness bounds, built once: :mod:`._rough`'s table, or on a bank
        of more than ``BANK_MAX`` samples (where each of its bins reads seconds of windows)
        :mod:`._rough_diff`'s, from the samples' differences."""
        if self._roughness is None:
            big = self.points.shape[0] > BANK_MAX
            self._roughness = (DiffRoughness if big else Roughness)(self.points, self.offsets)
        return self._roughness

    def __repr__(self) -> str:
        return f"BankIndex({self.machine!r}, {self.k} primitives, {len(self.skipped)} skipped)"


def _finest(n0: int) -> int:
    """Largest refinement j of a base index of n0 points within ``_FINE_CAP`` points."""
    return int(math.log2(max(_FINE_CAP / max(n0, 1), 1.0)))


def _screen(points: np.ndarray, offsets: np.ndarray) -> dict[int, str]:
    """Row → reason for every primitive that cannot be matched (see :class:`BankIndex`)."""
    counts = np.diff(offsets)
    out = {int(i): f"{counts[i]} sample(s), 2 needed" for i in np.flatnonzero(counts < 2)}
    if points.size == 0 or len(counts) == 0:
        return out
    # the usual bank: every value finite and in range, told by the smallest and the largest
    # value (a nan or an inf makes one of them non-finite), two reductions without the
    # temporaries of np.isfinite and np.abs (3x the time on 6 million values; the
    # per-primitive reductions below cost ten times more)
    lo, hi = float(points.min()), float(points.max())
    if math.isfinite(lo) and math.isfinite(hi) and max(-lo, hi) <= MAX_ABS_VALUE:
        return out
    starts = offsets[:-1][counts > 0]
    rows = np.flatnonzero(counts > 0)
    with np.errstate(invalid="ignore"):
        mag = np.abs(points).max(axis=1)
        finite = np.isfinite(points).all(axis=1)
    bad_finite = np.minimum.reduceat(finite, starts) == 0
    big = np.maximum.reduceat(np.where(finite, mag, 0.0), starts)
    for j in np.flatnonzero(bad_finite | (big > MAX_ABS_VALUE)):
        if bad_finite[j]:
            out[int(rows[j])] = "non-finite coordinates (nan or inf)"
        else:
            out[int(rows[j])] = (
                f"coordinates beyond {MAX_ABS_VALUE:.0e} (largest magnitude {big[j]:.3g})"
            )
    return out


def as_index(bank: Bank | BankIndex | Any) -> BankIndex:
    """A :class:`BankIndex` as is, or a new one built from a bank."""
    return bank if isinstance(bank, BankIndex) else BankIndex(bank)
