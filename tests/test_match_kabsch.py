"""Kabsch superposition: properties (hypothesis), degenerate pieces, modes, QCP vs SVD."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from primlib import InputError
from primlib.match import kabsch, rmsd_from_moments


def _rot(d: int, seed: int) -> np.ndarray:
    if d == 3:
        return Rotation.random(random_state=seed).as_matrix()
    th = np.random.default_rng(seed).uniform(-np.pi, np.pi)
    return np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])


def _curve(n: int, d: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)[:, None]
    return np.cumsum(rng.normal(size=(n, d)), axis=0) + 3.0 * np.sin(4 * t + rng.normal(size=d))


seeds = st.integers(0, 2**31 - 1)
dims = st.sampled_from([2, 3])


@settings(max_examples=40, deadline=None)
@given(seed=seeds, d=dims, n=st.integers(3, 40))
def test_random_rigid_motion_is_recovered(seed, d, n):
    p = _curve(n, d, seed)
    r = _rot(d, seed + 1)
    t = np.random.default_rng(seed + 2).normal(size=d) * 10
    res = kabsch(p, p @ r.T + t)
    scale = np.abs(p).max() + 10
    # round-off only: the motion is exact
    assert res.rmsd < 1e-9 * scale
    np.testing.assert_allclose(res.rotation, r, atol=1e-8)
    np.testing.assert_allclose(res.translation, t, atol=1e-8 * scale)


@settings(max_examples=40, deadline=None)
@given(seed=seeds, d=dims, n=st.integers(2, 30))
def test_rmsd_invariant_under_joint_rigid_motion(seed, d, n):
    rng = np.random.default_rng(seed)
    p, q = _curve(n, d, seed), _curve(n, d, seed + 7)
    r, t = _rot(d, seed + 3), rng.normal(size=d) * 5
    base = kabsch(p, q).rmsd
    moved = kabsch(p @ r.T + t, q @ r.T - t).rmsd
    np.testing.assert_allclose(moved, base, rtol=1e-9, atol=1e-9)
    # and under separate motions of each piece
    moved2 = kabsch(p @ _rot(d, seed + 4).T + 1.0, q @ r.T - t).rmsd
    np.testing.assert_allclose(moved2, base, rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(seed=seeds, d=dims, n=st.integers(4, 30))
def test_never_a_reflection(seed, d, n):
    p, q = _curve(n, d, seed), _curve(n, d, seed + 1)
    res = kabsch(p, q)
    np.testing.assert_allclose(np.linalg.det(res.rotation), 1.0, atol=1e-12)
    # a mirror image is reached by no proper rotation: with S = Pc'Pc (Pc the centred
    # points, eigenvalues l_1 >= ... >= l_d) the cross-covariance is S M (M the mirror,
    # det -1), whose singular values are the l_i; the best proper rotation must flip the
    # sign of the smallest, so n rmsd^2 = 2 tr S - 2 (tr S - 2 l_d) = 4 l_d: the mirror is
    # 2 sqrt(l_d / n) away, zero only for points in a hyperplane (asserting a fixed 1e-3
    # failed on four nearly coplanar points of 3-D, 5.2e-4 away)
    mirror = p * np.r_[-1.0, np.ones(d - 1)]
    pc = p - p.mean(axis=0)
    low = max(float(np.linalg.eigvalsh(pc.T @ pc)[0]), 0.0)
    radius = float(np.sqrt(np.sum(pc**2) / n))
    got = kabsch(p, mirror).rmsd
    # (to 1e-6 of the radius: near 0 an rmsd taken from a difference of squares errs by up
    # to ~sqrt(machine eps) of it; 6e-13 at most over 16,000 curves)
    assert abs(got - 2.0 * np.sqrt(low / n)) <= 1e-6 * radius


@settings(max_examples=40, deadline=None)
@given(seed=seeds, n=st.integers(3, 30), mode=st.sampled_from(["full", "z", "none"]))
def test_qcp_rmsd_equals_svd_rmsd(seed, n, mode):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(5, n, 3))
    q = p @ _rot(3, seed).T + 0.1 * rng.normal(size=(5, n, 3))
    q[1] = rng.normal(size=(n, 3))  # and an unrelated pair
    pc = p - p.mean(axis=1, keepdims=True)
    qc = q - q.mean(axis=1, keepdims=True)
    s = np.einsum("kna,knb->kab", pc, qc)
    if mode == "z":
        sp, sq = (pc**2).sum(axis=1), (qc**2).sum(axis=1)
    else:
        sp, sq = (pc**2).sum(axis=(1, 2)), (qc**2).sum(axis=(1, 2))
    fast = rmsd_from_moments(s, sp, sq, n, mode)
    np.testing.assert_allclose(fast, kabsch(p, q, rotation=mode).rmsd, rtol=1e-7, atol=1e-9)


def test_qcp_keeps_precision_for_near_identical_pieces():
    # rmsd 1e-4 of pieces of size 1e2 (1e-6 relative): QCP resolves rmsd down to about
    # sqrt(machine eps) of the size, where σ₃ = sqrt(eig(SᵀS)) would already be off by 1e-2
    rng = np.random.default_rng(0)
    p = 100 * rng.normal(size=(1, 50, 3))
    q = p + 1e-4 * rng.normal(size=p.shape)
    pc, qc = p - p.mean(axis=1), q - q.mean(axis=1)
    s = np.einsum("kna,knb->kab", pc, qc)
    fast = rmsd_from_moments(s, (pc**2).sum(axis=(1, 2)), (qc**2).sum(axis=(1, 2)), 50)
    np.testing.assert_allclose(fast, kabsch(p, q).rmsd, rtol=0.01)


@pytest.mark.parametrize("d", [2, 3])
def test_degenerate_point_gives_identity_and_zero(d):
    p = np.ones((10, d))
    q = np.full((10, d), 5.0)
    res = kabsch(p, q)
    assert res.rmsd == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(res.rotation, np.eye(d))
    np.testing.assert_allclose(res.translation, np.full(d, 4.0))


def test_degenerate_line_gets_least_angle_rotation():
    s = np.linspace(0, 1, 20)[:, None]
    p = s * np.array([1.0, 0.0, 0.0])
    q = s * np.array([0.0, 1.0, 0.0]) + 2.0
    res = kabsch(p, q)
    assert res.rmsd == pytest.approx(0.0, abs=1e-12)
    # the least turn taking x to y is a quarter turn about z
    np.testing.assert_allclose(
        res.rotation, Rotation.from_euler("z", 90, degrees=True).as_matrix(), atol=1e-12
    )
    # antiparallel: a half turn, still proper
    res2 = kabsch(p, -p)
    assert res2.rmsd == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(np.linalg.det(res2.rotation), 1.0)


def test_line_in_2d():
    s = np.linspace(0, 1, 20)[:, None]
    res = kabsch(s * [1.0, 0.0], s * [0.0, 1.0])
    assert res.rmsd == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(res.rotation, [[0, -1], [1, 0]], atol=1e-12)


def test_mode_z_rotates_about_the_vertical_only():
    p = _curve(30, 3, 1)
    rz = Rotation.from_euler("z", 40, degrees=True).as_matrix()
    res = kabsch(p, p @ rz.T + [1, 2, 3], rotation="z")
    assert res.rmsd < 1e-10
    np.testing.assert_allclose(res.rotation, rz, atol=1e-10)
    tilted = p @ Rotation.from_euler("x", 30, degrees=True).as_matrix().T
    resz = kabsch(p, tilted, rotation="z")
    np.testing.assert_allclose(resz.rotation[2], [0, 0, 1])
    assert resz.rmsd > kabsch(p, tilted).rmsd + 1e-3


def test_mode_none_is_translation_only():
    p = _curve(30, 3, 2)
    res = kabsch(p, p + 3.0, rotation="none")
    np.testing.assert_allclose(res.rotation, np.eye(3))
    assert res.rmsd < 1e-12
    rotated = p @ _rot(3, 5).T
    res2 = kabsch(p, rotated, rotation="none")
    expect = np.sqrt(np.mean(np.sum((rotated - rotated.mean(0) - p + p.mean(0)) ** 2, axis=1)))
    assert res2.rmsd == pytest.approx(expect)


def test_weights_ignore_zero_weight_outliers():
    p = _curve(30, 3, 3)
    r = _rot(3, 9)
    q = p @ r.T + 1.0
    q[:5] += 50.0
    w = np.ones(30)
    w[:5] = 0.0
    res = kabsch(p, q, weights=w)
    np.testing.assert_allclose(res.rotation, r, atol=1e-9)
    assert res.rmsd < 1e-9


def test_batched_shapes():
    p = np.random.default_rng(0).normal(size=(7, 12, 3))
    res = kabsch(p, p + 1.0)
    assert res.rotation.shape == (7, 3, 3)
    assert res.translation.shape == (7, 3)
    assert res.rmsd.shape == (7,)


@pytest.mark.parametrize(
    ("kw", "msg"),
    [
        ({"P": np.zeros((5, 3)), "Q": np.zeros((5, 2))}, "equal shape"),
        ({"P": np.zeros((5, 4)), "Q": np.zeros((5, 4))}, "d in 2 or 3"),
        ({"P": np.zeros((5, 2)), "Q": np.zeros((5, 2)), "rotation": "z"}, "needs 3-D"),
        (
            {"P": np.zeros((5, 3)), "Q": np.zeros((5, 3)), "rotation": "spin"},
            "one of full, z, none",
        ),
        ({"P": np.zeros((5, 3)), "Q": np.zeros((5, 3)), "weights": -np.ones(5)}, "weights"),
    ],
)
def test_bad_input(kw, msg):
    with pytest.raises(InputError, match=msg):
        kabsch(**kw)


def _moments_rmsd(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pc = p - p.mean(axis=-2, keepdims=True)
    qc = q - q.mean(axis=-2, keepdims=True)
    s = np.einsum("kna,knb->kab", pc, qc)
    return rmsd_from_moments(s, (pc**2).sum(axis=(1, 2)), (qc**2).sum(axis=(1, 2)), p.shape[1])


def test_rmsd_from_moments_on_a_straight_3d_piece():
    # issue 12: the largest root of Horn's quartic is double; Newton froze at 0.2828
    s = np.linspace(-1, 1, 50)[:, None]
    p = s * np.array([1.0, 2.0, 2.0]) / 3
    q = s * np.array([0.0, 0.0, 1.0])
    got = rmsd_from_moments((p.T @ q)[None], np.array([(p**2).sum()]), np.array([(q**2).sum()]), 50)
    # eq. (2) resolves an RMSD to √u of the radius (0.58 here): 1e-7 is round-off
    assert got[0] < 1e-7
    assert kabsch(p, q).rmsd < 1e-12


def _piece(kind: str, rng, n: int) -> np.ndarray:
    s = np.linspace(-1, 1, n)[:, None]
    direction = rng.normal(size=3)
    if kind == "point":
        return np.tile(rng.normal(size=3), (n, 1))
    if kind == "line":
        return s * direction
    if kind == "plane":
        p = np.cumsum(rng.normal(size=(n, 3)), axis=0)
        p[:, 2] = 0.0
        return p @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T
    return np.cumsum(rng.normal(size=(n, 3)), axis=0)


@settings(max_examples=80, deadline=None)
@given(
    seed=seeds,
    n=st.integers(3, 60),
    kind=st.sampled_from(["point", "line", "plane", "curve"]),
    noise=st.sampled_from([0.0, 1e-12, 1e-9, 1e-7, 1e-5, 1e-3, 1e-1]),
    same=st.booleans(),
)
def test_rmsd_from_moments_equals_kabsch_on_degenerate_pieces(seed, n, kind, noise, same):
    # random orientations of (nearly) degenerate pieces, and the same piece rotated
    rng = np.random.default_rng(seed)
    p = _piece(kind, rng, n) * rng.uniform(0.01, 100.0)
    q = p if same else _piece(kind, rng, n) * rng.uniform(0.01, 100.0)
    q = q @ Rotation.random(random_state=seed).as_matrix().T + rng.normal(size=3)
    size = np.abs(p).max() + np.abs(q).max()
    p = p + rng.normal(size=p.shape) * noise * size
    q = q + rng.normal(size=q.shape) * noise * size
    fast = _moments_rmsd(p[None], q[None])[0]
    slow = kabsch(p, q).rmsd
    # eq. (2) subtracts energies: round-off of a few hundred ulps of Σ|p̃|² + Σ|q̃|², per
    # point; kabsch's residual carries a few ulps of the coordinates (a point piece: only that)
    pc, qc = p - p.mean(axis=0), q - q.mean(axis=0)
    energy = ((pc**2).sum() + (qc**2).sum()) / n
    e = 64 * 2.2e-16 * size
    assert abs(fast**2 - slow**2) <= 1e-13 * energy + 2 * slow * e + e * e


@pytest.mark.parametrize("bend", [0.0, 1e-9, 1e-6, 1e-3, 1e-2, 0.1])
@pytest.mark.parametrize("mirror", [False, True])
def test_deflated_lambda_max_equals_horn_eigenvalue_on_nearly_straight_pieces(bend, mirror):
    # nearly straight pieces: the quartic's top root is (nearly) double, Newton's method
    # resolves it to √u only; the deflation must give eigvalsh's accuracy wherever it claims it
    from primlib.match._kabsch import _deflated_lambda_max, _horn_matrix

    rng = np.random.default_rng(3)
    s = np.linspace(-1.0, 1.0, 40)[:, None]
    p = np.stack([s[:, 0], bend * s[:, 0] ** 2, 0.3 * bend * s[:, 0] ** 3], axis=1)
    pieces = []
    for _ in range(50):
        q = p @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T
        q = q + 1e-3 * bend * rng.normal(size=q.shape)
        if mirror:
            q = q * np.array([1.0, 1.0, -1.0])
        pc, qc = p - p.mean(axis=0), q - q.mean(axis=0)
        pieces.append(pc.T @ qc * rng.uniform(0.01, 100.0))
    m = np.stack(pieces)
    lam, good = _deflated_lambda_max(m)
    top = np.linalg.eigvalsh(_horn_matrix(m))[:, -1]
    assert good.mean() > 0.9  # the dominant singular value is far from the others
    np.testing.assert_allclose(lam[good], top[good], rtol=1e-14)


def test_deflated_lambda_max_leaves_degenerate_cases_to_newton():
    # S = 0 (a point) and σ₁ = σ₂ (a circle against itself) have no dominant singular pair
    from primlib.match._kabsch import _deflated_lambda_max

    t = np.linspace(0.0, 2.0 * np.pi, 60, endpoint=False)
    c = np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
    _, good = _deflated_lambda_max(np.stack([np.zeros((3, 3)), c.T @ c]))
    assert not good.any()
