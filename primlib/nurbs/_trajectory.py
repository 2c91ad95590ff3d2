"""The Trajectory: a NURBS path whose parameter is normalised time."""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from scipy.interpolate import BSpline

from primlib._errors import InputError
from primlib.defaults import FIT_RTOL
from primlib.nurbs._basis import insert_knot, multiplicity
from primlib.nurbs._checks import (
    clamped_knots,
    degree_of,
    frozen,
    points_of,
    positive,
    radius,
)
from primlib.nurbs._fit import fit_samples
from primlib.nurbs._geomdl import (
    definition_from_exchange,
    definition_from_geomdl,
    exchange_dict,
    to_geomdl,
)

__all__ = ["Trajectory", "MIN_SAMPLES", "DEFAULT_RTOL", "V_SLACK", "DT_RTOL"]

MIN_SAMPLES = 8
"""Fewest samples :meth:`Trajectory.from_samples` accepts."""

DEFAULT_RTOL = FIT_RTOL
"""Default fit tolerance as a fraction of the samples' size, twice their largest distance
from the centroid (:data:`primlib.defaults.FIT_RTOL`)."""

V_SLACK = 1e-12
"""How far outside [0, 1] a normalised time may stray (rounding) before it is an error."""

DT_RTOL = 1e-6
"""Relative tolerance (of dt) for the duration being a whole number of sample steps."""


