"""Trajectory: fitting, evaluation against geomdl, segments, exchange, and input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geomdl import NURBS, exchange
from geomdl import BSpline as GBSpline

from primlib import InputError
from primlib.defaults import FIT_RTOL
from primlib.io import read_path_csv
from primlib.nurbs import Trajectory


def _lissajous(n=400, d=3, scale=50.0):
    v = np.linspace(0.0, 1.0, n)
    cols = [scale * np.cos(5 * v), 0.6 * scale * np.sin(3 * v + 0.3), 0.2 * scale * v**2]
    return np.column_stack(cols[:d])


def _quarter_circle(duration=2.0):
    # exact rational quadratic arc of the unit circle (The NURBS Book, sec. 7.3)
    return Trajectory.from_definition(
        2, [0, 0, 0, 1, 1, 1], [[1, 0], [1, 1], [0, 1]], [1, math.sqrt(0.5), 1], duration
    )


def _rational_cubic():
    rng = np.random.default_rng(0)
    m, p = 9, 3
    knots = np.r_[np.zeros(p + 1), np.sort(rng.uniform(0, 1, m - p - 1)), np.ones(p + 1)]
    return Trajectory.from_definition(
        p, knots, rng.normal(size=(m, 3)) * 10, rng.uniform(0.3, 3.0, m), 1.7
    )


# ---------------------------------------------------------------- fitting
def _size(pts):
    """The default fit tolerance's size: twice the largest distance from the centroid."""
    return 2.0 * np.sqrt(((pts - pts.mean(axis=0)) ** 2).sum(axis=1).max())


@pytest.mark.parametrize("d", [2, 3])
def test_fit_meets_default_tolerance_with_few_control_points(d):
    pts = _lissajous(d=d)
    tr = Trajectory.from_samples(pts, dt=0.005)
    tol = FIT_RTOL * _size(pts)
    assert tr.dim == d and tr.degree == 3 and not tr.rational
    assert tr.duration == pytest.approx(399 * 0.005, rel=1e-15)
    assert tr.dt == 0.005
    assert tr.n_ctrlpts < 40  # a smooth path needs far fewer than its 400 samples
    err = np.linalg.norm(tr.sample(0.005) - pts, axis=1).max()
    assert err <= tol
    assert tr.fit_error == pytest.approx(err, rel=1e-9)
    np.testing.assert_array_equal(tr.at([0.0, 1.0]), pts[[0, -1]])


def test_count_is_near_minimal():
    pts = _lissajous()
    tol = 1e-3
    tr = Trajectory.from_samples(pts, 0.01, tol=tol)
    m = tr.n_ctrlpts
    fewer = m - 1 - math.floor(0.05 * m)  # the search stops within 5 % of a failing count
    assert Trajectory.from_samples(pts, 0.01, n_ctrlpts=fewer).fit_error > tol


def test_smaller_tolerance_needs_more_control_points():
    pts = _lissajous()
    counts = [Trajectory.from_samples(pts, 0.01, tol=t).n_ctrlpts for t in (1e-1, 1e-3, 1e-5)]
    assert counts[0] < counts[1] < counts[2]


def test_noise_below_tolerance_falls_back_to_interpolation():
    rng = np.random.default_rng(0)
    pts = _lissajous(n=60) + rng.normal(scale=0.5, size=(60, 3))
    tr = Trajectory.from_samples(pts, 0.01, tol=1e-6)
    assert tr.n_ctrlpts == 60
    np.testing.assert_allclose(tr.sample(0.01), pts, atol=1e-9)


def test_fixed_count_and_degree():
    pts = _lissajous(d=2)
    tr = Trajectory.from_samples(pts, 0.01, degree=5, n_ctrlpts=12)
    assert tr.degree == 5 and tr.n_ctrlpts == 12 and tr.knots.shape == (18,)
    lin = Trajectory.from_samples(pts, 0.01, degree=1, tol=1e-2)
    assert lin.degree == 1 and lin.fit_error <= 1e-2


