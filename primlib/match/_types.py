"""Result types of the matcher: :class:`Segment` and :class:`Match`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Segment", "Match"]


@dataclass(frozen=True)
class Segment:
    """One piece of a new path and the stored piece that matches it.

    So that ``path.at(start + (end - start) * s) ≈ rotation @ prim.at(primitive_start +
    (primitive_end - primitive_start) * s) + translation`` for s in [0, 1], with RMS
    deviation ``rmsd`` over uniform-time samples.

    Attributes
    ----------
    start, end : float
        Normalised time of the new path covered by this segment.
    primitive : int or None
        Id of the matched primitive; None where nothing in the library matched.
    primitive_name : str or None
    primitive_start, primitive_end : float
        Normalised time of the primitive's matched piece (nan when unmatched).
    rotation : array, shape (d, d)
        Proper rotation (det = +1); identity when unmatched.
    translation : array, shape (d,)
    time_scale : float
        Primitive interval duration / segment duration (nan when unmatched).
    rmsd : float
        Kabsch RMSD between the two pieces sampled at uniform time (nan when unmatched).
    """

    start: float
    end: float
    primitive: int | None
    primitive_name: str | None
    primitive_start: float
    primitive_end: float
    rotation: np.ndarray
    translation: np.ndarray
    time_scale: float
    rmsd: float

    @property
    def matched(self) -> bool:
        return self.primitive is not None

    @property
    def angle(self) -> float:
        """Rotation angle in radians (the axis-angle magnitude)."""
        r = np.asarray(self.rotation, dtype=float)
        c = (np.trace(r) - (r.shape[0] - 2)) / 2.0 if r.shape[0] == 3 else r[0, 0]
        if r.shape[0] == 2:
            return float(np.arctan2(r[1, 0], r[0, 0]))
        return float(np.arccos(np.clip(c, -1.0, 1.0)))

    def to_dict(self) -> dict[str, Any]:
        def num(x: float) -> float | None:
            return None if x is None or not np.isfinite(x) else float(x)

        return {
            "start": float(self.start),
            "end": float(self.end),
            "primitive": None if self.primitive is None else int(self.primitive),
            "primitive_name": self.primitive_name,
            "primitive_start": num(self.primitive_start),
            "primitive_end": num(self.primitive_end),
            "rotation": np.asarray(self.rotation, dtype=float).tolist(),
            "translation": np.asarray(self.translation, dtype=float).tolist(),
            "time_scale": num(self.time_scale),
            "rmsd": num(self.rmsd),
            "angle_deg": float(np.degrees(self.angle)),
        }


@dataclass(frozen=True)
class Match:
    """The segmentation of a new path against a machine's primitives.

    Attributes
    ----------
    segments : tuple of Segment
        In path order, contiguous, first start 0, last end 1.
    matched_fraction : float
        (property) Fraction of the path's duration that matched segments cover.
    machine : str
    eps : float
        The RMSD tolerance each matched segment satisfies.
    rotation_mode : str
        ``"full"``, ``"z"`` or ``"none"``.
    path : Trajectory or None
        The new path that was matched.
    info : dict
        Search statistics (candidates examined, timings); free-form.
    """

    segments: tuple[Segment, ...]
    machine: str
    eps: float
    rotation_mode: str = "full"
    path: Any = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def n_unmatched(self) -> int:
        return sum(1 for s in self.segments if s.primitive is None)

    @property
    def matched_fraction(self) -> float:
        """Fraction of the path's duration covered by matched segments, in [0, 1]."""
        return float(sum(s.end - s.start for s in self.segments if s.primitive is not None))

    def to_dict(self) -> dict[str, Any]:
        return {
            "machine": self.machine,
            "eps": float(self.eps),
            "rotation_mode": self.rotation_mode,
            "n_segments": len(self.segments),
            "n_unmatched": self.n_unmatched,
            "matched_fraction": self.matched_fraction,
            "segments": [s.to_dict() for s in self.segments],
            "info": {k: v for k, v in self.info.items() if isinstance(v, int | float | str)},
        }
