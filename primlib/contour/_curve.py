"""A path as a curve in time: position, velocity and acceleration at times ``s`` (seconds).

Two sources: a Trajectory (anything with ``duration``, ``at(v)``, ``velocity(v)``,
``acceleration(v)``, parameter ``v = s / T``) or reference samples on a time grid, joined by
a not-a-knot cubic spline in time (C2, exact on cubics), which is what a controller's
interpolator would run through the same samples.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from primlib._errors import InputError

__all__ = ["Curve", "as_curve"]


class Curve:
    """Evaluate ``r(s)``, ``r'(s)``, ``r''(s)`` for ``s`` in ``[s0, s1]`` (clipped outside).

    Parameters
    ----------
    pos, vel, acc : callable
        ``f(s (m,)) -> (m, d)``; ``s`` is already clipped to ``[s0, s1]``.
    s0, s1 : float
        Time span of the path, ``s1 > s0``.
    dim : int
        Number of coordinates, 2 or 3.
    nodes : int
        Number of polyline nodes (uniform in time) used by the coarse closest-point search.
    """

    def __init__(self, pos, vel, acc, s0: float, s1: float, dim: int, nodes: int) -> None:
        self._pos, self._vel, self._acc = pos, vel, acc
        self.s0, self.s1, self.dim = float(s0), float(s1), int(dim)
        self.node_s = np.linspace(self.s0, self.s1, int(nodes))
        self.node_p = self.pos(self.node_s)
        seg = np.diff(self.node_p, axis=0)
        self.seg = seg
        self.seg_len2 = np.einsum("ij,ij->i", seg, seg)
        self.cum = np.concatenate(([0.0], np.cumsum(np.sqrt(self.seg_len2))))
        lo, hi = self.node_p.min(axis=0), self.node_p.max(axis=0)
        self.extent = float(np.max(hi - lo))
        # a speed below this counts as "stopped": tangent from the chord instead of r'
        self.speed_floor = 1e-9 * max(self.cum[-1], self.extent, 1e-300) / (self.s1 - self.s0)

    def clip(self, s: np.ndarray) -> np.ndarray:
        return np.clip(s, self.s0, self.s1)

    def pos(self, s: np.ndarray) -> np.ndarray:
        return np.asarray(self._pos(self.clip(s)), dtype=float)

    def vel(self, s: np.ndarray) -> np.ndarray:
        return np.asarray(self._vel(self.clip(s)), dtype=float)

    def acc(self, s: np.ndarray) -> np.ndarray:
        return np.asarray(self._acc(self.clip(s)), dtype=float)

    def tangent(self, s: np.ndarray, vel: np.ndarray | None = None):
        """Unit tangent at ``s`` and a mask of where it is well defined.

        Where the speed vanishes (a stop, a cusp), the tangent is the direction of the
        outgoing chord to the next polyline node (the incoming one at the path's end); where
        the curve does not move at all over that chord, the mask is False and the tangent 0.
        """
        s = self.clip(np.asarray(s, dtype=float))
        v = self.vel(s) if vel is None else vel
        speed = np.linalg.norm(v, axis=1)
        slow = speed <= self.speed_floor
        tau = v.copy()
        if np.any(slow):
            ss = s[slow]
            h = self.node_s[1] - self.node_s[0]
            fwd = ss + h <= self.s1
            a = np.where(fwd, ss, ss - h)
            b = np.where(fwd, ss + h, ss)
            tau[slow] = self.pos(b) - self.pos(a)
        norm = np.linalg.norm(tau, axis=1)
        ok = norm > 0
        out = np.zeros_like(tau)
        out[ok] = tau[ok] / norm[ok, None]
        return out, ok


def _check_points(name: str, a, dims=(2, 3)) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[1] not in dims:
        want = " or ".join(f"(n, {k})" for k in dims)
        raise InputError(f"{name}: expected an array of shape {want}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name}: expected finite values, got NaN or inf")
    return a


def check_times(t, n: int | None = None) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise InputError(f"t: expected a 1-D array of times, got shape {t.shape}")
    if n is not None and t.shape[0] != n:
        raise InputError(f"t: expected {n} times (one per row of actual), got {t.shape[0]}")
    if not np.all(np.isfinite(t)):
        raise InputError("t: expected finite times, got NaN or inf")
    return t


def as_curve(path, t: np.ndarray, nodes: int | None = None) -> Curve:
    """Wrap a Trajectory, or (n, d) reference samples on the grid ``t``, as a :class:`Curve`.

    Parameters
    ----------
    path : Trajectory or array, shape (n, d)
        The path; samples are joined by a not-a-knot cubic spline in time.
    t : array, shape (n,)
        Times in seconds; for samples, the (strictly increasing) grid they are on.
    nodes : int, optional
        Polyline nodes (uniform in time) for the coarse search; default 4096, and at least 4
        per control point for a Trajectory, at most 2 per sample interval for samples. The
        Newton step refines on the curve itself, so the polyline only has to put the
        closest point in the right 3-segment bracket.

    Raises
    ------
    InputError
        Samples of the wrong shape, non-finite, or a grid not strictly increasing.
    """
    if hasattr(path, "at") and hasattr(path, "duration"):
        T = float(path.duration)
        if not np.isfinite(T) or T <= 0:
            raise InputError(f"path: expected a positive duration, got {T}")
        dim = int(np.asarray(path.at(np.array([0.0]))).shape[1])
        if nodes is None:
            nodes = 4096
            if hasattr(path, "definition"):
                nodes = max(nodes, 4 * len(path.definition()["ctrlpts"]))
        return Curve(
            lambda s: path.at(s / T),
            lambda s: path.velocity(s / T),
            lambda s: path.acceleration(s / T),
            0.0,
            T,
            dim,
            nodes,
        )
    pts = _check_points("path", path)
    t = check_times(t, pts.shape[0])
    if pts.shape[0] < 2:
        raise InputError(f"path: expected at least 2 reference samples, got {pts.shape[0]}")
    if np.any(np.diff(t) <= 0):
        raise InputError(
            "t: expected strictly increasing times for a sampled path, got a step <= 0"
        )
    spline = CubicSpline(t, pts, axis=0)
    if nodes is None:
        nodes = min(2 * pts.shape[0] - 1, 4096)
    return Curve(
        spline, lambda s: spline(s, 1), lambda s: spline(s, 2), t[0], t[-1], pts.shape[1], nodes
    )
