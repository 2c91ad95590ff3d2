"""Linear, circular and exact contour-error estimators, vectorised over points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError
from primlib.contour._curve import Curve, _check_points, as_curve, check_times

__all__ = [
    "METHODS",
    "ContourEstimate",
    "ContourEstimator",
    "contour_error",
    "brute_force_contour_error",
]

METHODS = ("linear", "circular", "exact")

_CHUNK = 1 << 21  # points x candidate segments per block of the coarse search


@dataclass(frozen=True)
class ContourEstimate:
    """Result of a contour-error estimate for m points.

    Attributes
    ----------
    error : array, shape (m,)
        Contour error; 2-D: signed, positive to the left of the direction of travel; 3-D:
        the unsigned distance.
    normal : array, shape (m, d)
        Unit vector with ``p ~ foot + error * normal``: in 2-D the left normal of the path at
        the point the estimate refers to (the reference point for linear/circular, the
        closest point for exact); in 3-D the direction from the path to ``p`` (0 where p is
        on the path). A cross-coupled controller corrects along ``-error * normal``.
    param : array, shape (m,)
        Path time (seconds) of that point: the reference time, or ``s*`` of the closest
        point for the exact method.
    """

    error: np.ndarray
    normal: np.ndarray
    param: np.ndarray


def _left_normal(tau: np.ndarray) -> np.ndarray:
    return np.stack([-tau[:, 1], tau[:, 0]], axis=1)


class ContourEstimator:
    """Contour-error estimator bound to one path (build once, call every control step).

    Parameters
    ----------
    path : Trajectory or array, shape (n, d)
        The path, or reference samples on the grid ``t`` (then a cubic spline in time).
    t : array, shape (n,), optional
        The sample grid (required for samples, ignored for a Trajectory).
    method : {"exact", "linear", "circular"}
        See :mod:`primlib.contour`.
    nodes : int, optional
        Polyline nodes for the coarse search of the exact method.
    window : float
        Half-width of the exact method's search window along the path, in multiples of the
        tracking error ``|p - r(t)|`` (plus two polyline nodes each side). The closest point
        is within ``2 |p - r(t)|`` of ``r(t)`` in chord, so 4 leaves room for curvature; a
        larger value lets the search reach further branches of a self-crossing path.

    Raises
    ------
    InputError
        Unknown method, bad path samples or grid.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 2 * np.pi, 400)
    >>> ref = np.c_[10 * np.sin(t), 5 * np.cos(t)]
    >>> est = ContourEstimator(ref, t, method="exact")
    >>> e = est(t, ref * 1.01).error   # outside a clockwise ellipse = left of travel
    >>> bool(np.all(e > 0))
    True
    """

    def __init__(self, path, t=None, *, method: str = "exact", nodes=None, window=4.0):
        if method not in METHODS:
            raise InputError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
        if not (np.isfinite(window) and window > 0):
            raise InputError(f"window: expected a positive number, got {window}")
        if t is None and not hasattr(path, "at"):
            raise InputError("t: expected the time grid of the path samples, got None")
        self.method = method
        self.window = float(window)
        self.curve: Curve = as_curve(path, t, nodes)

    @property
    def dim(self) -> int:
        return self.curve.dim

    def __call__(self, t, actual) -> ContourEstimate:
        """Estimate the contour error of ``actual`` positions at reference times ``t``.

        Parameters
        ----------
        t : array, shape (m,)
            Reference times (seconds), clipped to the path's time span.
        actual : array, shape (m, d)
            Actual positions, in the path's coordinates.

        Returns
        -------
        ContourEstimate
        """
        p = _check_points("actual", actual)
        if p.shape[1] != self.dim:
            raise InputError(f"actual: expected {self.dim} columns like the path, got {p.shape[1]}")
        s = self.curve.clip(check_times(t, p.shape[0]))
        if self.method == "exact":
            return self._exact(s, p)
        r, v = self.curve.pos(s), self.curve.vel(s)
        tau, ok = self.curve.tangent(s, v)
        d = p - r
        if self.method == "linear":
            return self._linear(s, d, tau, ok)
        return self._circular(s, d, v, tau, ok)

    # -- linear and circular ---------------------------------------------------------------

    def _linear(self, s, d, tau, ok) -> ContourEstimate:
        if self.dim == 2:
            nrm = _left_normal(tau)
            e = np.einsum("ij,ij->i", nrm, d)  # cross(T, d): left of travel positive
            # nowhere-moving path: the distance itself, along the error
            e, nrm = _stationary(e, nrm, d, ok)
            return ContourEstimate(e, nrm, s)
        perp = d - np.einsum("ij,ij->i", tau, d)[:, None] * tau
        e = np.linalg.norm(perp, axis=1)
        return ContourEstimate(e, _unit(perp, e), s)

    def _circular(self, s, d, v, tau, ok) -> ContourEstimate:
        c = self.curve
        acc = c.acc(s)
        speed = np.linalg.norm(v, axis=1)
        moving = (speed > c.speed_floor) & ok
        sp = np.where(moving, speed, 1.0)
        a = np.einsum("ij,ij->i", tau, d)
        if self.dim == 2:
            nrm = _left_normal(tau)
            cross = v[:, 0] * acc[:, 1] - v[:, 1] * acc[:, 0]
            kappa = np.where(moving, cross / sp**3, 0.0)  # signed, > 0 turning left
            b = np.einsum("ij,ij->i", nrm, d)
            e = _circle_distance(kappa, a, b)
            e, nrm = _stationary(e, nrm, d, ok)
            return ContourEstimate(e, nrm, s)
        # 3-D: osculating plane spanned by T and the principal normal N
        an = acc - np.einsum("ij,ij->i", acc, tau)[:, None] * tau
        kvec = np.where(moving[:, None], an / sp[:, None] ** 2, 0.0)
        kappa = np.linalg.norm(kvec, axis=1)
        perp = d - a[:, None] * tau
        big = kappa > 0
        nvec = np.where(big[:, None], kvec / np.where(big, kappa, 1.0)[:, None], 0.0)
        b = np.einsum("ij,ij->i", nvec, perp)
        c2 = np.maximum(np.einsum("ij,ij->i", perp, perp) - b**2, 0.0)
        e_plane = _circle_distance(kappa, a, b)
        e = np.sqrt(e_plane**2 + c2)
        pn = np.linalg.norm(perp, axis=1)
        return ContourEstimate(e, _unit(perp, pn), s)

    # -- exact -----------------------------------------------------------------------------

    def _exact(self, s, p) -> ContourEstimate:
        c = self.curve
        s_star = self._closest(s, p)
        r = c.pos(s_star)
        d = p - r
        dist = np.linalg.norm(d, axis=1)
        if self.dim == 3:
            return ContourEstimate(dist, _unit(d, dist), s_star)
        tau, ok = c.tangent(s_star)
        nrm = _left_normal(tau)
        side = np.einsum("ij,ij->i", nrm, d)
        e = np.where(side < 0, -dist, dist)
        e, nrm = _stationary(e, nrm, d, ok)
        return ContourEstimate(e, nrm, s_star)

    def _closest(self, s: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Path time of the closest point to each ``p`` near the reference time ``s``.

        The search window is the arc ``|arc - arc(s)| <= window |p - r(s)|``. Where it runs
        past an end of the path and the path's other end lies within that reach of this one
        (a closed contour, or one that nearly closes), the window continues from the other
        end: the closest point on the curve may lie on the branch that arrives there.
        """
        c = self.curve
        nn = c.node_s.size
        delta = np.linalg.norm(p - c.pos(s), axis=1)
        arc0 = np.interp(s, c.node_s, c.cum)
        reach = self.window * delta
        jnode = _nearest_node(c, p, arc0 - reach, arc0 + reach)
        length = c.cum[-1]
        gap = float(np.linalg.norm(c.node_p[-1] - c.node_p[0]))
        closes = gap <= reach
        for wrap, a0, a1 in (
            (closes & (arc0 - reach < 0), length - (reach - arc0), np.full_like(arc0, length)),
            (closes & (arc0 + reach > length), np.zeros_like(arc0), arc0 + reach - length),
        ):
            rows = np.flatnonzero(wrap)
            if rows.size:
                other = _nearest_node(c, p[rows], a0[rows], a1[rows])
                d_own = np.linalg.norm(c.node_p[jnode[rows]] - p[rows], axis=1)
                d_other = np.linalg.norm(c.node_p[other] - p[rows], axis=1)
                jnode[rows] = np.where(d_other < d_own, other, jnode[rows])
        seg_pick = np.stack([np.maximum(jnode - 1, 0), np.minimum(jnode, nn - 2)], axis=1)
        return _refine(c, p, seg_pick)


