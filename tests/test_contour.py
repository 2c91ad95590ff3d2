from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from primlib import InputError
from primlib.contour import (
    METHODS,
    ContourEstimator,
    brute_force_contour_error,
    contour_error,
    ellipse_closest_point,
    ellipse_contour_error,
)

ROOT = Path(__file__).resolve().parents[1]


class Analytic:
    """A Trajectory-like analytic curve: f(s), f'(s), f''(s) on [0, T], v = s / T."""

    def __init__(self, f, df, ddf, duration):
        self.f, self.df, self.ddf, self.duration = f, df, ddf, float(duration)

    def at(self, v):
        return self.f(np.asarray(v) * self.duration)

    def velocity(self, v):
        return self.df(np.asarray(v) * self.duration)

    def acceleration(self, v):
        return self.ddf(np.asarray(v) * self.duration)


def ellipse(ax=10.0, by=5.0):
    # the paper's ellipse x = 10 sin t, y = 5 cos t: clockwise, left of travel = outside
    return Analytic(
        lambda s: np.c_[ax * np.sin(s), by * np.cos(s)],
        lambda s: np.c_[ax * np.cos(s), -by * np.sin(s)],
        lambda s: np.c_[-ax * np.sin(s), -by * np.cos(s)],
        2 * np.pi,
    )


def circle_ccw(radius=3.0):
    return Analytic(
        lambda s: radius * np.c_[np.cos(s), np.sin(s)],
        lambda s: radius * np.c_[-np.sin(s), np.cos(s)],
        lambda s: -radius * np.c_[np.cos(s), np.sin(s)],
        2 * np.pi,
    )


def helix():
    return Analytic(
        lambda s: np.c_[2 * np.cos(s), 2 * np.sin(s), 0.5 * s],
        lambda s: np.c_[-2 * np.sin(s), 2 * np.cos(s), 0.5 + 0 * s],
        lambda s: np.c_[-2 * np.cos(s), -2 * np.sin(s), 0 * s],
        4.0,
    )


def lissajous_samples(n=2001):
    t = np.linspace(0.0, 2.5, n)
    return t, np.c_[4 * np.sin(1.3 * t) + t, 3 * np.sin(2.1 * t + 0.4)]


@pytest.mark.parametrize("form", ["trajectory", "samples"])
def test_exact_matches_paper_quartic_on_the_ellipse(form):
    rng = np.random.default_rng(0)
    t = np.linspace(0.1, 2 * np.pi - 0.1, 4000)  # ends excluded: the path is open in time
    path = ellipse()
    ref = path.at(t / path.duration)
    actual = ref + rng.normal(scale=0.2, size=ref.shape)
    if form == "trajectory":
        e = contour_error(path, t, actual)
    else:
        tg = np.linspace(0, 2 * np.pi, 4001)
        # the reference samples on their own grid; the spline through them is 1e-11 off
        e = ContourEstimator(path.at(tg / path.duration), tg)(t, actual).error
    expected = ellipse_contour_error(10, 5, actual)
    np.testing.assert_allclose(e, expected, atol=1e-9)


def test_quartic_closest_point_is_on_the_ellipse_and_normal():
    rng = np.random.default_rng(1)
    p = rng.uniform(-14, 14, size=(200, 2))
    p[:5, 0] = 0.0  # on an axis: the degenerate root x_E = 0
    p[5:10, 1] = 0.0
    e = ellipse_closest_point(10, 5, p)
    np.testing.assert_allclose((e[:, 0] / 10) ** 2 + (e[:, 1] / 5) ** 2, 1.0, atol=1e-12)
    brute = brute_force_contour_error(ellipse(), np.zeros(len(p)), p, samples=50_000)
    dist = np.linalg.norm(p - e, axis=1)
    # the quartic finds the global minimum: never farther than the dense search
    assert np.all(dist <= np.abs(brute) + 1e-9)
    np.testing.assert_allclose(dist, np.abs(brute), atol=1e-7)