def test_stationary_path_is_a_point():
    pts = np.tile([3.0, -2.0, 1.0], (20, 1))
    tr = Trajectory.from_samples(pts, 0.1)
    np.testing.assert_allclose(tr.at(np.linspace(0, 1, 7)), np.tile(pts[0], (7, 1)), atol=1e-12)
    assert tr.extent < 1e-12


# ---------------------------------------------------------------- evaluation
def test_at_shapes_and_scalar():
    tr = Trajectory.from_samples(_lissajous(), 0.01)
    assert tr.at(0.5).shape == (3,)
    assert tr.at([0.1, 0.2]).shape == (2, 3)
    assert tr.at(np.array([])).shape == (0, 3)
    np.testing.assert_array_equal(tr.at(1 + 5e-13), tr.at(1.0))  # rounding slack


@pytest.mark.parametrize(
    "make", [lambda: Trajectory.from_samples(_lissajous(), 0.01), _rational_cubic, _quarter_circle]
)
def test_matches_geomdl_positions_and_derivatives(make):
    tr = make()
    curve = tr.nurbs
    assert isinstance(curve, NURBS.Curve)
    v = np.linspace(0.0, 1.0, 57)
    scale = np.abs(tr.ctrlpts).max()
    np.testing.assert_allclose(
        tr.at(v), np.array(curve.evaluate_list(v.tolist())), rtol=0, atol=1e-12 * scale
    )
    ders = np.array([curve.derivatives(float(u), order=2) for u in v])  # (k, 3, d) in v
    T = tr.duration
    np.testing.assert_allclose(tr.velocity(v) * T, ders[:, 1], rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(tr.acceleration(v) * T**2, ders[:, 2], rtol=1e-9, atol=1e-8 * scale)


def test_quarter_circle_is_exact():
    tr = _quarter_circle(duration=2.0)
    v = np.linspace(0, 1, 101)
    np.testing.assert_allclose(np.linalg.norm(tr.at(v), axis=1), 1.0, atol=1e-15)
    pos, vel, acc = tr.at(v), tr.velocity(v), tr.acceleration(v)
    # on a circle the velocity is tangent: d/dt |C|^2 = 2 C.C' = 0, and C.C'' = -|C'|^2
    np.testing.assert_allclose(np.sum(pos * vel, axis=1), 0.0, atol=1e-14)
    np.testing.assert_allclose(np.sum(pos * acc, axis=1), -np.sum(vel * vel, axis=1), rtol=1e-12)
    assert tr.extent == pytest.approx(1.0, abs=1e-6)


def test_sample_and_times():
    tr = Trajectory.from_samples(_lissajous(n=101), dt=0.02)  # T = 2 s
    assert tr.times(0.02).shape == (101,)
    np.testing.assert_allclose(tr.times(0.01), np.arange(201) * 0.01)
    s = tr.sample(0.01)
    assert s.shape == (201, 3)
    np.testing.assert_array_equal(s[[0, -1]], tr.at([0.0, 1.0]))
    np.testing.assert_allclose(s[::2], tr.sample(0.02), atol=1e-12 * 50)
    with pytest.raises(InputError, match=r"dt: expected a step that divides the duration T = 2"):
        tr.sample(0.03)
    with pytest.raises(
        InputError,
        match=r"dt: expected a positive finite number of seconds, "
        r"got 0",
    ):
        tr.times(0)
    with pytest.raises(InputError, match=r"dt: expected a step that divides"):
        tr.sample(5.0)


# ---------------------------------------------------------------- segments
@pytest.mark.parametrize(
    "make", [lambda: Trajectory.from_samples(_lissajous(), 0.01), _rational_cubic, _quarter_circle]
)
@pytest.mark.parametrize(
    ("v0", "v1"), [(0.2, 0.7), (0.0, 0.35), (0.6, 1.0), (0.0, 1.0), (0.5, 0.5000001)]
)
def test_segment_is_exact(make, v0, v1):
    tr = make()
    seg = tr.segment(v0, v1)
    s = np.linspace(0, 1, 77)
    scale = np.abs(tr.ctrlpts).max()
    np.testing.assert_allclose(seg.at(s), tr.at(v0 + (v1 - v0) * s), rtol=0, atol=1e-12 * scale)
    assert seg.duration == pytest.approx((v1 - v0) * tr.duration, rel=1e-15)
    assert seg.knots[0] == 0.0 and seg.knots[-1] == 1.0 and seg.rational == tr.rational
    # time derivatives agree too: the segment runs at the same speed
    np.testing.assert_allclose(
        seg.velocity(s), tr.velocity(v0 + (v1 - v0) * s), rtol=1e-8, atol=1e-8 * scale / tr.duration
    )


def test_segment_at_existing_knot():
    tr = Trajectory.from_samples(_lissajous(), 0.01, n_ctrlpts=13)  # interior knots i / 10
    seg = tr.segment(0.3, 0.6)
    s = np.linspace(0, 1, 31)
    np.testing.assert_allclose(seg.at(s), tr.at(0.3 + 0.3 * s), atol=1e-12 * 50)
    assert seg.n_ctrlpts == 3 + 3  # p + number of spans (3)


# ---------------------------------------------------------------- exchange
def test_definition_round_trip_and_read_only():
    tr = _rational_cubic()
    d = tr.definition()
    assert set(d) == {"degree", "knots", "ctrlpts", "weights", "duration"}
    again = Trajectory.from_definition(**d)
    v = np.linspace(0, 1, 11)
    np.testing.assert_array_equal(again.at(v), tr.at(v))
    with pytest.raises(ValueError, match="read-only"):
        d["ctrlpts"][0, 0] = 1.0
    with pytest.raises(AttributeError, match="Trajectory is immutable: cannot set 'duration'"):
        tr.duration = 3.0
    assert repr(tr) == "Trajectory(dim=3, duration=1.7 s, degree=3, ctrlpts=9, rational)"


def test_from_nurbs_bspline_on_other_interval():
    c = GBSpline.Curve()
    c.degree = 2
    c.ctrlpts = [[0, 0], [1, 2], [3, 1], [4, 4]]
    c.knotvector = [0, 0, 0, 2, 4, 4, 4]  # geomdl normalises it to [0, 1] itself
    tr = Trajectory.from_nurbs(c, duration=3.0)
    np.testing.assert_array_equal(tr.knots, [0, 0, 0, 0.5, 1, 1, 1])
    v = np.linspace(0, 1, 9)
    np.testing.assert_allclose(tr.at(v), np.array(c.evaluate_list(v.tolist())), atol=1e-14)
    with pytest.raises(
        InputError, match="curve: expected a geomdl BSpline.Curve or NURBS.Curve, got str"
    ):
        Trajectory.from_nurbs("curve", 1.0)


@pytest.mark.parametrize(
    "make", [lambda: Trajectory.from_samples(_lissajous(), 0.01), _rational_cubic]
)
def test_json_round_trip_and_geomdl_reads_it(tmp_path, make):
    tr = make()
    f = tmp_path / "p.json"
    tr.to_json(f)
    back = Trajectory.from_json(f)
    for key, value in tr.definition().items():
        np.testing.assert_array_equal(back.definition()[key], value)
    (curve,) = exchange.import_json(str(f))  # geomdl itself reads the file
    v = np.linspace(0, 1, 23)
    np.testing.assert_allclose(
        np.array(curve.evaluate_list(v.tolist())), tr.at(v), atol=1e-12 * np.abs(tr.ctrlpts).max()
    )


def test_from_json_reads_geomdl_export(tmp_path):
    tr = _rational_cubic()
    f = tmp_path / "g.json"
    exchange.export_json(tr.nurbs, str(f))
    with pytest.raises(InputError, match=r"g\.json: expected a 'duration' \(seconds\) beside"):
        Trajectory.from_json(f)
    back = Trajectory.from_json(f, duration=1.7)
    v = np.linspace(0, 1, 23)
    np.testing.assert_allclose(back.at(v), tr.at(v), rtol=1e-14, atol=1e-13)


@pytest.mark.parametrize(
    ("doc", "message"),
    [
        ({"x": 1}, r"expected geomdl JSON with a 'shape' holding 'type' and 'data'"),
        (
            {"shape": {"type": "surface", "data": []}},
            r"expected a geomdl curve, got shape type "
            r"'surface'",
        ),
        ({"shape": {"type": "curve", "data": [{}, {}]}}, r"expected exactly one curve, got 2"),
        ({"shape": {"type": "curve", "data": [{"degree": 2}]}}, r"expected a curve with 'degree'"),
        (
            {
                "duration": 1.0,
                "shape": {
                    "type": "curve",
                    "data": [
                        {
                            "degree": 2,
                            "knotvector": [0, 0, 0, 1, 1],
                            "control_points": {"points": [[0, 0], [1, 1], [2, 0]]},
                        }
                    ],
                },
            },
            r"knots: expected shape \(6,\) for 3 control points of degree 2, got \(5,\)",
        ),
    ],
)
def test_from_json_errors(tmp_path, doc, message):
    import json

    f = tmp_path / "c.json"
    f.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=rf"c\.json: {message}"):
        Trajectory.from_json(f)


