"""A lower bound on every primitive's RMSD against a piece of the path at once, before any
window is scored: the probes a long piece of a path the library does not hold costs nothing.

Any piece P of primitive j, sampled anywhere on its interpolant, lies in a ball of radius
R_j about the centre c_j of the primitive's bounding box (the samples' farthest distance
from c_j, plus the Catmull-Rom overshoot: a value between samples i and i + 1 is the chord
point plus Σ c_m (p_m − p_i) with Σ|c_m|·|p_m − p_i| < 0.3 of the largest sample step;
0.5 is used). Its radius of gyration g(P) (RMS distance from its centroid, which minimises
the RMS distance to any point) is then at most R_j. The Kabsch RMSD of eq. (1) satisfies
√K·rmsd = ‖Q̃ − R P̃‖ ≥ ‖Q̃‖ − ‖P̃‖ (triangle inequality, R orthogonal), so

    rmsd ≥ g(Q) − R_j                                              (any rotation)

and axis by axis for the restricted families: with R = I the error splits per axis,
rmsd² ≥ Σ_a (g_a(Q) − h_ja)₊² (h_ja the bounding box's half-width plus the same margin);
a turn about z keeps the xy norm and the z axis: rmsd² ≥ (g_xy(Q) − R_xy,j)₊² +
(g_z(Q) − h_jz)₊². A primitive too short for the time-scale range (its duration below
low × the piece's) cannot match at all. The probe fails when every primitive's bound is
at or above ε: exactly what the exact check would decide, only sooner.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._rows import row_groups

__all__ = ["Envelope", "lower_bounds", "rejects", "row_groups"]

_OVERSHOOT = 0.5  # of the largest sample step (Catmull-Rom: < 0.3)


@dataclass(frozen=True)
class Envelope:
    """Per primitive: ball radius ``radius`` (k,), half-widths ``half`` (k, d), the xy
    radius ``radius_xy`` (k,) (3-D only, else zeros), and ``last`` = samples − 1 (k,)."""

    radius: np.ndarray
    half: np.ndarray
    radius_xy: np.ndarray
    last: np.ndarray

    @classmethod
    def of(cls, points: np.ndarray, offsets: np.ndarray, max_step: np.ndarray) -> Envelope:
        starts = offsets[:-1]
        counts = np.diff(offsets)
        k, d = len(starts), points.shape[1]
        lo, hi = np.empty((k, d)), np.empty((k, d))
        far2, far2_xy = np.empty(k), np.zeros(k)
        # whole primitives ~65,536 samples at a time, one axis at a time on contiguous
        # columns: every pass then reads a column in cache (2.5x less time than whole
        # columns, whose passes went to memory; the (N, d) layout's short rows cost ~5x
        # more per element)
        for g0, g1 in row_groups(offsets):
            r0, r1 = offsets[g0], offsets[g1]
            st, cn = starts[g0:g1] - r0, counts[g0:g1]
            sq = np.zeros(r1 - r0)
            for a in range(d):
                col = np.array(points[r0:r1, a])  # a copy, contiguous
                lo[g0:g1, a] = np.minimum.reduceat(col, st)
                hi[g0:g1, a] = np.maximum.reduceat(col, st)
                col -= np.repeat(0.5 * (lo[g0:g1, a] + hi[g0:g1, a]), cn)  # from the centre
                col *= col
                sq += col
                if a == 1 and d == 3:
                    far2_xy[g0:g1] = np.maximum.reduceat(sq, st)
            far2[g0:g1] = np.maximum.reduceat(sq, st)
        margin = _OVERSHOOT * max_step
        far_xy = np.sqrt(far2_xy) + margin if d == 3 else np.zeros(k)
        half = 0.5 * (hi - lo) + margin[:, None]
        return cls(np.sqrt(far2) + margin, half, far_xy, np.diff(offsets) - 1.0)


def lower_bounds(env: Envelope, q: np.ndarray, rotation: str) -> np.ndarray:
    """Lower bound of the Kabsch RMSD of any piece of each primitive against ``q`` (K, d)
    in the rotation family ``rotation``, shape (k,) (module notes)."""
    qc = q - q.mean(axis=0)
    g_axis = np.sqrt(np.mean(qc * qc, axis=0))
    if rotation == "full":
        return np.maximum(float(np.sqrt(np.sum(g_axis**2))) - env.radius, 0.0)
    if rotation == "none":
        return np.sqrt(np.sum(np.maximum(g_axis - env.half, 0.0) ** 2, axis=1))
    g_xy = float(np.hypot(g_axis[0], g_axis[1]))
    return np.hypot(
        np.maximum(g_xy - env.radius_xy, 0.0), np.maximum(g_axis[2] - env.half[:, 2], 0.0)
    )


def rejects(env: Envelope, q: np.ndarray, samples: float, low: float, rotation: str,
            eps: float, more: np.ndarray | None = None) -> bool:  # fmt: skip
    """True when no primitive can be within ``eps`` of the piece ``q`` (K, d), which lasts
    ``samples`` sample steps, at time scales >= ``low`` (module notes); ``more``: other lower
    bounds per primitive (:func:`._rough.rough_bounds`), or None."""
    lb = lower_bounds(env, q, rotation)
    if more is not None:
        lb = np.maximum(lb, more)
    possible = (env.last >= low * samples * (1.0 - 1e-9)) & (lb < eps * (1.0 + 1e-9))
    return not bool(np.any(possible))