class Trajectory:
    """A 2-D or 3-D path in time: a NURBS curve C(v) with v = t / T in [0, 1].

    Immutable: the arrays are read-only and attributes cannot be set. Build one with
    :meth:`from_samples` (fit), :meth:`from_definition` (cheap, no checks beyond shapes),
    :meth:`from_nurbs`, :meth:`from_csv` or :meth:`from_json`.

    Evaluation (:meth:`at`, :meth:`velocity`, :meth:`acceleration`, :meth:`sample`) runs on
    scipy ``BSpline`` objects in homogeneous coordinates (w P, w), built once and cached;
    geomdl holds the same curve for exchange (:attr:`nurbs`, :meth:`to_json`).

    Attributes
    ----------
    duration : float
        T in seconds.
    dim : int
        d, 2 or 3.
    degree : int
        p.
    knots : array, shape (m + p + 1,)
        Clamped knot vector on [0, 1].
    ctrlpts : array, shape (m, d)
        Cartesian control points.
    weights : array, shape (m,)
        Positive weights (all 1 for a fitted path).
    dt : float or None
        Sample time of the samples the path was fitted from (None when not fitted).
    fit_error : float or None
        Largest distance between the fitted curve and its samples (None when not fitted).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(201) * 0.01
    >>> p = Trajectory.from_samples(np.column_stack([np.cos(t), np.sin(t)]), dt=0.01)
    >>> p.duration, p.dim
    (2.0, 2)
    >>> p.sample(0.01).shape
    (201, 2)
    """

    __slots__ = (
        "duration",
        "dim",
        "degree",
        "knots",
        "ctrlpts",
        "weights",
        "dt",
        "fit_error",
        "rational",
        "_cache",
    )

    def __init__(
        self,
        degree: int,
        knots: np.ndarray,
        ctrlpts: np.ndarray,
        weights: np.ndarray,
        duration: float,
        dt: float | None = None,
        fit_error: float | None = None,
    ) -> None:
        # Internal: arguments are already checked; use the from_* constructors.
        weights = frozen(weights)
        init = object.__setattr__
        init(self, "degree", int(degree))
        init(self, "knots", frozen(knots))
        init(self, "ctrlpts", frozen(ctrlpts))
        init(self, "weights", weights)
        init(self, "duration", float(duration))
        init(self, "dim", int(self.ctrlpts.shape[1]))
        init(self, "dt", None if dt is None else float(dt))
        init(self, "fit_error", None if fit_error is None else float(fit_error))
        init(self, "rational", bool(np.any(weights != weights[0])))
        init(self, "_cache", {})

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"Trajectory is immutable: cannot set {name!r}")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"Trajectory is immutable: cannot delete {name!r}")

    def __reduce__(self):
        # __setattr__ is closed, so pickle and copy rebuild through the constructor
        return (
            Trajectory,
            (
                self.degree,
                self.knots,
                self.ctrlpts,
                self.weights,
                self.duration,
                self.dt,
                self.fit_error,
            ),
        )

    def __repr__(self) -> str:
        kind = "rational" if self.rational else "non-rational"
        return (
            f"Trajectory(dim={self.dim}, duration={self.duration:g} s, degree={self.degree}, "
            f"ctrlpts={self.n_ctrlpts}, {kind})"
        )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_samples(
        cls,
        points: Any,
        dt: float,
        tol: float | None = None,
        degree: int = 3,
        *,
        n_ctrlpts: int | None = None,
    ) -> Trajectory:
        """Fit uniformly timed samples; the number of control points is chosen automatically.

        Parameters
        ----------
        points : array, shape (n, d)
            Samples at t = 0, dt, ..., (n - 1) dt; d = 2 or 3; n >= 8.
        dt : float
            Sample time in seconds, > 0. The duration is T = (n - 1) dt.
        tol : float, optional
            Largest allowed distance (Euclidean, user units) between the curve and any
            sample; default :data:`primlib.defaults.FIT_RTOL` (1e-4) times the samples'
            size: twice their largest distance from the centroid, which a rotation keeps
            (about the largest side of the bounding box, which it does not).
        degree : int, default 3
            Degree p of the curve.
        n_ctrlpts : int, optional
            Use exactly this many control points (p + 1 .. n) instead of searching.

        Returns
        -------
        Trajectory
            Non-rational (weights 1), clamped uniform knots; starts and ends exactly at the
            first and last sample. With m < n control points it is the least-squares fit
            with the smallest m found (within 5 %) whose error is below ``tol``; when none
            is, it interpolates every sample (m = n).

        Raises
        ------
        InputError
            points not (n, 2) or (n, 3), NaN, inf or a magnitude beyond
            :data:`primlib.defaults.MAX_ABS_VALUE`, n < 8, dt <= 0, tol <= 0, a degree
            that is not an integer in 1 .. n - 1, n_ctrlpts outside p + 1 .. n.
        """
        pts = points_of(points)
        dt = positive(dt, "dt", " of seconds")
        p = degree_of(degree)
        n = pts.shape[0]
        if n < MIN_SAMPLES:
            raise InputError(f"points: expected at least {MIN_SAMPLES} samples, got {n}")
        if p >= n:
            raise InputError(f"degree: expected an integer below the {n} samples, got {p}")
        if tol is None:
            # from the centroid, not the bounding box: a rotated copy is fitted the same way;
            # twice the radius keeps the old scale (a straight line's length)
            size = 2.0 * radius(pts)
            scale = size if size > 0 else max(1.0, float(np.abs(pts).max()))
            tol = DEFAULT_RTOL * scale
        else:
            tol = positive(tol, "tol", " (user units)")
        if n_ctrlpts is not None:
            if (
                isinstance(n_ctrlpts, bool)
                or not isinstance(n_ctrlpts, int | np.integer)
                or not p + 1 <= n_ctrlpts <= n
            ):
                raise InputError(
                    f"n_ctrlpts: expected an integer in {p + 1} .. {n}, got {n_ctrlpts!r}"
                )
            n_ctrlpts = int(n_ctrlpts)
        fit = fit_samples(pts, tol, p, n_ctrlpts)
        m = fit.ctrlpts.shape[0]
        return cls(p, fit.knots, fit.ctrlpts, np.ones(m), (n - 1) * dt, dt, fit.error)

    @classmethod
    def from_definition(
        cls,
        degree: int,
        knots: Any,
        ctrlpts: Any,
        weights: Any = None,
        duration: float = 1.0,
    ) -> Trajectory:
        """A trajectory from its NURBS definition (cheap: no geomdl, no fitting).

        Parameters
        ----------
        degree : int
            p >= 1.
        knots : array, shape (m + p + 1,)
            Non-decreasing, clamped (p + 1 equal knots at each end), interior multiplicity
            at most p. A knot vector on [a, b] is mapped affinely onto [0, 1].
        ctrlpts : array, shape (m, d)
            Cartesian control points, d = 2 or 3, m >= p + 1.
        weights : array, shape (m,), optional
            Positive weights; default all 1.
        duration : float
            T in seconds, > 0.

        Raises
        ------
        InputError
            For any shape or value that breaks the rules above.
        """
        p = degree_of(degree)
        ctrl = points_of(ctrlpts, "ctrlpts")
        m = ctrl.shape[0]
        if m < p + 1:
            raise InputError(f"ctrlpts: expected at least degree + 1 = {p + 1} points, got {m}")
        kv = clamped_knots(knots, m, p)
        if weights is None:
            w = np.ones(m)
        else:
            try:
                w = np.asarray(weights, dtype=np.float64)
            except (TypeError, ValueError):
                raise InputError("weights: expected a numeric array") from None
            if w.shape != (m,):
                raise InputError(f"weights: expected shape ({m},), got {w.shape}")
            if not (np.isfinite(w).all() and np.all(w > 0)):
                raise InputError("weights: expected positive finite values, got otherwise")
        T = positive(duration, "duration", " of seconds")
        return cls(p, kv, ctrl, w, T)

    @classmethod
    def from_nurbs(cls, curve: Any, duration: float) -> Trajectory:
        """A trajectory from a geomdl ``NURBS.Curve`` or ``BSpline.Curve``.

        Parameters
        ----------
        curve : geomdl curve
            Its parameter is taken as normalised time (a knot vector on [a, b] is mapped
            onto [0, 1]).
        duration : float
            T in seconds, > 0.
        """
        return cls.from_definition(**definition_from_geomdl(curve), duration=duration)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, tol: float | None = None, degree: int = 3):
        """Fit a path CSV file (header ``t,x,y`` or ``t,x,y,z``; see :meth:`from_samples`).

        The sample time is dt = t[-1] / (n - 1); the file is checked by
        :func:`primlib.io.read_path_csv`.
        """
        from primlib.io import read_path_csv

        t, points = read_path_csv(path)
        dt = float(t[-1]) / (t.shape[0] - 1)
        return cls.from_samples(points, dt, tol=tol, degree=degree)

    @classmethod
    def from_json(cls, path: str | os.PathLike, duration: float | None = None) -> Trajectory:
        """Read geomdl's JSON exchange format with the duration beside the curve.

        Parameters
        ----------
        path : str or path-like
            A file written by :meth:`to_json`, or by ``geomdl.exchange.export_json`` (one
            curve; then pass ``duration``).
        duration : float, optional
            Seconds; only used when the file has no ``"duration"``.
        """
        from primlib.io import read_path_json

        d = definition_from_exchange(read_path_json(path), str(path), duration)
        try:
            return cls.from_definition(**d)
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from None

    # ------------------------------------------------------------------ exchange
    def definition(self) -> dict:
        """dict(degree, knots (m+p+1,), ctrlpts (m, d), weights (m,), duration) — read-only."""
        return dict(
            degree=self.degree,
            knots=self.knots,
            ctrlpts=self.ctrlpts,
            weights=self.weights,
            duration=self.duration,
        )

    @property
    def nurbs(self):
        """The geomdl ``NURBS.Curve`` (parameter = normalised time), built on first use.

        It is a copy for exchange: changing it does not change this trajectory.
        """
        curve = self._cache.get("nurbs")
        if curve is None:
            curve = to_geomdl(self.degree, self.knots, self.ctrlpts, self.weights)
            self._cache["nurbs"] = curve
        return curve

    def to_json(self, path: str | os.PathLike) -> None:
        """Write geomdl's JSON exchange format with ``"duration"`` beside the shape."""
        from primlib.io import write_path_json

        write_path_json(
            path,
            exchange_dict(self.degree, self.knots, self.ctrlpts, self.weights, self.duration),
        )

    def to_csv(self, path: str | os.PathLike, dt: float) -> None:
        """Write the path sampled at t = 0, dt, ..., T (header ``t,x,y`` or ``t,x,y,z``)."""
        from primlib.io import write_path_csv

        write_path_csv(path, self.times(dt), self.sample(dt))

    # ------------------------------------------------------------------ properties
    @property
    def n_ctrlpts(self) -> int:
        """m, the number of control points."""
        return int(self.ctrlpts.shape[0])

    @property
    def extent(self) -> float:
        """Largest side of the path's bounding box (from 8 m + 1025 points along it)."""
        e = self._cache.get("extent")
        if e is None:
            e = float(np.ptp(self.at(np.linspace(0.0, 1.0, 8 * self.n_ctrlpts + 1025)), 0).max())
            self._cache["extent"] = e
        return e

    # ------------------------------------------------------------------ evaluation
    def _spline(self) -> BSpline:
        key = "spline"
        spl = self._cache.get(key)
        if spl is None:
            c = self.ctrlpts
            if self.rational:  # homogeneous coordinates (w P, w)
                c = np.column_stack([self.ctrlpts * self.weights[:, None], self.weights])
            spl = BSpline(self.knots, c, self.degree, extrapolate=True)
            self._cache[key] = spl
        return spl

    def _eval(self, v: np.ndarray, nu: int) -> np.ndarray:
        """nu-th v-derivative of the (homogeneous) spline; de Boor per span, so repeated
        interior knots are fine (``BSpline.derivative`` would refuse them)."""
        spl = self._spline()
        if nu > self.degree:
            return np.zeros(v.shape + (spl.c.shape[1],))
        return spl(v, nu=nu)

    def _params(self, v: Any, name: str = "v") -> np.ndarray:
        try:
            arr = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"{name}: expected normalised times in [0, 1]") from None
        if arr.ndim > 1:
            raise InputError(f"{name}: expected a scalar or shape (k,), got shape {arr.shape}")
        if arr.size and not (
            np.isfinite(arr).all() and arr.min() >= -V_SLACK and arr.max() <= 1.0 + V_SLACK
        ):
            bad = arr[~(np.isfinite(arr) & (arr >= -V_SLACK) & (arr <= 1.0 + V_SLACK))][0]
            raise InputError(f"{name}: expected normalised times in [0, 1], got {float(bad)!r}")
        return np.clip(arr, 0.0, 1.0)

    def _derivatives(self, v: np.ndarray, order: int) -> list[np.ndarray]:
        """[C, C', C''][: order + 1] with respect to v at parameters v (k,)."""
        d = self.dim
        raw = [self._eval(v, k) for k in range(order + 1)]
        if not self.rational:
            out = raw
        else:
            out = self._quotient(raw, d, order)
        # A clamped curve starts and ends exactly on its end control points; say so exactly
        # rather than through a basis that sums to 1 only up to rounding.
        out[0][v == 0.0] = self.ctrlpts[0]
        out[0][v == 1.0] = self.ctrlpts[-1]
        return out

    @staticmethod
    def _quotient(raw: list[np.ndarray], d: int, order: int) -> list[np.ndarray]:
        # Quotient rule on C = A / W (homogeneous A = sum N w P, W = sum N w):
        # C' = (A' - W' C) / W, C'' = (A'' - 2 W' C' - W'' C) / W  (The NURBS Book, eq. 4.8)
        A = [r[..., :d] for r in raw]
        W = [r[..., d:] for r in raw]
        out = [A[0] / W[0]]
        if order >= 1:
            out.append((A[1] - W[1] * out[0]) / W[0])
        if order >= 2:
            out.append((A[2] - 2.0 * W[1] * out[1] - W[2] * out[0]) / W[0])
        return out

    def at(self, v: Any) -> np.ndarray:
        """Positions at normalised times.

        Parameters
        ----------
        v : float or array, shape (k,)
            Normalised times in [0, 1] (1e-12 slack for rounding).

        Returns
        -------
        array, shape (k, d) (or (d,) for a scalar v)
        """
        return self._derivatives(self._params(v), 0)[0]

    def velocity(self, v: Any) -> np.ndarray:
        """dC/dt = (dC/dv) / T at normalised times v; shape (k, d), user units per second."""
        return self._derivatives(self._params(v), 1)[1] / self.duration

    def acceleration(self, v: Any) -> np.ndarray:
        """d2C/dt2 = (d2C/dv2) / T^2 at normalised times v; shape (k, d), units per s^2."""
        return self._derivatives(self._params(v), 2)[2] / self.duration**2

    def _count(self, dt: Any) -> int:
        dt = positive(dt, "dt", " of seconds")
        steps = round(self.duration / dt)
        if steps < 1 or abs(steps * dt - self.duration) > DT_RTOL * dt:
            raise InputError(
                f"dt: expected a step that divides the duration T = {self.duration!r} s, "
                f"got dt = {dt!r} s (T / dt = {self.duration / dt:.9g})"
            )
        return steps + 1

    def times(self, dt: float) -> np.ndarray:
        """t = i dt, i = 0 .. n - 1, n = round(T / dt) + 1; shape (n,).

        Raises
        ------
        InputError
            If dt <= 0 or T is not a whole multiple of dt (within 1e-6 dt).
        """
        return np.arange(self._count(dt)) * float(dt)

    def sample(self, dt: float) -> np.ndarray:
        """Positions at t = 0, dt, ..., T; shape (round(T / dt) + 1, d).

        The normalised times are i / (n - 1), so the first and last rows are exactly C(0)
        and C(1).
        """
        n = self._count(dt)
        return self._derivatives(np.arange(n) / (n - 1), 0)[0]

    # ------------------------------------------------------------------ sub-curves
    def segment(self, v0: float, v1: float) -> Trajectory:
        """The exact sub-curve between normalised times v0 < v1, reparametrised to [0, 1].

        Knots v0 and v1 are inserted (Boehm) up to multiplicity p, which leaves the curve
        unchanged; the control points between them define the piece. Its duration is
        (v1 - v0) T, so ``seg.at(s) == self.at(v0 + (v1 - v0) s)`` and velocities agree.

        Parameters
        ----------
        v0, v1 : float
            0 <= v0 < v1 <= 1.

        Returns
        -------
        Trajectory
            Same degree and weights regime; duration (v1 - v0) T.

        Raises
        ------
        InputError
            If v0 or v1 is outside [0, 1] or v0 >= v1.
        """
        a = float(self._params(v0, "v0"))
        b = float(self._params(v1, "v1"))
        if not a < b:
            raise InputError(f"v0, v1: expected v0 < v1, got v0 = {a!r}, v1 = {b!r}")
        p = self.degree
        kv = np.array(self.knots)
        ctrl = (
            np.column_stack([self.ctrlpts * self.weights[:, None], self.weights])
            if self.rational
            else np.array(self.ctrlpts)
        )
        for u in (a, b):
            if 0.0 < u < 1.0:
                kv, ctrl = insert_knot(kv, ctrl, p, u, max(0, p - multiplicity(kv, u)))
        first = int(np.searchsorted(kv, a, side="right")) - 1 - p
        between = kv[(kv > a) & (kv < b)]
        sub_kv = np.concatenate([np.zeros(p + 1), (between - a) / (b - a), np.ones(p + 1)])
        m = sub_kv.shape[0] - p - 1
        sub = ctrl[first : first + m]
        if self.rational:
            w = sub[:, -1]
            pts = sub[:, :-1] / w[:, None]
        else:
            w, pts = np.ones(m), sub
        return Trajectory(p, sub_kv, pts, w, (b - a) * self.duration)

    # ------------------------------------------------------------------ exact transforms
    def with_duration(self, duration: float) -> Trajectory:
        """The same curve traversed in ``duration`` seconds (velocities scale by T / duration).

        Raises
        ------
        InputError
            If duration is not a positive finite number.
        """
        T = positive(duration, "duration", " of seconds")
        return Trajectory(self.degree, self.knots, self.ctrlpts, self.weights, T)

    def transformed(self, rotation: Any = None, translation: Any = None) -> Trajectory:
        """The path moved rigidly (or by any linear map): C'(v) = R C(v) + b, exactly.

        NURBS are invariant under affine maps: transforming the control points transforms the
        curve (The NURBS Book, sec. 4.2), so the result is exact and keeps the weights.

        Parameters
        ----------
        rotation : array, shape (d, d), optional
            R (identity when omitted); any matrix is accepted, a rotation keeps shapes.
        translation : array, shape (d,), optional
            b (zero when omitted).

        Raises
        ------
        InputError
            If R is not (d, d) or b not (d,), or either is not finite.
        """
        d = self.dim
        R = np.eye(d) if rotation is None else np.asarray(rotation, dtype=np.float64)
        b = np.zeros(d) if translation is None else np.asarray(translation, dtype=np.float64)
        if R.shape != (d, d) or not np.isfinite(R).all():
            raise InputError(f"rotation: expected a finite ({d}, {d}) matrix, got {R.shape}")
        if b.shape != (d,) or not np.isfinite(b).all():
            raise InputError(f"translation: expected a finite ({d},) vector, got {b.shape}")
        return Trajectory(
            self.degree, self.knots, self.ctrlpts @ R.T + b, self.weights, self.duration, self.dt
        )