def test_csv_round_trip(tmp_path):
    tr = Trajectory.from_samples(_lissajous(n=201), dt=0.01)
    f = tmp_path / "p.csv"
    tr.to_csv(f, 0.005)
    t, pts = read_path_csv(f)
    np.testing.assert_array_equal(pts, tr.sample(0.005))
    np.testing.assert_array_equal(t, tr.times(0.005))
    back = Trajectory.from_csv(f, tol=1e-4)
    assert back.dt == pytest.approx(0.005, rel=1e-12)
    assert back.duration == pytest.approx(tr.duration, rel=1e-12)
    assert np.linalg.norm(back.sample(0.005) - pts, axis=1).max() <= 1e-4


# ---------------------------------------------------------------- bad input
GOOD = _lissajous(n=20)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            dict(points=np.zeros((20, 4))),
            r"points: expected shape \(n, 2\) or \(n, 3\), got "
            r"\(20, 4\)",
        ),
        (dict(points=np.zeros(20)), r"points: expected shape \(n, 2\) or \(n, 3\), got \(20,\)"),
        (
            dict(points=np.where(np.arange(60).reshape(20, 3) == 31, np.nan, GOOD)),
            r"points: expected finite values, got NaN or inf in row 10",
        ),
        (dict(points=GOOD[:7]), r"points: expected at least 8 samples, got 7"),
        (dict(dt=0.0), r"dt: expected a positive finite number of seconds, got 0\.0"),
        (dict(dt=-1), r"dt: expected a positive finite number of seconds, got -1"),
        (dict(dt=float("nan")), r"dt: expected a positive finite number of seconds, got nan"),
        (dict(tol=0), r"tol: expected a positive finite number \(user units\), got 0"),
        (dict(tol=-1e-3), r"tol: expected a positive finite number \(user units\), got -0\.001"),
        (dict(degree=0), r"degree: expected an integer >= 1, got 0"),
        (dict(degree=2.5), r"degree: expected an integer >= 1, got 2\.5"),
        (dict(degree=20), r"degree: expected an integer below the 20 samples, got 20"),
        (dict(n_ctrlpts=3), r"n_ctrlpts: expected an integer in 4 \.\. 20, got 3"),
        (dict(n_ctrlpts=21), r"n_ctrlpts: expected an integer in 4 \.\. 20, got 21"),
    ],
)
def test_from_samples_errors(kwargs, message):
    args = dict(points=GOOD, dt=0.01) | kwargs
    with pytest.raises(InputError, match=message):
        Trajectory.from_samples(**args)


