"""Invariants of Trajectory, checked on random paths and random NURBS definitions."""

from __future__ import annotations

import numpy as np
from geomdl import exchange
from hypothesis import given, settings
from hypothesis import strategies as st

from primlib.defaults import FIT_RTOL
from primlib.io import read_path_csv
from primlib.nurbs import Trajectory

SETTINGS = settings(max_examples=25, deadline=None)


@st.composite
def smooth_samples(draw):
    """A random smooth path: a few random sinusoids per axis, n samples at uniform time."""
    seed = draw(st.integers(0, 2**32 - 1))
    n = draw(st.integers(8, 400))
    d = draw(st.sampled_from([2, 3]))
    rng = np.random.default_rng(seed)
    v = np.linspace(0.0, 1.0, n)
    k = rng.integers(1, 4)
    freq = rng.uniform(0.2, 4.0, size=(k, d))
    amp = rng.uniform(1.0, 100.0, size=(k, d))
    phase = rng.uniform(0.0, 2 * np.pi, size=(k, d))
    pts = (amp[None] * np.sin(2 * np.pi * freq[None] * v[:, None, None] + phase[None])).sum(1)
    pts += rng.uniform(-1e3, 1e3, size=d)
    dt = draw(st.sampled_from([0.001, 0.004, 0.01]))
    return pts, dt


