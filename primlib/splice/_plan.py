"""Stage 1 of the splice: check the segments, plan the junctions (primitive-matching paper §3.3.3).

The paper's junction cases (figure 6) are told apart by where the two transformed pieces
put the junction point, measured along the path's tangent and converted to time:
``delta = (end of piece j - start of piece j+1) . v / |v|^2``.

- overlap (case ①, ΔT < 0 in eq. (22)): delta > dt/2, piece j runs past where piece j+1
  starts;
- gap (case ②, ΔT > 0): delta < -dt/2, piece j stops short of piece j+1;
- continuous (case ③, ΔT = 0): |delta| <= dt/2.

The band is centred on the junction, ``band`` seconds wide, widened to cover the mismatch
(2|delta| + 2 dt) in the first two cases, and confined to where both pieces are defined
(the paper's points c_j and b_{j+1} lie on both pieces): a piece extends past its window only
as far as its primitive goes on, so two rest-to-rest primitives meet with no band at all —
blending a moving piece with one that has not started would only add error.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from primlib._errors import InputError
from primlib.defaults import BAND_SAMPLES
from primlib.splice._continuous import resample_linear

__all__ = ["StoredSignal", "Band", "JunctionPlan", "plan_junctions", "GRID_TOL"]

# a piece whose start is this close to the grid (in samples) and whose time scale is within a
# tenth of it of 1 uses the stored samples as they are
GRID_TOL = 1e-6
# unmatched segments at most this many samples long are absorbed by a matched neighbour
_ABSORB_SAMPLES = 5


@dataclass(frozen=True)
class StoredSignal:
    """What the splice needs of one stored primitive.

    Attributes
    ----------
    signal : array, shape (n_l, d)
        Converged input on the machine's dt grid.
    points : array, shape (n_l, d)
        The primitive's path sampled on the same grid (absolute coordinates).
    duration : float
        Seconds.
    name : str or None
    versions : tuple of (signal, duration)
        The same primitive (same shape and pose) stored at other durations, for eq. (20).
    """

    signal: np.ndarray
    points: np.ndarray
    duration: float
    name: str | None = None
    versions: tuple = ()


@dataclass(frozen=True)
class Band:
    """A transition band between two consecutive pieces.

    Attributes
    ----------
    junction : float
        Time of the junction on the new path, seconds.
    start, end : float
        The band, seconds: the input goes linearly from the earlier piece's to the later's.
    kind : str
        ``"overlap"``, ``"gap"`` or ``"continuous"`` (paper's cases ①, ②, ③).
    delta : float
        Along-path mismatch of the two pieces at the junction, seconds (> 0 overlap).
    distance : float
        Distance between the two pieces' junction points, user units.
    """

    junction: float
    start: float
    end: float
    kind: str
    delta: float
    distance: float

    def to_dict(self) -> dict:
        return {k: (v if isinstance(v, str) else float(v)) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class JunctionPlan:
    """Where each piece goes on the new path and how its neighbours meet it.

    Attributes
    ----------
    points : array, shape (n, d)
        The new path on the machine's grid (absolute coordinates).
    segments : tuple of Segment
        The segments after joining one primitive's consecutive windows and absorbing
        unmatched slivers.
    bounds : array, shape (k, 2)
        Each segment's (start, end), normalised time.
    duration : float
        Seconds.
    dt : float
    band : float
        Nominal transition band width, seconds.
    bands : tuple of Band
        One per junction.
    reach : array, shape (k, 2)
        How far, in seconds, each segment's input must extend before its start and after
        its end to cover the bands.
    extent : float
        Largest coordinate range of the path (1 for a path that does not move).
    notes : tuple of str
    """

    points: np.ndarray
    segments: tuple
    bounds: np.ndarray
    duration: float
    dt: float
    band: float
    bands: tuple[Band, ...]
    reach: np.ndarray
    extent: float
    notes: tuple[str, ...] = ()

    @property
    def n(self) -> int:
        return int(self.points.shape[0])

    @property
    def t(self) -> np.ndarray:
        return np.arange(self.n) * self.dt

    @property
    def y_d(self) -> np.ndarray:
        """The desired output: the path relative to its first point."""
        return self.points - self.points[0]

    @property
    def sample_segment(self) -> np.ndarray:
        """Segment index of each sample, shape (n,)."""
        edges = self.bounds[:, 1] * self.duration
        return np.searchsorted(edges[:-1], self.t + 1e-9 * self.dt, side="right")

    def extent_samples(self, j: int) -> tuple[int, int]:
        """First and last sample of segment j's input, bands included."""
        a_t, b_t = self.bounds[j] * self.duration
        lo = max(0, int(np.floor((a_t - self.reach[j, 0]) / self.dt + 1e-9)))
        hi = min(self.n - 1, int(np.ceil((b_t + self.reach[j, 1]) / self.dt - 1e-9)))
        return lo, hi


def _interp_point(points: np.ndarray, v: float) -> np.ndarray:
    """Point at normalised time v of a path sampled on a uniform grid."""
    return resample_linear(points, np.array([v * (points.shape[0] - 1)]))[0]


def _piece_ends(seg, prim: StoredSignal) -> tuple[np.ndarray, np.ndarray]:
    """Where a piece's window starts and ends on the new path (its primitive moved)."""
    r = np.asarray(seg.rotation, dtype=float)
    c = np.asarray(seg.translation, dtype=float)
    a = r @ _interp_point(prim.points, seg.primitive_start) + c
    b = r @ _interp_point(prim.points, seg.primitive_end) + c
    return a, b


def _reach(seg, stored, side: str) -> float:
    """New-path time a piece's primitive extends before its window start or after its end."""
    if seg.primitive is None:
        return np.inf  # the path's own inverse is defined everywhere
    prim = stored[seg.primitive]
    k = float(seg.time_scale)
    if not np.isfinite(k) or k <= 0:
        return 0.0
    frac = seg.primitive_start if side == "before" else 1.0 - seg.primitive_end
    return max(0.0, frac) * float(prim.duration) / k


def _check(machine, points, duration: float, segments: Sequence, band: float | None):
    """The splice's input checks; returns (points, band, segments)."""
    dt = machine.dt
    pts = np.asarray(points, dtype=float)
    n = int(round(float(duration) / dt)) + 1
    if pts.ndim != 2 or pts.shape != (n, machine.dim):
        raise InputError(
            f"points: expected shape ({n}, {machine.dim}) for a {duration} s path at dt {dt}, "
            f"got {pts.shape}"
        )
    band = BAND_SAMPLES * dt if band is None else float(band)
    if not np.isfinite(band) or band < 0:
        raise InputError(f"band: expected a width >= 0 s, got {band}")
    segs = list(segments)
    if not segs:
        raise InputError("segments: expected at least one segment, got none")
    bounds = np.array([[s.start, s.end] for s in segs], dtype=float)
    if (
        abs(bounds[0, 0]) > 1e-9
        or abs(bounds[-1, 1] - 1.0) > 1e-9
        or np.any(np.abs(bounds[1:, 0] - bounds[:-1, 1]) > 1e-9)
        or np.any(bounds[:, 1] < bounds[:, 0])
    ):
        raise InputError(
            f"segments: expected contiguous segments from 0 to 1, got {bounds.tolist()}"
        )
    return pts, band, segs


def merge_continuations(segs: Sequence, stored: Mapping[int, StoredSignal], dt: float) -> list:
    """Join consecutive segments that are one primitive's consecutive windows with the same
    pose and time scale (the matcher may split a long piece): one piece, no junction."""
    out: list = []
    for s in segs:
        prev = out[-1] if out else None
        if (
            prev is not None
            and s.primitive is not None
            and prev.primitive == s.primitive
            and s.primitive in stored
        ):
            T_l = float(stored[s.primitive].duration)
            size = 1.0 + float(np.max(np.ptp(stored[s.primitive].points, axis=0)))
            same = (
                np.allclose(prev.rotation, s.rotation, atol=GRID_TOL)
                and np.allclose(prev.translation, s.translation, atol=GRID_TOL * size)
                and abs(float(prev.time_scale) - float(s.time_scale)) <= 1e-7
                and abs(prev.primitive_end - s.primitive_start) * T_l <= GRID_TOL * dt
            )
            if same:
                out[-1] = replace(prev, end=s.end, primitive_end=s.primitive_end)
                continue
        out.append(s)
    return out


def _absorb_into(nb, s, stored, T: float, before: bool):
    """Neighbour ``nb`` extended over sliver ``s`` (its primitive goes on there)."""
    ext = (s.end - s.start) * T * float(nb.time_scale) / float(stored[nb.primitive].duration)
    if before:
        return replace(nb, end=s.end, primitive_end=nb.primitive_end + ext)
    return replace(nb, start=s.start, primitive_start=nb.primitive_start - ext)


def absorb_slivers(segs: Sequence, stored, T: float, limit: float) -> tuple[list, list]:
    """Extend matched pieces over short unmatched neighbours; returns (segments, absorbed)."""
    out = list(segs)
    absorbed = []
    i = 0
    while i < len(out):
        s = out[i]
        short = (s.end - s.start) * T <= limit + 1e-12
        if s.primitive is None and short and len(out) > 1:
            if i > 0 and out[i - 1].primitive is not None:
                out[i - 1] = _absorb_into(out[i - 1], s, stored, T, before=True)
            elif i + 1 < len(out) and out[i + 1].primitive is not None:
                out[i + 1] = _absorb_into(out[i + 1], s, stored, T, before=False)
            else:
                i += 1
                continue
            absorbed.append((s.start * T, s.end * T))
            del out[i]
            continue
        i += 1
    return out, absorbed


def _junction(pts, vel, segs, stored, bounds, j: int, T: float, dt: float, band, extent):
    """The band between segments j and j + 1 (see the module docstring)."""
    tj = bounds[j, 1] * T
    left, right = segs[j], segs[j + 1]
    if left.primitive is not None and right.primitive is not None:
        _, e = _piece_ends(left, stored[left.primitive])
        s, _ = _piece_ends(right, stored[right.primitive])
    else:
        e = s = _interp_point(pts, bounds[j, 1])
    gap = e - s
    v = _interp_point(vel, bounds[j, 1])
    speed2 = float(v @ v)
    dist = float(np.linalg.norm(gap))
    if speed2 > (1e-9 * extent / dt) ** 2:
        delta = float(gap @ v) / speed2
        kind = "overlap" if delta > dt / 2 else "gap" if delta < -dt / 2 else "continuous"
    else:  # junction at rest: no along-path time
        delta = 0.0
        kind = "continuous" if dist <= 1e-6 * extent else "gap"
    width = band if kind == "continuous" else max(band, 2 * abs(delta) + 2 * dt)
    # the band lies where both pieces are defined: piece j beyond its window only while
    # its primitive goes on, piece j+1 before its window only after its primitive began
    lo = max(bounds[j, 0] * T, tj - min(width / 2, _reach(right, stored, "before")))
    hi = min(bounds[j + 1, 1] * T, tj + min(width / 2, _reach(left, stored, "after")))
    return Band(tj, lo, hi, kind, delta, dist)


def plan_junctions(
    machine,
    points,
    duration: float,
    segments: Sequence,
    stored: Mapping[int, StoredSignal],
    *,
    band: float | None = None,
    absorb: float | None = None,
) -> JunctionPlan:
    """Check the segments, join and absorb what needs no junction, and set each band.

    Parameters
    ----------
    machine : Machine
    points : array, shape (n, d)
        The new path on the machine's grid, n = round(duration / dt) + 1.
    duration : float
        Seconds.
    segments : sequence of Segment
        In path order, contiguous from 0 to 1.
    stored : mapping primitive id -> StoredSignal
    band : float, optional
        Transition band width in seconds (default ``BAND_SAMPLES`` dt from
        :mod:`primlib.defaults`).
    absorb : float, optional
        Unmatched segments at most this long (seconds, default 5 dt) are absorbed by a
        matched neighbour.

    Returns
    -------
    JunctionPlan

    Raises
    ------
    InputError
        For a bad shape, non-contiguous segments or a negative band.
    """
    dt = machine.dt
    pts, band, segs = _check(machine, points, duration, segments, band)
    T = float(duration)
    segs = merge_continuations(segs, stored, dt)
    limit = absorb if absorb is not None else _ABSORB_SAMPLES * dt
    segs, absorbed = absorb_slivers(segs, stored, T, limit)
    bounds = np.array([[s.start, s.end] for s in segs], dtype=float)
    vel = np.gradient(pts, dt, axis=0)
    extent = float(np.max(np.ptp(pts, axis=0))) or 1.0
    bands = []
    reach = np.zeros((len(segs), 2))  # band half-widths before / after each segment
    for j in range(len(segs) - 1):
        b = _junction(pts, vel, segs, stored, bounds, j, T, dt, band, extent)
        bands.append(b)
        reach[j, 1] = b.end - b.junction
        reach[j + 1, 0] = b.junction - b.start
    notes = tuple(
        f"unmatched sliver t = {a:.4g}..{b:.4g} s absorbed by the neighbouring piece"
        for a, b in absorbed
    )
    return JunctionPlan(pts, tuple(segs), bounds, T, dt, band, tuple(bands), reach, extent, notes)