def test_evaluation_errors():
    tr = Trajectory.from_samples(GOOD, 0.01)
    for bad in (-1e-9, 1.0 + 1e-9, float("nan")):
        with pytest.raises(InputError, match=r"v: expected normalised times in \[0, 1\], got"):
            tr.at([0.5, bad])
    with pytest.raises(InputError, match=r"v: expected a scalar or shape \(k,\), got shape"):
        tr.velocity(np.zeros((2, 2)))
    with pytest.raises(InputError, match=r"v0, v1: expected v0 < v1, got v0 = 0\.5, v1 = 0\.5"):
        tr.segment(0.5, 0.5)
    with pytest.raises(InputError, match=r"v1: expected normalised times in \[0, 1\], got 1\.5"):
        tr.segment(0.5, 1.5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(knots=[0, 0, 0, 0.5, 1, 1]), r"knots: expected shape \(7,\) for 4 control points"),
        (dict(knots=[0, 0, 0.1, 0.5, 1, 1, 1]), r"knots: expected a clamped vector"),
        (dict(knots=[0, 0, 0, 1, 1, 1, 1]), r"knots: expected a clamped vector \(exactly 3"),
        (dict(knots=[0, 0, 0, 0.7, 0.5, 1, 1]), r"knots: expected finite non-decreasing"),
        (dict(weights=[1, 1, 0, 1]), r"weights: expected positive finite values"),
        (dict(weights=[1, 1, 1]), r"weights: expected shape \(4,\), got \(3,\)"),
        (dict(duration=0), r"duration: expected a positive finite number of seconds, got 0"),
        (dict(ctrlpts=[[0, 0], [1, 1]]), r"ctrlpts: expected at least degree \+ 1 = 3 points"),
    ],
)
def test_from_definition_errors(kwargs, message):
    args = (
        dict(
            degree=2,
            knots=[0, 0, 0, 0.5, 1, 1, 1],
            ctrlpts=[[0, 0], [1, 1], [2, 0], [3, 3]],
            weights=None,
            duration=1.0,
        )
        | kwargs
    )
    with pytest.raises(InputError, match=message):
        Trajectory.from_definition(**args)