def test_exact_matches_brute_force_on_sampled_curve():
    t, ref = lissajous_samples()
    rng = np.random.default_rng(2)
    actual = ref + rng.normal(scale=0.05, size=ref.shape)
    e = contour_error(ref, t, actual)[::4]
    # the same spline as a Trajectory-like path, so the slow search runs on a subset
    spline = CubicSpline(t, ref, axis=0)
    path = Analytic(spline, lambda s: spline(s, 1), lambda s: spline(s, 2), t[-1])
    bf = brute_force_contour_error(path, t[::4], actual[::4], samples=50_000)
    inner = slice(5, -5)  # at the open ends the closest point is the end point in both
    extent = np.ptp(ref, axis=0).max()
    np.testing.assert_allclose(e[inner], bf[inner], atol=1e-6 * extent)


def test_exact_3d_helix_is_unsigned_distance():
    path = helix()
    rng = np.random.default_rng(3)
    t = np.linspace(0.2, 3.8, 200)
    ref = path.at(t / path.duration)
    actual = ref + rng.normal(scale=0.1, size=ref.shape)
    est = ContourEstimator(path, method="exact")(t, actual)
    bf = brute_force_contour_error(path, t, actual, samples=50_000)
    np.testing.assert_allclose(est.error, bf, atol=1e-7)
    assert np.all(est.error >= 0)
    # p = foot + e * normal with the foot on the path at param
    foot = path.at(est.param / path.duration)
    np.testing.assert_allclose(foot + est.error[:, None] * est.normal, actual, atol=1e-12)


@pytest.mark.parametrize("method", METHODS)
def test_sign_left_of_travel_positive(method):
    path = circle_ccw(3.0)  # counter-clockwise: the inside is on the left
    t = np.linspace(0.5, 5.5, 50)
    ref = path.at(t / path.duration)
    inside = contour_error(path, t, 0.99 * ref, method)
    outside = contour_error(path, t, 1.01 * ref, method)
    # on the circle itself the circular and exact estimates are exactly |p| - R, mirrored
    np.testing.assert_allclose(inside, 0.03, rtol=1e-9 if method != "linear" else 1e-12)
    np.testing.assert_allclose(outside, -0.03, rtol=1e-9 if method != "linear" else 1e-12)


def test_circular_is_exact_on_a_circle_with_lag():
    path = circle_ccw(3.0)
    t = np.linspace(0.5, 5.5, 100)
    rng = np.random.default_rng(4)
    lagged = path.at((t - 0.05) / path.duration)  # on the path, behind the reference
    radial = 1 + rng.uniform(-0.02, 0.02, t.size)
    actual = lagged * radial[:, None]
    want = 3.0 * (1 - radial)  # left (inside) positive
    for method in ("circular", "exact"):
        np.testing.assert_allclose(contour_error(path, t, actual, method), want, atol=1e-9)
    # the linear estimate sees the lag: error ~ R (1 - cos(lag angle)), second order
    lin = contour_error(path, t, actual, "linear")
    assert np.max(np.abs(lin - want)) > 1e-3


def test_estimates_agree_to_second_order():
    path = ellipse()
    t = np.linspace(0.3, 6.0, 200)
    ref = path.at(t / path.duration)
    for scale in (1e-2, 1e-3):
        rng = np.random.default_rng(5)
        actual = ref + scale * rng.normal(size=ref.shape)
        ex = contour_error(path, t, actual)
        lin = contour_error(path, t, actual, "linear")
        cir = contour_error(path, t, actual, "circular")
        # linear misses the curvature term k a^2 / 2 (|k| <= 10/25 on this ellipse);
        # circular misses only third-order terms
        assert np.max(np.abs(lin - ex)) <= 0.4 * (4 * scale) ** 2
        assert np.max(np.abs(cir - ex)) <= 50 * scale**3


@pytest.mark.parametrize("method", METHODS)
def test_zero_error_on_the_reference(method):
    t, ref = lissajous_samples(801)
    np.testing.assert_allclose(contour_error(ref, t, ref, method), 0.0, atol=1e-12)


