"""Splicing transformed pieces into one first-iteration input (primitive-matching paper §3.3.3).

Each matched segment of the new path gets its primitive's stored input transformed (time
scale, rotation, holding input for the translation — whole primitive from rest, then the
window cut out); consecutive pieces are joined by a transition band in which the input is
linearly interpolated from one piece to the next (the paper's "无扰切换", bumpless switch).

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

Unlike eq. (23), which concatenates pieces of their own durations and then corrects the
total length, each piece here is time-scaled to exactly its segment (the matcher's time
scale), so the spliced input is on the machine's dt grid with exactly the new path's length
and the paper's length error sum ΔT is zero by construction; the junction cases only set
the band.

Residual correction by superposition (``correction``, default ``"error"``). The machine is
linear, so what the spliced pieces miss can be added as the model inverse of the residual.
Each piece is right for the state its primitive had at the window's start; at a junction
the machine arrives in the state the previous piece left, and an integrating axis keeps
any input error there as a lasting position offset (measured on the benchmark's true
machine: the raw splice, ``"none"``, is as bad as the nominal-model inverse). Designs,
measured in benchmarks/bench_warm_start.py:

- ``"error"`` (default): ``u0 = G^-1 (y_d - E)``. The library's knowledge is the model's
  error on its own pairs, ``e_l = y_l - G u_l`` (stored path minus the model's output of
  the stored input, at the stored samples); per piece it is time-scaled and rotated like
  the piece (:func:`piece_error`), and its increments, blended over the bands like the
  inputs, are summed along the new path into E — increments, because the error a
  primitive had accumulated before the window is not on the new path. So the model's
  error only enters through the change of e_l under the time scale, and the junctions
  need nothing special: the inverse of the whole path is continuous through them. On the
  nominal machine E = 0 and u0 is the exact model inverse of the new path.
- ``"input"``: ``u_s + G^-1 y_d - Σ λ_j G^-1 y_j`` (y_j a piece's own path from its rest,
  :func:`piece_path`): the blended input corrections; cutting a piece's correction at
  its window leaves a state mismatch that integrates (worse than ``"error"``).
- ``"output"``: ``u_s + G^-1 (y_d - y_w)``, y_w the pieces' paths blended like the
  inputs. Blending inputs is not blending outputs: ``G (λ u) != λ G u`` over a band, and
  the difference (first order in the pieces' mismatch through the band) is left as an
  offset; measured no better than ``"none"``.
- ``"junction"`` (the previous design): least squares on the input within
  ``max(band / 2, 10 dt)`` of each junction so that the model's simulated output follows
  the path; good on a refined model, harmful on the nominal one (it fits the model's
  accumulated error, not the machine's).

Where every piece is its stored signal unchanged and their stored paths are the new path
sample for sample, the stored inputs are returned as they are (a stored primitive's warm
start is its stored signal).

An unmatched segment is filled with the nominal-model inverse of the new path
(:func:`primlib.plant.invert`, computed once over the whole path so its state is right at
the window), and said so in the result; with the residual correction its input is the
inverse of the model in use (refined when refined) of the path minus E.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from primlib._errors import InputError
from primlib.splice._continuous import resample_linear
from primlib.splice._transform import (
    derivative_orders,
    holding_input,
    model_inverse,
    piece_error,
    piece_path,
    time_scale_direct,
    transform,
)

__all__ = ["Band", "StoredSignal", "SpliceResult", "splice", "METHODS", "CORRECTIONS"]

METHODS = ("auto", "model", "direct")
CORRECTIONS = ("error", "input", "output", "junction", "none")
# a piece whose start is this close to the grid (in samples) and whose time scale is within a
# tenth of it of 1 uses the stored samples as they are
_GRID_TOL = 1e-6
# weight of the first-difference penalty of the junction correction (relative)
JUNCTION_SMOOTH = 1e-3


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
class SpliceResult:
    """The spliced input and how each part of it was made.

    Attributes
    ----------
    u : array, shape (n, d)
    bands : tuple of Band
    sample_segment : array of int, shape (n,)
        Index of the segment each sample belongs to (bands blend it with a neighbour).
    sources : tuple of str
        One line per segment saying where its input came from.
    methods : tuple of str
        Per segment: ``"identity"``, ``"model"``, ``"direct"`` or ``"inverse"``.
    notes : tuple of str
    spliced : array, shape (n, d) or None
        The pieces' inputs joined over the bands, before the residual correction.
    correction : str
        Which correction was applied (see :func:`splice`).
    """

    u: np.ndarray
    bands: tuple[Band, ...]
    sample_segment: np.ndarray
    sources: tuple[str, ...]
    methods: tuple[str, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    spliced: np.ndarray | None = None
    correction: str = "none"


def _interp_point(points: np.ndarray, v: float) -> np.ndarray:
    """Point at normalised time v of a path sampled on a uniform grid."""
    return resample_linear(points, np.array([v * (points.shape[0] - 1)]))[0]


def _piece_geometry(seg, prim: StoredSignal):
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


def _correct_junctions(
    machine, u, y_d, t, bands, half: float, feedback: bool, smooth: float | None = None
):
    """Least-squares input correction near the junctions; returns (u, samples per axis).

    min ||y_d - G (u + E x)||^2 + lam (smooth ||D x||^2 + 1e-8 ||x||^2) over x, E selecting
    the samples within ``half`` of a junction, G the lifted (closed-loop) model, D the first
    difference inside each band; lam = trace(A^T A) / m, A = G E, so the weights are
    relative and scale-free. The difference penalty keeps the correction from the
    alternating (Nyquist) inputs an exact sampled-data inverse would use.
    """
    n = u.shape[0]
    mask = np.zeros(n, dtype=bool)
    for b in bands:
        mask |= np.abs(t - b.junction) <= half + 1e-9
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return u, 0
    resid = y_d - machine.simulate(u, y_d if feedback else None)
    h = machine.impulse_response(n)
    rows = np.arange(n)[:, None] - idx[None, :]  # G[r, j] = h[r - j] for r >= j
    valid = rows >= 0
    m = idx.size
    d = np.zeros((m - 1, m))
    d[np.arange(m - 1), np.arange(m - 1)] = -1.0
    d[np.arange(m - 1), np.arange(1, m)] = 1.0
    d = d[np.diff(idx) == 1]  # no difference across two bands
    smooth = JUNCTION_SMOOTH if smooth is None else smooth
    reg = smooth * (d.T @ d) + 1e-8 * np.eye(m)
    out = u.copy()
    for i in range(machine.dim):
        a = np.where(valid, h[np.clip(rows, 0, n - 1), i], 0.0)
        ata = a.T @ a
        lam = np.trace(ata) / m
        if lam <= 0:
            continue
        x = np.linalg.solve(ata + lam * reg, a.T @ resid[:, i])
        out[idx, i] += x
    return out, int(m)


def _merge_continuations(segs, stored, dt: float):
    """Join consecutive segments that are one primitive's consecutive windows with the same
    pose and time scale (the matcher may split a long piece): one piece, no junction."""
    from dataclasses import replace

    out = []
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
                np.allclose(prev.rotation, s.rotation, atol=_GRID_TOL)
                and np.allclose(prev.translation, s.translation, atol=_GRID_TOL * size)
                and abs(float(prev.time_scale) - float(s.time_scale)) <= 1e-7
                and abs(prev.primitive_end - s.primitive_start) * T_l <= _GRID_TOL * dt
            )
            if same:
                out[-1] = replace(prev, end=s.end, primitive_end=s.primitive_end)
                continue
        out.append(s)
    return out


def _absorb_slivers(segs, stored, T: float, limit: float):
    """Extend matched pieces over short unmatched neighbours; returns (segments, absorbed)."""
    from dataclasses import replace

    out = list(segs)
    absorbed = []
    i = 0
    while i < len(out):
        s = out[i]
        short = (s.end - s.start) * T <= limit + 1e-12
        if s.primitive is None and short and len(out) > 1:
            if i > 0 and out[i - 1].primitive is not None:
                nb = out[i - 1]
                k = float(nb.time_scale)
                ext = (s.end - s.start) * T * k / float(stored[nb.primitive].duration)
                out[i - 1] = replace(nb, end=s.end, primitive_end=nb.primitive_end + ext)
            elif i + 1 < len(out) and out[i + 1].primitive is not None:
                nb = out[i + 1]
                k = float(nb.time_scale)
                ext = (s.end - s.start) * T * k / float(stored[nb.primitive].duration)
                out[i + 1] = replace(nb, start=s.start, primitive_start=nb.primitive_start - ext)
            else:
                i += 1
                continue
            absorbed.append((s.start * T, s.end * T))
            del out[i]
            continue
        i += 1
    return out, absorbed


def splice(
    machine,
    points,
    duration: float,
    segments: Sequence,
    stored: Mapping[int, StoredSignal],
    *,
    band: float | None = None,
    method: str = "auto",
    inverse_machine=None,
    absorb: float | None = None,
    correction: str = "error",
) -> SpliceResult:
    """First-iteration input of a new path from its matched segments.

    Parameters
    ----------
    machine : Machine
        Nominal model of the machine the signals were learned for.
    points : array, shape (n, d)
        The new path on the machine's grid t = 0, dt, ..., n = round(duration / dt) + 1.
    duration : float
        The new path's duration, seconds.
    segments : sequence of Segment
        In path order, contiguous from 0 to 1 (a :class:`primlib.match.Match`'s segments).
    stored : mapping primitive id -> StoredSignal
        Every matched primitive's stored signal and points.
    band : float, optional
        Transition band width in seconds (default 8 dt); 0 switches abruptly.
    method : {"auto", "model", "direct"}
        Time scaling: model-based (one version, the nominal model's filter G(s/k)/G(s)),
        model-free eq. (20) (needs ``versions``), or "auto": eq. (20) when the primitive
        is stored at as many distinct durations as the model has derivative orders
        (:func:`derivative_orders`) and the piece is time-scaled (k != 1), else
        model-based. A piece with k = 1 on the grid needs no time scaling at all.
    inverse_machine : Machine, optional
        Model whose inverse fills unmatched segments (default ``machine``).
    absorb : float, optional
        Unmatched segments at most this long (seconds, default 5 dt) next to a matched one
        are covered by extending that piece (its primitive goes on there, or its last input
        is held): the matcher's last search step can leave such slivers, and the inverse of
        a few samples would only add a junction.
    correction : {"error", "input", "output", "junction", "none"}
        Residual correction by superposition (see the module docstring). ``"error"``
        (default): ``G^-1 (y_d - E)``, E the model's error measured on the pieces' stored
        pairs, transformed like them and accumulated along the path. ``"input"``,
        ``"output"``, ``"junction"`` (the previous least-squares junction fit) and
        ``"none"`` (the spliced pieces as they are) are kept for comparison.

    Returns
    -------
    SpliceResult

    Raises
    ------
    InputError
        For a bad shape, non-contiguous segments, an unknown method or a negative band.
    """
    if method not in METHODS:
        raise InputError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    if correction not in CORRECTIONS:
        raise InputError(
            f"correction: expected one of {', '.join(CORRECTIONS)}, got {correction!r}"
        )
    dt = machine.dt
    pts = np.asarray(points, dtype=float)
    n = int(round(float(duration) / dt)) + 1
    if pts.ndim != 2 or pts.shape != (n, machine.dim):
        raise InputError(
            f"points: expected shape ({n}, {machine.dim}) for a {duration} s path at dt {dt}, "
            f"got {pts.shape}"
        )
    band = 8 * dt if band is None else float(band)
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
    T = float(duration)
    segs = _merge_continuations(segs, stored, dt)
    segs, absorbed = _absorb_slivers(segs, stored, T, absorb if absorb is not None else 5 * dt)
    bounds = np.array([[s.start, s.end] for s in segs], dtype=float)
    t = np.arange(n) * dt
    y_d = pts - pts[0]
    feedback = bool(machine.feedback)
    orders = derivative_orders(machine)
    notes: list[str] = [
        f"unmatched sliver t = {a:.4g}..{b:.4g} s absorbed by the neighbouring piece"
        for a, b in absorbed
    ]

    # junction geometry first: it sets the band widths, which set each piece's extent
    bands: list[Band] = []
    half = np.zeros((len(segs), 2))  # band half-widths before / after each segment
    vel = np.gradient(pts, dt, axis=0)
    extent = float(np.max(np.ptp(pts, axis=0))) or 1.0
    for j in range(len(segs) - 1):
        tj = bounds[j, 1] * T
        left, right = segs[j], segs[j + 1]
        if left.primitive is not None and right.primitive is not None:
            _, e = _piece_geometry(left, stored[left.primitive])
            s, _ = _piece_geometry(right, stored[right.primitive])
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
        bands.append(Band(tj, lo, hi, kind, delta, dist))
        half[j, 1] = hi - tj
        half[j + 1, 0] = tj - lo

    inverse = None
    pieces: list[np.ndarray] = []
    paths: list[np.ndarray] = []  # y_j: what each piece was built to track (new-path coords)
    inverses: list[np.ndarray] = []  # G^-1 y_j from the piece's own rest (plus its holding)
    slopes: list[np.ndarray] = []  # per-sample increments of the model's error on piece j
    sources: list[str] = []
    methods: list[str] = []
    for j, seg in enumerate(segs):
        a_t, b_t = bounds[j, 0] * T, bounds[j, 1] * T
        lo = max(0, int(np.floor((a_t - half[j, 0]) / dt + 1e-9)))
        hi = min(n - 1, int(np.ceil((b_t + half[j, 1]) / dt - 1e-9)))
        piece = np.zeros((n, machine.dim))
        if seg.primitive is None:
            if inverse is None:
                from primlib.plant import invert

                inv_m = machine if inverse_machine is None else inverse_machine
                inverse = invert(inv_m, y_d, reference=y_d if feedback else None)
            piece[lo : hi + 1] = inverse[lo : hi + 1]
            pieces.append(piece)
            paths.append(y_d)
            inverses.append(piece)
            slopes.append(np.zeros((n, machine.dim)))
            sources.append(
                f"segment {j}: unmatched, nominal-model inverse of the path "
                f"(t = {a_t:.4g}..{b_t:.4g} s)"
            )
            methods.append("inverse")
            continue
        prim = stored[seg.primitive]
        u_l = np.asarray(prim.signal, dtype=float)
        n_l = u_l.shape[0]
        T_l = float(prim.duration)
        span_d = b_t - a_t
        span_l = (seg.primitive_end - seg.primitive_start) * T_l
        k = float(seg.time_scale)
        if not np.isfinite(k) or k <= 0:
            if span_d <= 0:
                raise InputError(f"segments: segment {j} has zero duration and no time scale")
            k = span_l / span_d
        t0 = a_t - seg.primitive_start * T_l / k  # new time of the primitive's start
        m0 = int(np.floor(t0 / dt + 1e-9))
        offset = m0 * dt - t0
        if offset > 0:  # rounding
            offset = 0.0
        rot = np.asarray(seg.rotation, dtype=float)
        p = rot @ prim.points[0] + np.asarray(seg.translation, dtype=float) - pts[0]
        ref = (prim.points - prim.points[0]) if feedback else None
        # within 1e-6 dt of the grid, k within 1e-7 of 1: the stored grid is the new grid
        # (the input moves by ~1e-6 of one sample's change, far below any model error)
        near = abs(offset) <= _GRID_TOL * dt or abs(offset + dt) <= _GRID_TOL * dt
        on_grid = abs(k - 1.0) <= 0.1 * _GRID_TOL and near
        if on_grid:  # the matcher's k = 1 up to rounding: the stored grid is the new grid
            k = 1.0
            if abs(offset + dt) <= _GRID_TOL * dt:
                m0 += 1
            offset = 0.0
        n_out = hi - m0 + 1
        versions = list(prim.versions)
        use_direct = (
            method != "model"
            and not on_grid
            and orders is not None
            and not feedback
            and len(versions) + 1 >= len(orders)
        )
        if method == "direct" and not use_direct:
            raise InputError(
                f"method: 'direct' (eq. (20)) needs the primitive of segment {j} stored at "
                f"{len(orders or (1, 2))} durations on an open-loop all-pole machine, got "
                f"{len(versions) + 1}"
            )
        how = "model"
        path_j = np.zeros((n, machine.dim))
        inv_j = np.zeros((n, machine.dim))
        slope_j = np.zeros((n, machine.dim))
        if n_out >= 2:
            if use_direct:
                target_T = T_l / k  # the whole primitive's duration at the new speed
                vers = [(u_l, T_l / target_T)] + [
                    (np.asarray(s, dtype=float), float(d) / target_T) for s, d in versions
                ]
                try:
                    w, weights = time_scale_direct(vers, n_out, dt, orders=orders, offset=offset)
                except InputError as exc:
                    if method == "direct":
                        raise
                    notes.append(f"segment {j}: eq. (20) not used ({exc}); model-based instead")
                    use_direct = False
                else:
                    full = transform(machine, w, rotation=rot, n=n_out)
                    how = "direct"
            # where this piece goes: time scale, rotation, grid offset, length, PID reference
            placement = dict(k=k, rotation=rot, offset=offset, n=n_out, reference=ref)
            if not use_direct:
                full = transform(machine, u_l, **placement)
                how = "identity" if on_grid and np.allclose(rot, np.eye(machine.dim)) else how
            hold = holding_input(machine, p)[None, :]
            full = full + hold
            idx = np.arange(m0, hi + 1)
            keep = idx >= lo
            piece[idx[keep]] = full[keep]
            if lo < m0:  # band reaches before the primitive starts: at rest there
                piece[lo:m0] = hold
            if correction == "error":
                err = piece_error(machine, u_l, prim.points, **placement)
                inc = np.diff(err, axis=0, prepend=err[:1])
                slope_j[idx[keep]] = inc[keep]
                slope_j[max(lo, m0)] = 0.0  # the error accumulated before the window is not ours
            if correction in ("error", "input", "output"):
                y_full = piece_path(machine, u_l, prim.points, **placement)
                path_j[idx[keep]] = y_full[keep] + p
                if correction == "input":
                    v = model_inverse(machine, y_full, reference=y_full if feedback else None)
                    inv_j[idx[keep]] = v[keep] + hold
                if lo < m0:  # at rest before the primitive starts
                    path_j[lo:m0] = p
                    inv_j[lo:m0] = hold
        pieces.append(piece)
        paths.append(path_j)
        inverses.append(inv_j)
        slopes.append(slope_j)
        methods.append(how)
        label = prim.name or f"#{seg.primitive}"
        what = {
            "identity": "stored signal",
            "model": "model-based time scale G(s/k)/G(s)",
            "direct": f"model-free eq. (20) from {len(versions) + 1} durations",
        }[how]
        sources.append(
            f"segment {j}: primitive {seg.primitive} ({label}) "
            f"v {seg.primitive_start:.4g}..{seg.primitive_end:.4g}, k = {k:.4g}, "
            f"rotation {np.degrees(seg.angle):.3g} deg, {what} (t = {a_t:.4g}..{b_t:.4g} s)"
        )
        if n_l < 2:
            notes.append(f"segment {j}: stored signal has fewer than 2 samples")

    # assemble: each sample from its segment, then blend across the bands
    edges = bounds[:, 1] * T
    sample_segment = np.searchsorted(edges[:-1], t + 1e-9 * dt, side="right")

    def assemble(parts):
        out = np.empty((n, machine.dim))
        for j, part in enumerate(parts):
            sel = sample_segment == j
            out[sel] = part[sel]
        for j, bd in enumerate(bands):
            if bd.end - bd.start <= 0:
                continue
            sel = (t >= bd.start - 1e-9 * dt) & (t <= bd.end + 1e-9 * dt)
            lam = ((t[sel] - bd.start) / (bd.end - bd.start))[:, None]
            out[sel] = (1.0 - lam) * parts[j][sel] + lam * parts[j + 1][sel]
        return out

    u_s = assemble(pieces)
    u = u_s
    fb_ref = y_d if feedback else None
    exact = (
        correction in ("error", "input", "output")
        and all(m == "identity" for m in methods)
        and float(np.max(np.abs(y_d - assemble(paths)))) <= 1e-12 * extent
    )
    if exact:
        # the path is the pieces' own stored paths, sample for sample: their stored inputs
        # are the library's answer as they are (no correction to add, not even rounding)
        notes.append("the path is made of the pieces' own stored paths: stored inputs as is")
    elif correction == "error":
        # the model's error along the new path, estimated from the pieces: each piece's
        # increments (the stored primitive's measured output minus the model's output of its
        # stored input, time-scaled and rotated), blended over the bands, accumulated
        err_path = np.cumsum(assemble(slopes), axis=0)
        # E switches pieces at the junctions (a kink where a band has no width): an estimate,
        # so smoothed over the band's scale (Gaussian, sigma = max(band, 8 dt) / 4) — the
        # inverse of a kink is an input impulse that the sampling zero near -1 of the XYZ
        # axes rings out for a second (measured: 10x the Nyquist-band input of the plain
        # inverse on the example path)
        sigma = max(band, 8 * dt) / (4 * dt)
        err_path = ndimage.gaussian_filter1d(err_path, sigma, axis=0, mode="nearest")
        err_path -= err_path[0]
        u = model_inverse(machine, y_d - err_path, reference=fb_ref)
        notes.append(
            "model-error correction: the model inverse of the path minus the model's error "
            "the pieces measured (stored path minus model output of the stored input), "
            "accumulated along the path"
        )
    elif correction == "input":
        # eq. (11) by superposition on the residual: G^-1 y_d - Σ λ_j G^-1 y_j is the
        # model's input for what the pieces miss; the difference is exactly 0 where the
        # path is a piece's own path (bit for bit: a stored primitive comes back)
        u = u_s + (model_inverse(machine, y_d, reference=fb_ref) - assemble(inverses))
        notes.append(
            "residual correction: the model inverse of the path minus the blended model "
            "inverses of the pieces' own paths added to the spliced input"
        )
    elif correction == "output":
        r = y_d - assemble(paths)
        u = u_s + model_inverse(machine, r, reference=r if feedback else None)
        notes.append(
            "residual correction: the model inverse of the path minus the pieces' blended "
            "paths added to the spliced input"
        )
    elif correction == "junction" and bands:
        u, fixed = _correct_junctions(machine, u, y_d, t, bands, max(band / 2, 10 * dt), feedback)
        notes.append(
            f"junction correction: input in {fixed} band sample(s) per axis fitted so the "
            "model follows the path through the junctions"
        )
    if any(m == "inverse" for m in methods):
        k_un = sum(m == "inverse" for m in methods)
        notes.append(f"{k_un} unmatched segment(s) filled with the nominal-model inverse")
    return SpliceResult(
        u=u,
        bands=tuple(bands),
        sample_segment=sample_segment,
        sources=tuple(sources),
        methods=tuple(methods),
        notes=tuple(notes),
        spliced=u_s,
        correction=correction,
    )