def test_from_definition_discontinuous_knots_rejected():
    with pytest.raises(
        InputError,
        match=r"knots: expected interior multiplicity at most the "
        r"degree 1 \(a continuous path\), got 2",
    ):
        Trajectory.from_definition(1, [0, 0, 0.5, 0.5, 1, 1], np.eye(4, 2), None, 1.0)


def test_from_definition_maps_knots_onto_unit_interval():
    ctrl = [[0, 0], [1, 2], [3, 1], [4, 4]]
    a = Trajectory.from_definition(2, [2, 2, 2, 3, 4, 4, 4], ctrl, None, 1.0)
    b = Trajectory.from_definition(2, [0, 0, 0, 0.5, 1, 1, 1], ctrl, None, 1.0)
    np.testing.assert_array_equal(a.knots, b.knots)
    v = np.linspace(0, 1, 9)
    np.testing.assert_array_equal(a.at(v), b.at(v))


def test_pickle_and_copy_round_trip():
    import copy
    import pickle

    tr = Trajectory.from_samples(_lissajous(), 0.01)
    for back in (pickle.loads(pickle.dumps(tr)), copy.deepcopy(tr), copy.copy(tr)):
        for key, value in tr.definition().items():
            np.testing.assert_array_equal(back.definition()[key], value)
        assert back.dt == tr.dt and back.fit_error == tr.fit_error
        assert not back.ctrlpts.flags.writeable