def test_cusp_and_stop_are_finite():
    # (s^2, s^3) has a cusp (zero speed) at s = 0; samples with a dwell at both ends
    s = np.linspace(-1, 1, 401)
    ref = np.c_[s**2, s**3]
    t = np.linspace(0, 2, 401)
    rng = np.random.default_rng(6)
    actual = ref + rng.normal(scale=0.01, size=ref.shape)
    for method in METHODS:
        e = contour_error(ref, t, actual, method)
        assert np.all(np.isfinite(e))
    ex = contour_error(ref, t, actual)
    bf = brute_force_contour_error(ref, t, actual, samples=40_000)
    # the search window (4 |p - r| of arc) keeps to the local branch; within 0.1 of the cusp
    # the other branch folds back closer than that arc, the global closest point may be there
    far = np.abs(s) > 0.4
    np.testing.assert_allclose(ex[far], bf[far], atol=1e-6)
    assert np.all(np.abs(ex) >= np.abs(bf) - 1e-9)
    # a window of the whole path finds the global closest point everywhere
    wide = contour_error(ref, t, actual, window=1e6)
    np.testing.assert_allclose(np.abs(wide), np.abs(bf), atol=1e-6)
    dwell = np.r_[np.zeros((50, 2)), np.c_[np.linspace(0, 1, 100), np.zeros(100)]]
    td = np.arange(150) * 0.01
    for method in METHODS:
        e = contour_error(dwell, td, dwell + [0.0, 0.02], method)
        assert np.all(np.isfinite(e))
        # at rest before the move the tangent is the outgoing chord: still 0.02 to the left
        np.testing.assert_allclose(e[60:-5], 0.02, atol=1e-9)


def test_stationary_path_gives_distance():
    t = np.linspace(0, 1, 20)
    ref = np.tile([1.0, 2.0], (20, 1))
    actual = ref + [0.3, 0.4]
    for method in METHODS:
        np.testing.assert_allclose(contour_error(ref, t, actual, method), 0.5, atol=1e-12)


def test_self_intersection_keeps_the_local_branch():
    # figure eight through the origin at s = 0 and s = pi; horizontal branch at s = 0 goes
    # up-right, the other down-right: a point just above the crossing is left of the
    # first branch (it would be on the right side of the second)
    tt = np.linspace(-np.pi / 2, 3 * np.pi / 2, 4001)
    ref = np.c_[np.sin(tt), np.sin(tt) * np.cos(tt)]
    k = np.argmin(np.abs(tt))
    p = ref[k] + np.array([[-0.01, 0.01]]) / np.sqrt(2)
    e = ContourEstimator(ref, tt)(tt[[k]], p)
    assert np.isfinite(e.error[0]) and e.error[0] > 0
    np.testing.assert_allclose(abs(e.error[0]), 0.01, rtol=1e-6)
    assert abs(e.param[0]) < 0.05  # stayed on the branch at s = 0, not the one at s = pi