@st.composite
def definitions(draw):
    """A random valid NURBS definition: degree 1-5, clamped random knots, positive weights."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    p = int(rng.integers(1, 6))
    m = int(rng.integers(p + 1, p + 12))
    d = int(rng.choice([2, 3]))
    interior = np.sort(np.round(rng.uniform(0.001, 0.999, m - p - 1), 3))  # repeated knots happen
    if interior.size:
        _, counts = np.unique(interior, return_counts=True)
        if counts.max() > p:  # keep the path continuous
            interior = np.linspace(0, 1, m - p + 1)[1:-1]
    knots = np.concatenate([np.zeros(p + 1), interior, np.ones(p + 1)])
    rational = draw(st.booleans())
    weights = rng.uniform(0.2, 5.0, m) if rational else np.ones(m)
    ctrl = rng.normal(scale=10.0, size=(m, d))
    duration = float(rng.uniform(0.1, 20.0))
    return Trajectory.from_definition(p, knots, ctrl, weights, duration)


def _random_rotation(rng, d):
    q, r = np.linalg.qr(rng.normal(size=(d, d)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


@SETTINGS
@given(smooth_samples())
def test_fit_is_within_tolerance_and_hits_the_ends(case):
    pts, dt = case
    tr = Trajectory.from_samples(pts, dt)
    tol = FIT_RTOL * 2.0 * np.sqrt(((pts - pts.mean(axis=0)) ** 2).sum(axis=1).max())
    assert np.linalg.norm(tr.sample(dt) - pts, axis=1).max() <= tol
    np.testing.assert_array_equal(tr.at([0.0, 1.0]), pts[[0, -1]])
    assert tr.duration == (len(pts) - 1) * dt


@SETTINGS
@given(definitions(), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1))
def test_segment_of_segment_is_one_segment(tr, a, b, c, e):
    v0, v1 = sorted((a, b))
    s0, s1 = sorted((c, e))
    if v1 - v0 < 1e-6 or s1 - s0 < 1e-6:
        return
    inner = tr.segment(v0, v1).segment(s0, s1)
    direct = tr.segment(v0 + (v1 - v0) * s0, v0 + (v1 - v0) * s1)
    s = np.linspace(0, 1, 41)
    scale = np.abs(tr.ctrlpts).max()
    # every step is exact up to rounding; the weights' spread amplifies it a little
    np.testing.assert_allclose(inner.at(s), direct.at(s), rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(
        inner.at(s), tr.at(v0 + (v1 - v0) * (s0 + (s1 - s0) * s)), rtol=0, atol=1e-10 * scale
    )
    assert inner.duration == np.float64(direct.duration) or np.isclose(
        inner.duration, direct.duration, rtol=1e-14
    )


@SETTINGS
@given(definitions())
def test_derivatives_match_central_differences(tr):
    # Central differences with step h inside one polynomial piece: truncation error
    # <= h^2 / 6 max|C3| (first) and h^2 / 12 max|C4| (second), rounding ~ eps |C| / h^k,
    # Ck the k-th v-derivative; C3 is bounded by differencing C'' over the stencil.
    h1, h2 = 1e-5, 1e-4
    v = np.linspace(0.02, 0.98, 61)
    v = v[np.abs(v[:, None] - tr.knots[None, :]).min(axis=1) > 2 * h2]
    if v.size == 0:
        return
    T = tr.duration
    vel, acc = tr.velocity(v) * T, tr.acceleration(v) * T**2
    fd_v = (tr.at(v + h1) - tr.at(v - h1)) / (2 * h1)
    fd_a = (tr.at(v + h2) - 2 * tr.at(v) + tr.at(v - h2)) / h2**2
    d3 = np.abs(tr.acceleration(v + h2) - tr.acceleration(v - h2)).max() * T**2 / (2 * h2)
    d4 = 2 * d3 / h2  # crude but safe: C3 changes by at most 2 max|C3| over the stencil
    eps, size = np.finfo(float).eps, np.abs(tr.at(v)).max()
    tol_v = 10 * (h1**2 / 6 * d3 + eps * size / h1)
    tol_a = 10 * (h2**2 / 12 * d4 + 4 * eps * size / h2**2)
    np.testing.assert_allclose(fd_v, vel, rtol=1e-6, atol=tol_v)
    np.testing.assert_allclose(fd_a, acc, rtol=1e-4, atol=tol_a)


@SETTINGS
@given(smooth_samples(), st.integers(0, 2**32 - 1))
def test_rigid_motion_commutes_with_the_fit(case, seed):
    pts, dt = case
    rng = np.random.default_rng(seed)
    d = pts.shape[1]
    R, b = _random_rotation(rng, d), rng.uniform(-500, 500, d)
    m = min(len(pts), 4 + len(pts) // 10)
    fit = Trajectory.from_samples(pts, dt, n_ctrlpts=m)
    moved = Trajectory.from_samples(pts @ R.T + b, dt, n_ctrlpts=m)
    scale = np.abs(pts).max() + np.abs(b).max()
    v = np.linspace(0, 1, 33)
    np.testing.assert_allclose(moved.at(v), fit.at(v) @ R.T + b, rtol=0, atol=1e-9 * scale)
    assert abs(moved.fit_error - fit.fit_error) <= 1e-9 * scale


@SETTINGS
@given(definitions())
def test_json_round_trip_is_exact_and_geomdl_agrees(tmp_path_factory, tr):
    f = tmp_path_factory.mktemp("json") / "p.json"
    tr.to_json(f)
    back = Trajectory.from_json(f)
    for key, value in tr.definition().items():
        np.testing.assert_array_equal(back.definition()[key], value)
    (curve,) = exchange.import_json(str(f))
    v = np.linspace(0, 1, 17)
    np.testing.assert_allclose(
        np.array(curve.evaluate_list(v.tolist())),
        tr.at(v),
        rtol=0,
        atol=1e-10 * np.abs(tr.ctrlpts).max(),
    )


@SETTINGS
@given(smooth_samples())
def test_csv_round_trip_refits_within_tolerance(tmp_path_factory, case):
    pts, dt = case
    tr = Trajectory.from_samples(pts, dt)
    f = tmp_path_factory.mktemp("csv") / "p.csv"
    tr.to_csv(f, dt)
    t, written = read_path_csv(f)
    np.testing.assert_array_equal(written, tr.sample(dt))
    back = Trajectory.from_csv(f, tol=1e-6 * np.ptp(pts, axis=0).max())
    assert np.isclose(back.duration, tr.duration, rtol=1e-12)
    assert np.linalg.norm(back.sample(dt) - written, axis=1).max() <= 1e-6 * np.ptp(pts, 0).max()