@pytest.mark.parametrize(
    "make", [lambda: Trajectory.from_samples(_lissajous(), 0.01), _rational_cubic]
)
def test_transformed_and_with_duration_are_exact(make):
    tr = make()
    rng = np.random.default_rng(1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    b = np.array([5.0, -7.0, 2.0])
    moved = tr.transformed(q, b)
    v = np.linspace(0, 1, 29)
    scale = np.abs(tr.ctrlpts).max() + 7
    np.testing.assert_allclose(moved.at(v), tr.at(v) @ q.T + b, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(
        moved.velocity(v), tr.velocity(v) @ q.T, rtol=1e-12, atol=1e-12 * scale
    )
    slow = tr.with_duration(2 * tr.duration)
    np.testing.assert_array_equal(slow.at(v), tr.at(v))
    np.testing.assert_allclose(slow.velocity(v), tr.velocity(v) / 2, rtol=1e-15)
    np.testing.assert_allclose(slow.acceleration(v), tr.acceleration(v) / 4, rtol=1e-15)
    with pytest.raises(
        InputError,
        match=r"rotation: expected a finite \(3, 3\) matrix, got "
        r"\(2, 2\)",
    ):
        tr.transformed(np.eye(2))
    with pytest.raises(InputError, match=r"translation: expected a finite \(3,\) vector"):
        tr.transformed(None, [1.0, np.nan, 0.0])
    with pytest.raises(InputError, match=r"duration: expected a positive finite number"):
        tr.with_duration(-1)


def test_from_nurbs_accepts_geomdl_split_curve_with_end_knots_ulps_below_1():
    # issue 12: geomdl's split_curve wrote end knots 0.9999999999999998 x3, 1.0
    from geomdl import operations

    t = np.arange(400) * 0.01
    tr = Trajectory.from_samples(np.c_[np.cos(t), np.sin(2 * t)], 0.01)
    first, second = operations.split_curve(tr.nurbs, 0.0024709595620390893)
    assert first.knotvector[-4:-1] == [1.0 - 2.0**-52] * 3  # the case as geomdl writes it
    for piece, (a, b) in (
        (first, (0.0, 0.0024709595620390893)),
        (second, (0.0024709595620390893, 1.0)),
    ):
        got = Trajectory.from_nurbs(piece, 1.0)
        s = np.linspace(0.0, 1.0, 17)
        np.testing.assert_allclose(got.at(s), tr.at(a + (b - a) * s), atol=1e-12)
    with pytest.raises(InputError, match="knots: expected a clamped vector"):
        Trajectory.from_definition(3, [0, 0, 0, 0, 0.999999, 0.999999, 0.999999, 1], np.eye(4, 2))


@pytest.mark.parametrize("dim", [2, 3])
def test_rotated_copy_is_fitted_the_same_way(dim):
    # issue 12: the default tolerance followed the bounding box, so a rotated copy got
    # another control-point count and matched its original at RMSD 5e-4 instead of 0
    from scipy.spatial.transform import Rotation

    t = np.arange(600) * 0.005
    pts = np.c_[40 * np.cos(t), 15 * np.sin(2 * t), 3 * t][:, :dim]
    R = Rotation.from_euler("zyx", [37, 21, -12], degrees=True).as_matrix()[:dim, :dim]
    if dim == 2:
        R = Rotation.from_euler("z", 37, degrees=True).as_matrix()[:2, :2]
    a = Trajectory.from_samples(pts, 0.005)
    b = Trajectory.from_samples(pts @ R.T, 0.005)
    assert a.n_ctrlpts == b.n_ctrlpts
    diff = b.sample(0.005) - a.sample(0.005) @ R.T
    rmsd = float(np.sqrt((diff**2).sum(axis=1).mean()))
    assert rmsd < 1e-12 * 40


@pytest.mark.parametrize(
    "name", ["paths/corner-and-arc.csv", "library/line-x-fast.csv", "library/arc-climb.csv"]
)
def test_fit_of_a_path_at_rest_does_not_run_backwards(name):
    # issue 12: minimum-jerk starts were fitted with a control point behind the start
    # (x = -2.6e-5 on corner-and-arc, up to 1.1e-3 of travel on line-x): a cusp
    from pathlib import Path

    f = Path(__file__).resolve().parents[1] / "data" / name
    t, p = read_path_csv(f)
    tr = Trajectory.from_csv(f)
    assert tr.fit_error <= FIT_RTOL * _size(p)
    np.testing.assert_array_equal(tr.velocity([0.0, 1.0]), np.zeros((2, 3)))
    v = np.linspace(0.0, 1.0, 400_001)
    q = tr.at(v)
    for end, head in ((p[0], q[:4000]), (p[-1], q[-4000:][::-1])):
        moved = head - end
        direction = moved[-1] / np.linalg.norm(moved[-1])
        # along the samples' direction of travel, never behind the end point
        assert (moved @ direction).min() >= 0.0


def test_fit_of_a_moving_end_is_not_held_at_rest():
    pts = _lissajous(d=3)
    tr = Trajectory.from_samples(pts, dt=0.005)
    sample_velocity = (pts[1] - pts[0]) / 0.005
    got = tr.velocity(0.0)
    assert got @ sample_velocity > 0.99 * np.linalg.norm(got) * np.linalg.norm(sample_velocity)
