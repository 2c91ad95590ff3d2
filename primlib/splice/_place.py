"""Stage 2 of the splice: place each piece — its stored input transformed onto the new grid.

Each matched segment gets its primitive's stored input transformed (time scale, rotation,
holding input for the translation) as a whole primitive from rest, on the new path's grid,
and the window it covers (bands included) cut out. Unlike eq. (23), which concatenates pieces
of their own durations and then corrects the total length, each piece is time-scaled to
exactly its segment (the matcher's time scale), so the spliced input has exactly the new
path's length and the paper's length error ΣΔT is zero by construction.

Which time scaling: a piece with k = 1 on the grid uses the stored input as it is; otherwise
``method="auto"`` uses eq. (20) when the primitive is stored at as many distinct durations as
the model's inverse has derivative orders on an open-loop all-pole machine, and the
model-based transform in every other case; ``"model"`` / ``"direct"`` force one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from primlib._errors import InputError
from primlib.splice._plan import GRID_TOL, JunctionPlan, StoredSignal
from primlib.splice._transform import (
    holding_input,
    piece_path,
    time_scale_direct,
    transform,
)

__all__ = ["METHODS", "Placement", "PlacedPiece", "place_piece", "place_unmatched"]

METHODS = ("auto", "model", "direct")

_WHAT = {
    "identity": "stored signal",
    "model": "model-based time scale G(s/k)/G(s)",
}


@dataclass(frozen=True)
class Placement:
    """Where a transformed primitive goes on the new path's grid.

    Attributes
    ----------
    k : float
        Time scale (primitive time per new time).
    rotation : array, shape (d, d)
    offset : float
        New time of the primitive's first transformed sample minus its start, in (-dt, 0].
    first : int
        New-grid sample of the primitive's first transformed sample (may be < 0).
    lo, hi : int
        The samples the piece covers on the new grid, bands included.
    translation : array, shape (d,)
        Offset of the primitive's first point from the path's first point.
    hold : array, shape (d,)
        Holding input of that offset (:func:`holding_input`).
    reference : array, shape (n_l, d) or None
        The stored PID reference (feedback machines).
    on_grid : bool
        The stored grid is the new grid (k = 1, no offset).
    """

    k: float
    rotation: np.ndarray
    offset: float
    first: int
    lo: int
    hi: int
    translation: np.ndarray
    hold: np.ndarray
    reference: np.ndarray | None
    on_grid: bool

    @property
    def n(self) -> int:
        """Transformed samples, from the primitive's start to ``hi``."""
        return self.hi - self.first + 1

    def transform_args(self) -> dict:
        """Keyword arguments of :func:`transform`, :func:`piece_path`, :func:`piece_error`."""
        return dict(
            k=self.k, rotation=self.rotation, offset=self.offset, n=self.n, reference=self.reference
        )

    def put(self, full: np.ndarray, before, n: int) -> np.ndarray:
        """An (n, d) signal: ``full`` (rows from ``first``) on [lo, hi], ``before`` on the
        samples before the primitive starts, zero elsewhere."""
        out = np.zeros((n, full.shape[1]))
        idx = np.arange(self.first, self.hi + 1)
        keep = idx >= self.lo
        out[idx[keep]] = full[keep]
        if self.lo < self.first:  # the band reaches before the primitive starts: at rest
            out[self.lo : self.first] = before
        return out


@dataclass(frozen=True)
class PlacedPiece:
    """One segment's input on the new path's grid.

    Attributes
    ----------
    u : array, shape (n, d)
        The piece's input on its samples (bands included), zero elsewhere.
    path : array, shape (n, d)
        What the piece was built to track, relative to the path's first point, on the same
        samples (for an unmatched segment: the path itself).
    method : str
        ``"identity"``, ``"model"``, ``"direct"`` or ``"inverse"`` (unmatched).
    source : str
        One line saying where the input came from.
    stored : StoredSignal or None
        The primitive (None when unmatched).
    placement : Placement or None
        None when unmatched, or when the piece is shorter than two samples.
    notes : tuple of str
    """

    u: np.ndarray
    path: np.ndarray
    method: str
    source: str
    stored: StoredSignal | None = None
    placement: Placement | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)


def _placement(machine, plan: JunctionPlan, j: int, prim: StoredSignal) -> Placement:
    seg = plan.segments[j]
    dt = machine.dt
    a_t, b_t = plan.bounds[j] * plan.duration
    lo, hi = plan.extent_samples(j)
    T_l = float(prim.duration)
    k = float(seg.time_scale)
    if not np.isfinite(k) or k <= 0:
        if b_t - a_t <= 0:
            raise InputError(f"segments: segment {j} has zero duration and no time scale")
        k = (seg.primitive_end - seg.primitive_start) * T_l / (b_t - a_t)
    t0 = a_t - seg.primitive_start * T_l / k  # new time of the primitive's start
    m0 = int(np.floor(t0 / dt + 1e-9))
    offset = min(m0 * dt - t0, 0.0)  # > 0 only by rounding
    # within 1e-6 dt of the grid, k within 1e-7 of 1: the stored grid is the new grid
    # (the input moves by ~1e-6 of one sample's change, far below any model error)
    near = abs(offset) <= GRID_TOL * dt or abs(offset + dt) <= GRID_TOL * dt
    on_grid = abs(k - 1.0) <= 0.1 * GRID_TOL and near
    if on_grid:
        k = 1.0
        if abs(offset + dt) <= GRID_TOL * dt:
            m0 += 1
        offset = 0.0
    rot = np.asarray(seg.rotation, dtype=float)
    p = rot @ prim.points[0] + np.asarray(seg.translation, dtype=float) - plan.points[0]
    ref = (prim.points - prim.points[0]) if machine.feedback else None
    hold = holding_input(machine, p)
    return Placement(k, rot, offset, m0, lo, hi, p, hold, ref, on_grid)


