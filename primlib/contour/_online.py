"""Contour error one sample at a time, for an estimator inside a control loop."""

from __future__ import annotations

import numpy as np

from primlib._errors import InputError
from primlib.contour._curve import as_curve
from primlib.contour._ellipse import ellipse_closest_point
from primlib.contour._estimate import METHODS, ContourEstimator, _circle_distance

__all__ = ["OnlineContourEstimator"]


class OnlineContourEstimator:
    """Per-sample contour error for a 2-D path on a fixed time grid (a control loop).

    The linear and circular estimates need only the reference point, its tangent and its
    curvature at each grid time: these are evaluated once for the whole grid, so a call
    costs a few float operations. The exact estimate uses the paper's ellipse quartic when
    ``ellipse`` is given (eqs. (7)-(13)), else :class:`ContourEstimator` on the one point.

    Parameters
    ----------
    path : Trajectory or array, shape (n, 2)
        The path (samples on the grid ``t``).
    t : array, shape (n,)
        The loop's time grid.
    method : {"exact", "linear", "circular"}
    ellipse : tuple (semi_x, semi_y, centre (2,), clockwise), optional
        The path is this ellipse (exact method only).

    Raises
    ------
    InputError
        Unknown method, a 3-D path, bad samples.
    """

    def __init__(self, path, t, method: str = "exact", ellipse=None) -> None:
        if method not in METHODS:
            raise InputError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
        t = np.asarray(t, dtype=float)
        self.method = method
        curve = as_curve(path, t)
        if curve.dim != 2:
            raise InputError(f"path: expected a 2-D path for the loop estimator, got {curve.dim}-D")
        self._ellipse = None
        if method == "exact":
            if ellipse is not None:
                a, b, centre, clockwise = ellipse
                self._ellipse = (float(a), float(b), np.asarray(centre, float), bool(clockwise))
            else:
                self._full = ContourEstimator(path, t if not hasattr(path, "at") else None)
            self._t = t
            return
        s = curve.clip(t)
        v = curve.vel(s)
        tau, ok = curve.tangent(s, v)
        self._r = curve.pos(s)
        self._tau = tau
        self._nrm = np.stack([-tau[:, 1], tau[:, 0]], axis=1)
        self._ok = ok
        if method == "circular":
            acc = curve.acc(s)
            speed = np.linalg.norm(v, axis=1)
            moving = (speed > curve.speed_floor) & ok
            sp = np.where(moving, speed, 1.0)
            cross = v[:, 0] * acc[:, 1] - v[:, 1] * acc[:, 0]
            self._kappa = np.where(moving, cross / sp**3, 0.0)
        else:
            self._kappa = np.zeros(len(s))

    def __call__(self, k: int, p) -> tuple[float, np.ndarray]:
        """Contour error (left of travel positive) and left unit normal at grid index ``k``.

        Parameters
        ----------
        k : int
            Index into the time grid.
        p : array, shape (2,)
            Actual position.

        Returns
        -------
        error : float
        normal : array, shape (2,)
        """
        p = np.asarray(p, dtype=float)
        if self.method == "exact":
            if self._ellipse is None:
                est = self._full(self._t[k : k + 1], p[None, :])
                return float(est.error[0]), est.normal[0]
            a, b, c, clockwise = self._ellipse
            q = p - c
            e = ellipse_closest_point(a, b, q[None, :])[0]
            # outward normal at E; left of travel for a clockwise ellipse
            n = np.array([e[0] / a**2, e[1] / b**2])
            n /= np.linalg.norm(n)
            if not clockwise:
                n = -n
            return float(n @ (q - e)), n
        d = p - self._r[k]
        if not self._ok[k]:
            dist = float(np.hypot(d[0], d[1]))
            return dist, (d / dist if dist > 0 else np.zeros(2))
        a = float(self._tau[k] @ d)
        b = float(self._nrm[k] @ d)
        if self.method == "linear":
            return b, self._nrm[k]
        return float(_circle_distance(self._kappa[k], a, b)), self._nrm[k]