def _nearest_node(c: Curve, p: np.ndarray, arc_lo, arc_hi) -> np.ndarray:
    """Index of the polyline node nearest to each point within its arc-length window
    (widened by two nodes each side), searched in blocks of equal width."""
    m = p.shape[0]
    nn = c.node_s.size
    lo = np.clip(np.searchsorted(c.cum, arc_lo, side="left") - 2, 0, nn - 2)
    hi = np.clip(np.searchsorted(c.cum, arc_hi, side="right") + 2, lo + 1, nn - 1)
    nseg = hi - lo
    jnode = np.empty(m, dtype=np.intp)
    width = 1 << np.ceil(np.log2(nseg + 1)).astype(int)
    cols = [np.ascontiguousarray(c.node_p[:, k]) for k in range(c.dim)]
    for k in np.unique(width):
        rows = np.flatnonzero(width == k)
        step = max(1, _CHUNK // int(k))
        for i0 in range(0, rows.size, step):
            rr = rows[i0 : i0 + step]
            j = np.minimum(lo[rr, None] + np.arange(k), hi[rr, None])
            d2 = (cols[0][j] - p[rr, 0, None]) ** 2
            for ax in range(1, c.dim):
                d2 += (cols[ax][j] - p[rr, ax, None]) ** 2
            jnode[rr] = j[np.arange(rr.size), np.argmin(d2, axis=1)]
    return jnode


def _refine(c: Curve, p: np.ndarray, seg_pick: np.ndarray) -> np.ndarray:
    """The nearer of each point's two candidate segments, then Newton on the curve."""
    m = p.shape[0]
    nn = c.node_s.size
    a = c.node_p[seg_pick]
    sv = c.seg[seg_pick]
    l2 = c.seg_len2[seg_pick]
    q = p[:, None, :] - a
    w = np.clip(np.einsum("ijk,ijk->ij", q, sv) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
    diff = q - w[..., None] * sv
    kk = np.argmin(np.einsum("ijk,ijk->ij", diff, diff), axis=1)
    jbest = seg_pick[np.arange(m), kk]
    wbest = w[np.arange(m), kk]
    ns = c.node_s
    s_init = ns[jbest] + wbest * (ns[jbest + 1] - ns[jbest])
    blo = ns[np.maximum(jbest - 1, 0)]
    bhi = ns[np.minimum(jbest + 2, nn - 1)]
    s_newton = _safeguarded_newton(c, p, s_init, blo, bhi)
    # keep the best of Newton, the coarse estimate and the bracket ends: never worse
    # than the polyline search, whatever the curve does inside the bracket
    cand = np.stack([s_newton, s_init, blo, bhi], axis=1)
    pts = c.pos(cand.ravel()).reshape(m, 4, -1)
    d2 = np.einsum("ijk,ijk->ij", pts - p[:, None], pts - p[:, None])
    return cand[np.arange(m), np.argmin(d2, axis=1)]


def _safeguarded_newton(c: Curve, p, s, lo, hi, iterations: int = 60) -> np.ndarray:
    """Minimise ``g(s) = |r(s) - p|^2 / 2`` in ``[lo, hi]``: Newton on ``g'`` with bisection.

    ``g' = (r - p) . r'``, ``g'' = |r'|^2 + (r - p) . r''``. Where ``g'`` does not change sign
    over the bracket the start value is returned (the caller compares with the ends).
    """
    s = s.copy()
    lo, hi = lo.copy(), hi.copy()

    def g12(ss, pp):
        r, r1, r2 = c.pos(ss), c.vel(ss), c.acc(ss)
        d = r - pp
        return np.einsum("ij,ij->i", d, r1), np.einsum("ij,ij->i", r1, r1) + np.einsum(
            "ij,ij->i", d, r2
        )

    g_lo, _ = g12(lo, p)
    g_hi, _ = g12(hi, p)
    active = np.flatnonzero((g_lo < 0) & (g_hi > 0))
    tol = 1e-13 * (c.s1 - c.s0)
    s[active] = np.clip(s[active], lo[active], hi[active])
    for _ in range(iterations):
        if active.size == 0:
            break
        sa, la, ha = s[active], lo[active], hi[active]
        g1, g2 = g12(sa, p[active])
        neg = g1 < 0
        la = np.where(neg, sa, la)
        ha = np.where(neg, ha, sa)
        convex = g2 > 0
        step = np.where(convex, g1 / np.where(convex, g2, 1.0), 0.0)
        newton = sa - step
        # a Newton step below the tolerance is convergence even when rounding puts it on
        # the bracket end; outside the bracket or on a concave stretch: bisect
        conv = convex & (np.abs(step) <= tol)
        bad = ~convex | ~(newton > la) | ~(newton < ha)
        s_new = np.where(conv, newton, np.where(bad, 0.5 * (la + ha), newton))
        done = conv | (ha - la <= tol) | (g1 == 0)
        s[active], lo[active], hi[active] = np.where(g1 == 0, sa, s_new), la, ha
        active = active[~done]
    return s


def _circle_distance(kappa, a, b):
    """Signed distance (toward the centre positive) from a point to a circle of curvature
    ``kappa`` through the origin with tangent ``(1, 0)`` and centre at ``(0, 1/kappa)``.

    ``e = sign(k)(R - |p - c|) = (2b - k(a^2 + b^2)) / (1 + sqrt((k a)^2 + (1 - k b)^2))``,
    exact, finite for every ``kappa`` (0: ``e = b``, the linear estimate). Its second-order
    expansion ``b - k a^2 / 2`` is the circular estimate of eq. (5), CEE-MFAC paper; the
    paper prints the quadratic terms as ``(e_x^2 + e_y^2)/(2R)``, which is not the expansion
    of the distance to the osculating circle, so we use the exact form.
    """
    return (2.0 * b - kappa * (a * a + b * b)) / (
        1.0 + np.sqrt((kappa * a) ** 2 + (1.0 - kappa * b) ** 2)
    )


def _unit(v, norm):
    ok = norm > 0
    return np.where(ok[:, None], v / np.where(ok, norm, 1.0)[:, None], 0.0)


def _stationary(e, nrm, d, ok):
    """Where the path has no direction at all (it does not move): distance, along d."""
    if np.all(ok):
        return e, nrm
    dist = np.linalg.norm(d, axis=1)
    e = np.where(ok, e, dist)
    nrm = np.where(ok[:, None], nrm, _unit(d, dist))
    return e, nrm


def contour_error(path, t, actual, method: str = "exact", **kwargs) -> np.ndarray:
    """Contour error of actual positions against a path.

    Parameters
    ----------
    path : Trajectory or array, shape (n, d)
        The path: a Trajectory (``at``, ``velocity``, ``acceleration``, ``duration``), or the
        reference samples on the grid ``t``, treated as a cubic spline in time.
    t : array, shape (n,)
        Times in seconds of the actual positions (for samples, also their grid).
    actual : array, shape (n, d)
        Actual positions in the path's coordinates (add the start point to the output of
        ``Machine.simulate``, which is relative to it).
    method : {"exact", "linear", "circular"}
        Closest point on the path near the reference point; distance to the tangent line;
        distance to the osculating circle at the reference point.
    **kwargs
        ``nodes`` and ``window``, see :class:`ContourEstimator`.

    Returns
    -------
    array, shape (n,)
        2-D: signed, positive to the left of the direction of travel; 3-D: unsigned.

    Raises
    ------
    InputError
        Unknown method, shapes that disagree, NaN or inf, a sample grid not increasing.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 11)
    >>> ref = np.c_[t, 0 * t]                       # along +x
    >>> contour_error(ref, t, ref + [0.0, 0.1], "linear")[:3]
    array([0.1, 0.1, 0.1])
    """
    return ContourEstimator(path, t, method=method, **kwargs)(t, actual).error


def brute_force_contour_error(path, t, actual, samples: int = 200_000) -> np.ndarray:
    """Reference implementation: the globally closest point by dense sampling, refined.

    The path is sampled at ``samples`` uniform times; for each point the nearest sample is
    found by exhaustive search, then 2001 samples across the two neighbouring intervals
    pick the refined closest point. The sign (2-D) is taken as in :func:`contour_error`.
    Slow by design (``O(n * samples)``), for tests and benchmarks.

    Returns
    -------
    array, shape (n,)
    """
    p = _check_points("actual", actual)
    c = as_curve(path, t, nodes=16)
    t = check_times(t, p.shape[0])
    ss = np.linspace(c.s0, c.s1, samples)
    q = c.pos(ss)
    q2 = np.einsum("ij,ij->i", q, q)
    h = ss[1] - ss[0]
    best = np.empty(p.shape[0])
    block = max(1, (1 << 24) // samples)
    for i0 in range(0, p.shape[0], block):
        pb = p[i0 : i0 + block]
        d2 = q2[None, :] - 2.0 * pb @ q.T
        k = np.argmin(d2, axis=1)
        fine = ss[k, None] + np.linspace(-h, h, 2001)[None, :]
        qf = c.pos(fine.ravel()).reshape(pb.shape[0], 2001, -1)
        df = np.einsum("ijk,ijk->ij", qf - pb[:, None], qf - pb[:, None])
        best[i0 : i0 + block] = c.clip(fine[np.arange(pb.shape[0]), np.argmin(df, axis=1)])
    r = c.pos(best)
    d = p - r
    dist = np.linalg.norm(d, axis=1)
    if c.dim == 3:
        return dist
    tau, _ = c.tangent(best)
    side = tau[:, 0] * d[:, 1] - tau[:, 1] * d[:, 0]
    return np.where(side < 0, -dist, dist)