def _use_direct(machine, prim, pl: Placement, method: str, orders, j: int) -> bool:
    versions = len(prim.versions) + 1
    use = (
        method != "model"
        and not pl.on_grid
        and orders is not None
        and not machine.feedback
        and versions >= len(orders)
    )
    if method == "direct" and not use:
        raise InputError(
            f"method: 'direct' (eq. (20)) needs the primitive of segment {j} stored at "
            f"{len(orders or (1, 2))} durations on an open-loop all-pole machine, got "
            f"{versions}"
        )
    return use


def _direct(machine, prim: StoredSignal, pl: Placement, orders) -> np.ndarray:
    """Eq. (20) from the stored versions, then the rotation (raises InputError)."""
    u_l = np.asarray(prim.signal, dtype=float)
    T_l = float(prim.duration)
    target_T = T_l / pl.k  # the whole primitive's duration at the new speed
    vers = [(u_l, T_l / target_T)] + [
        (np.asarray(s, dtype=float), float(d) / target_T) for s, d in prim.versions
    ]
    w, _ = time_scale_direct(vers, pl.n, machine.dt, orders=orders, offset=pl.offset)
    return transform(machine, w, rotation=pl.rotation, n=pl.n)


def _transformed(machine, prim, pl: Placement, method: str, orders, j: int):
    """The whole transformed primitive from rest: (input, how, notes)."""
    notes: list[str] = []
    if _use_direct(machine, prim, pl, method, orders, j):
        try:
            return _direct(machine, prim, pl, orders), "direct", notes
        except InputError as exc:
            if method == "direct":
                raise
            notes.append(f"segment {j}: eq. (20) not used ({exc}); model-based instead")
    full = transform(machine, np.asarray(prim.signal, dtype=float), **pl.transform_args())
    same = pl.on_grid and np.allclose(pl.rotation, np.eye(machine.dim))
    return full, "identity" if same else "model", notes


def place_piece(machine, plan: JunctionPlan, j: int, prim: StoredSignal, method, orders):
    """Segment j's primitive transformed onto the new grid and cut to its samples.

    Parameters
    ----------
    machine : Machine
        The model the transforms use.
    plan : JunctionPlan
    j : int
        Segment index (a matched segment).
    prim : StoredSignal
        Its primitive.
    method : {"auto", "model", "direct"}
    orders : tuple of int or None
        :func:`derivative_orders` of ``machine``.

    Returns
    -------
    PlacedPiece
    """
    seg = plan.segments[j]
    pl = _placement(machine, plan, j, prim)
    n, d = plan.n, machine.dim
    notes: list[str] = []
    how = "model"
    u = path = np.zeros((n, d))
    if pl.n >= 2:
        full, how, notes = _transformed(machine, prim, pl, method, orders, j)
        u = pl.put(full + pl.hold[None, :], pl.hold, n)
        y_full = piece_path(machine, prim.signal, prim.points, **pl.transform_args())
        path = pl.put(y_full + pl.translation, pl.translation, n)
    if np.asarray(prim.signal).shape[0] < 2:
        notes.append(f"segment {j}: stored signal has fewer than 2 samples")
    a_t, b_t = plan.bounds[j] * plan.duration
    what = _WHAT.get(how, f"model-free eq. (20) from {len(prim.versions) + 1} durations")
    source = (
        f"segment {j}: primitive {seg.primitive} ({prim.name or f'#{seg.primitive}'}) "
        f"v {seg.primitive_start:.4g}..{seg.primitive_end:.4g}, k = {pl.k:.4g}, "
        f"rotation {np.degrees(seg.angle):.3g} deg, {what} (t = {a_t:.4g}..{b_t:.4g} s)"
    )
    placement = pl if pl.n >= 2 else None
    return PlacedPiece(u, path, how, source, prim, placement, tuple(notes))


def place_unmatched(plan: JunctionPlan, j: int, inverse: np.ndarray) -> PlacedPiece:
    """An unmatched segment: the model inverse of the whole path, cut to its samples."""
    lo, hi = plan.extent_samples(j)
    u = np.zeros_like(inverse)
    u[lo : hi + 1] = inverse[lo : hi + 1]
    a_t, b_t = plan.bounds[j] * plan.duration
    source = (
        f"segment {j}: unmatched, nominal-model inverse of the path (t = {a_t:.4g}..{b_t:.4g} s)"
    )
    return PlacedPiece(u, plan.y_d, "inverse", source)