def test_circular_straight_line_is_linear():
    t = np.linspace(0, 1, 50)
    ref = np.c_[3 * t, 4 * t]
    rng = np.random.default_rng(7)
    actual = ref + rng.normal(scale=0.1, size=ref.shape)
    lin = contour_error(ref, t, actual, "linear")
    np.testing.assert_allclose(contour_error(ref, t, actual, "circular"), lin, atol=1e-12)
    want = (3 * actual[:, 1] - 4 * actual[:, 0]) / 5
    np.testing.assert_allclose(lin, want, atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(
    angle=st.floats(-np.pi, np.pi),
    shift=st.tuples(st.floats(-100, 100), st.floats(-100, 100)),
    method=st.sampled_from(METHODS),
)
def test_invariant_under_rigid_motion(angle, shift, method):
    t, ref = lissajous_samples(601)
    rng = np.random.default_rng(8)
    actual = ref + rng.normal(scale=0.05, size=ref.shape)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    e0 = contour_error(ref, t, actual, method)
    e1 = contour_error(ref @ rot.T + shift, t, actual @ rot.T + shift, method)
    np.testing.assert_allclose(e1, e0, atol=1e-9)


def test_bad_input():
    t, ref = lissajous_samples(50)
    with pytest.raises(InputError, match="method: expected one of linear, circular, exact"):
        contour_error(ref, t, ref, "quartic")
    with pytest.raises(InputError, match=r"actual: expected an array of shape \(n, 2\)"):
        contour_error(ref, t, ref[:, 0])
    with pytest.raises(InputError, match="actual: expected finite values"):
        contour_error(ref, t, np.where(t[:, None] > 1, np.nan, ref))
    with pytest.raises(InputError, match="t: expected strictly increasing"):
        contour_error(ref, t[::-1], ref)
    with pytest.raises(InputError, match="t: expected 50 times"):
        contour_error(ref, t[:-1], ref)
    with pytest.raises(InputError, match="actual: expected 2 columns like the path, got 3"):
        ContourEstimator(ref, t)(t, np.c_[ref, t])
    with pytest.raises(InputError, match="t: expected the time grid"):
        ContourEstimator(ref)
    with pytest.raises(InputError, match="window: expected a positive number"):
        ContourEstimator(ref, t, window=0)
    with pytest.raises(InputError, match="path: expected at least 2 reference samples"):
        contour_error(ref[:1], t[:1], ref[:1])
    with pytest.raises(InputError, match="semi axes: expected an ellipse with unequal"):
        ellipse_contour_error(2, 2, ref)
    with pytest.raises(InputError, match="semi axes: expected two positive numbers"):
        ellipse_contour_error(-1, 2, ref)


@pytest.mark.parametrize("method", METHODS)
def test_nurbs_trajectory_path(method):
    from primlib.nurbs import Trajectory

    dt = 0.01
    t = np.arange(0, 2 * np.pi + dt / 2, dt)
    traj = Trajectory.from_samples(np.c_[10 * np.sin(t), 5 * np.cos(t)], dt, tol=1e-7)
    rng = np.random.default_rng(9)
    tq = np.linspace(0.2, traj.duration - 0.2, 300)
    actual = traj.at(tq / traj.duration) + rng.normal(scale=0.01, size=(300, 2))
    e = contour_error(traj, tq, actual, method)
    exact = ellipse_contour_error(10, 5, actual)
    # the fit is within 1e-7 of the ellipse; linear/circular add their own O(e^2) terms
    tol = {"exact": 1e-6, "circular": 1e-5, "linear": 5e-4}[method]
    np.testing.assert_allclose(e, exact, atol=tol)


@pytest.mark.parametrize("as_trajectory", [False, True])
def test_exact_is_the_true_closest_point_at_the_ends_of_a_noisy_ellipse(as_trajectory):
    # issue 12: 20 mm ellipse sampled at 1 ms, 0.05 mm noise on the actual positions; near
    # the start the closest point lies on the branch arriving at the (nearly closed) end,
    # which the arc-length window did not reach: sample 2 was off by 0.024 mm
    from primlib.nurbs import Trajectory

    dt = 1e-3
    t = np.arange(0.0, 2 * np.pi, dt)
    ref = np.c_[10 * np.sin(t), 5 * np.cos(t)]
    actual = ref + np.random.default_rng(0).normal(scale=0.05, size=ref.shape)
    ends = np.r_[0:40, len(t) - 40 : len(t), 40 : len(t) - 40 : 97]
    if as_trajectory:
        path = slow = Trajectory.from_samples(ref, dt)
    else:  # the samples' spline, as a Trajectory-like path so brute force runs on a subset
        path, spline = ref, CubicSpline(t, ref, axis=0)
        slow = Analytic(spline, lambda s: spline(s, 1), lambda s: spline(s, 2), t[-1])
    e = contour_error(path, t, actual)[ends]
    bf = brute_force_contour_error(slow, t[ends], actual[ends], samples=50_000)
    np.testing.assert_allclose(e, bf, atol=1e-6)  # brute force resolves ~1e-8 mm here


def test_contour_sign_just_behind_a_start_at_rest():
    # issue 12: the fit of a path starting at rest put a control point behind the start,
    # so the exact estimate of a point just behind it had the wrong sign (-1e-3)
    from primlib.io import read_path_csv
    from primlib.nurbs import Trajectory

    t, p = read_path_csv(ROOT / "data" / "paths" / "corner-and-arc.csv")
    tr = Trajectory.from_samples(p[:, :2], t[1])
    for method in METHODS:
        e = contour_error(tr, [0.02], [[-1e-6, 1e-3]], method=method)
        np.testing.assert_allclose(e, [1e-3], rtol=1e-3, err_msg=method)
