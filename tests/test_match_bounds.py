"""The search's lower bounds against brute force: never above the exact Kabsch RMSD of any
window, in every rotation family, and not vacuous."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from primlib.match import kabsch
from primlib.match._bounds import (
    QueryMoments,
    _columns,
    gyration_bound,
    half_bound_margin,
    half_window_bound,
    half_window_bound_fixed,
    principal_bound,
    principal_bound_points,
    speed_bound,
    speed_groups,
    speed_screen,
    strided_cumsum,
    strided_prefix_sums,
    sym_eigvals,
)


def _sequence(rng, m: int, d: int, kind: str) -> np.ndarray:
    """A point sequence: a smooth random walk, or a degenerate one (line, point, plane)."""
    walk = np.cumsum(rng.normal(size=(m, d)), axis=0) * rng.uniform(0.1, 100.0)
    if kind == "line":
        return np.linspace(0, 1, m)[:, None] * rng.normal(size=d) * 50 + rng.normal(size=d)
    if kind == "point":
        return np.tile(rng.normal(size=d) * 10, (m, 1))
    if kind == "plane" and d == 3:
        walk[:, 2] = 0.0
        return walk @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T
    return walk


def _windows(pts: np.ndarray, k: int, dil: int) -> np.ndarray:
    """Every window {m + i·dil, i < k} gathered, shape (n_windows, k, d)."""
    n = pts.shape[0] - (k - 1) * dil
    idx = np.arange(n)[:, None] + np.arange(k) * dil
    return pts[idx]


def _exact(wins: np.ndarray, q: np.ndarray, rotation: str) -> np.ndarray:
    return kabsch(wins, np.broadcast_to(q, wins.shape), rotation=rotation).rmsd


def _bounds(pts: np.ndarray, qc: np.ndarray, dil: int):
    k = qc.shape[0]
    psum, pmax, radius = strided_prefix_sums(pts, dil)
    query = QueryMoments.of(qc)
    n = pts.shape[0] - (k - 1) * dil
    lb1 = half_window_bound(psum, n, dil, query, half_bound_margin(k, qc.shape[1], pmax, radius))
    lb2 = principal_bound(psum, np.arange(n), dil, query, pmax, radius)
    return lb1, lb2


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    d=st.sampled_from([2, 3]),
    k=st.integers(4, 24),
    dil=st.integers(1, 3),
    kind=st.sampled_from(["walk", "line", "point", "plane"]),
    query=st.sampled_from(["random", "copy", "line"]),
)
def test_bounds_never_exceed_the_exact_rmsd_of_any_window(seed, d, k, dil, kind, query):
    rng = np.random.default_rng(seed)
    pts = _sequence(rng, 40 + (k - 1) * dil, d, kind)
    wins = _windows(pts, k, dil)
    if query == "copy":  # a rotated, noisy copy of one window: bounds near zero there
        r = Rotation.random(random_state=seed).as_matrix()[:d, :d] if d == 3 else np.eye(2)
        q = wins[rng.integers(len(wins))] @ r.T + rng.normal(size=(k, d)) * 1e-3
    elif query == "line":
        q = np.linspace(0, 1, k)[:, None] * rng.normal(size=d) * 30
    else:
        q = np.cumsum(rng.normal(size=(k, d)), axis=0) * 10
    qc = q - q.mean(axis=0)
    lb1, lb2 = _bounds(pts, qc, dil)
    scale = 1e-12 * (1.0 + np.abs(pts).max() + np.abs(qc).max())
    rotations = ["full", "none"] + (["z"] if d == 3 else [])
    psum, pmax, radius = strided_prefix_sums(pts, dil)
    margin = half_bound_margin(k, d, pmax, radius) * np.sqrt(d)
    lb4 = principal_bound_points(pts, np.arange(len(wins)), dil, QueryMoments.of(qc), radius)
    for rotation in rotations:
        exact = _exact(wins, qc, rotation)
        assert np.all(lb1 <= exact + scale), (rotation, np.max(lb1 - exact))
        assert np.all(lb2 <= exact + scale), (rotation, np.max(lb2 - exact))
        assert np.all(lb4 <= exact + scale), (rotation, np.max(lb4 - exact))
        if rotation != "full":
            # the restricted families' own bound: at or above the rotation-invariant one
            # (up to its wider round-off margin)
            lb3 = half_window_bound_fixed(
                psum, len(wins), dil, QueryMoments.of(qc), margin, rotation
            )
            assert np.all(lb3 <= exact + scale), (rotation, np.max(lb3 - exact))
            assert np.all(lb3 >= lb1 - margin - 1e-9 * (1 + np.abs(lb1)))


def test_restricted_bounds_are_much_tighter_for_restricted_rotations():
    # a rotated copy of a window: any-rotation bounds are ~0, the no-rotation bound is not
    rng = np.random.default_rng(5)
    pts = np.cumsum(rng.normal(size=(300, 3)), axis=0)
    wins = _windows(pts, 16, 1)
    r = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    qc = wins[100] @ r.T
    qc = qc - qc.mean(axis=0)
    psum, pmax, radius = strided_prefix_sums(pts, 1)
    query = QueryMoments.of(qc)
    margin = half_bound_margin(16, 3, pmax, radius) * np.sqrt(3)
    full = half_window_bound(psum, len(wins), 1, query, margin)
    none = half_window_bound_fixed(psum, len(wins), 1, query, margin, "none")
    z = half_window_bound_fixed(psum, len(wins), 1, query, margin, "z")
    assert full[100] < 1e-9 and z[100] < 1e-9  # a turn about z is allowed by both
    exact = _exact(wins, qc, "none")
    assert none[100] > 0.3 * exact[100] > 0
    assert np.median(none / exact) > 1.5 * np.median(np.maximum(full, 0) / exact)


def test_bounds_are_not_vacuous():
    # a query unlike the windows: both bounds recover a good part of the true RMSD
    rng = np.random.default_rng(4)
    pts = np.cumsum(rng.normal(size=(400, 3)), axis=0)
    q = np.linspace(0, 1, 16)[:, None] * np.array([30.0, 0.0, 0.0])
    qc = q - q.mean(axis=0)
    lb1, lb2 = _bounds(pts, qc, 2)
    exact = _exact(_windows(pts, 16, 2), qc, "full")
    assert np.median(lb1 / exact) > 0.3
    assert np.median(lb2 / exact) > 0.3
    # from the gathered points: the same bound, with a smaller round-off margin
    wins = _windows(pts, 16, 2)
    radius = float(np.linalg.norm(pts, axis=1).max())
    lb4 = principal_bound_points(pts, np.arange(len(wins)), 2, QueryMoments.of(qc), radius)
    assert np.all(lb4 >= lb2 - 1e-9 * (1.0 + np.abs(lb2)))
    np.testing.assert_allclose(lb4, lb2, rtol=1e-3, atol=1e-3 * np.abs(lb2).max())


@pytest.mark.parametrize("dil", [1, 2, 4])
def test_prefix_sums_give_every_window_sum(dil):
    rng = np.random.default_rng(dil)
    pts = rng.normal(size=(50, 3))
    psum, pmax, radius = strided_prefix_sums(pts, dil)
    k = 7
    wins = _windows(pts, k, dil)
    m = np.arange(len(wins))
    s = psum[:, m + k * dil] - psum[:, m]
    np.testing.assert_allclose(s[:3].T, wins.sum(axis=1), atol=1e-12)
    np.testing.assert_allclose(s[3], (wins**2).sum(axis=(1, 2)), atol=1e-12)
    np.testing.assert_allclose(s[4], (wins[..., 0] ** 2).sum(axis=1), atol=1e-12)  # xx
    np.testing.assert_allclose(s[5], (wins[..., 1] ** 2).sum(axis=1), atol=1e-12)  # yy
    np.testing.assert_allclose(s[7], (wins[..., 0] * wins[..., 1]).sum(axis=1), atol=1e-12)
    assert radius == pytest.approx(np.linalg.norm(pts, axis=1).max())
    assert np.all(pmax >= np.abs(psum).max(axis=1))
    # without the products: the coordinates' and |p|²'s rows alone, the same values
    short, smax, sradius = strided_prefix_sums(pts, dil, products=False)
    np.testing.assert_array_equal(short, psum[:4])
    np.testing.assert_array_equal(smax, pmax[:4])
    assert sradius == radius
    # the squares alone (rotation "none"'s per-axis bound): the first 7 rows, the same values
    sq, sqmax, sqradius = strided_prefix_sums(pts, dil, products="squares")
    np.testing.assert_array_equal(sq, psum[:7])
    np.testing.assert_array_equal(sqmax, pmax[:7])
    assert sqradius == radius


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(3, 30))
def test_gyration_bound_never_exceeds_the_rmsd(seed, k):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(20, k, 3)) * rng.uniform(0.1, 10, size=(20, 1, 1))
    q = rng.normal(size=(k, 3)) * 3
    pc = p - p.mean(axis=1, keepdims=True)
    qc = q - q.mean(axis=0)
    lb = gyration_bound((pc**2).sum(axis=(1, 2)), float((qc**2).sum()), k)
    assert np.all(lb <= _exact(p, q, "full") + 1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_closed_form_eigenvalues_match_eigvalsh(d):
    rng = np.random.default_rng(d)
    a = rng.normal(size=(200, d, d))
    a = a @ a.transpose(0, 2, 1)
    a[:20] = np.eye(d) * 2.0  # repeated eigenvalues
    a[20:40, :, -1] = a[20:40, -1, :] = 0.0  # singular
    np.testing.assert_allclose(sym_eigvals(a), np.linalg.eigvalsh(a)[:, ::-1], atol=1e-6)


def _speed_term(x: np.ndarray, k: int, dil: int, tau_q: np.ndarray, ell: float) -> np.ndarray:
    """ℓ·RMS(τ_w − τ_q) of every window of sample indices x, as the search scores it."""
    xw = _windows(x[:, None], k, dil)[..., 0]
    dur = xw[:, -1] - xw[:, 0]
    still = dur <= 1e-9
    tau_w = (xw - xw[:, :1]) / np.where(still, 1.0, dur)[:, None]
    tau_w[still] = tau_q
    return ell * np.sqrt(np.mean((tau_w - tau_q) ** 2, axis=1))


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    k=st.integers(3, 30),
    dil=st.integers(1, 3),
    parts=st.integers(1, 8),
    offset=st.sampled_from([0.0, 1e3, 1e6]),
)
def test_speed_bound_never_exceeds_the_exact_speed_term(seed, k, dil, parts, offset):
    rng = np.random.default_rng(seed)
    m = 60 + (k - 1) * dil
    # non-decreasing sample indices with stationary stretches (x does not advance)
    steps = rng.exponential(size=m) * (rng.uniform(size=m) > 0.2)
    x = offset + np.concatenate([[0.0], np.cumsum(steps[1:])])
    tau_q = np.concatenate([[0.0], np.sort(rng.uniform(size=k - 2)), [1.0]]) if k > 2 else (
        np.array([0.0, 1.0])[:k])  # fmt: skip
    ell = rng.uniform(0.1, 100.0)
    exact = _speed_term(x, k, dil, tau_q, ell)
    n = exact.size
    csum = strided_cumsum(x, dil)
    sliced = speed_bound(csum, x, (0, n), dil, tau_q, ell, parts)
    gathered = speed_bound(csum, x, np.arange(n), dil, tau_q, ell, parts)
    np.testing.assert_allclose(sliced, gathered, rtol=1e-14, atol=1e-14 * ell)
    # the groups computed once for a query (as the screen passes them): the same bound
    given = speed_bound(csum, x, (0, n), dil, tau_q, ell, parts, speed_groups(tau_q, parts))
    np.testing.assert_array_equal(given, sliced)
    assert np.all(sliced <= exact + 1e-12 * ell), np.max(sliced - exact)
    # the screen keeps every window whose bound (so every one whose exact term) is below
    # the limit, and drops most of the others
    two = speed_bound(csum, x, (0, n), dil, tau_q, ell, 2)
    for limit in np.quantile(exact, [0.1, 0.5, 0.9]):
        kept = speed_screen(csum, x, (0, n), dil, tau_q, ell, limit)
        assert np.all(kept[two < limit]) and np.all(kept[exact < limit])
        assert not np.any(kept[two > limit * (1 + 1e-6) + 1e-9 * ell])
        # the windows gathered by index: the same mask
        some = np.flatnonzero(rng.random(n) < 0.3)
        np.testing.assert_array_equal(
            speed_screen(csum, x, some, dil, tau_q, ell, limit), kept[some]
        )
        groups = speed_groups(tau_q, 2)
        np.testing.assert_array_equal(
            speed_screen(csum, x, (0, n), dil, tau_q, ell, limit, groups=groups), kept
        )


def test_speed_bound_is_not_vacuous_and_tightens_with_groups():
    # a speed profile unlike the query's: the bound recovers most of the exact term
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.uniform(0.2, 3.0, size=400))
    k, ell = 20, 10.0
    tau_q = np.linspace(0.0, 1.0, k) ** 1.5
    exact = _speed_term(x, k, 1, tau_q, ell)
    csum = strided_cumsum(x, 1)
    n = exact.size
    two = speed_bound(csum, x, (0, n), 1, tau_q, ell, 2)
    eight = speed_bound(csum, x, (0, n), 1, tau_q, ell, 8)
    assert np.all(two <= eight + 1e-12)
    assert np.median(eight / exact) > 0.6


@pytest.mark.parametrize("rotation", ["full", "none", "z"])
def test_gathered_half_window_bound_equals_the_sliced_one(rotation):
    rng = np.random.default_rng(7)
    pts = np.cumsum(rng.normal(size=(40000, 3)), axis=0)
    qc = np.cumsum(rng.normal(size=(12, 3)), axis=0)
    qc -= qc.mean(axis=0)
    dil = 2
    psum, pmax, radius = strided_prefix_sums(pts, dil)
    query = QueryMoments.of(qc)
    margin = half_bound_margin(12, 3, pmax, radius)
    n = pts.shape[0] - 11 * dil
    starts = np.sort(rng.choice(n, size=20000, replace=False))  # more than one block
    if rotation == "full":
        every = half_window_bound(psum, n, dil, query, margin)
        some = half_window_bound(psum, starts.size, dil, query, margin, starts)
    else:
        every = half_window_bound_fixed(psum, n, dil, query, margin, rotation)
        some = half_window_bound_fixed(psum, starts.size, dil, query, margin, rotation, starts)
    # the same arithmetic on the same columns; einsum may sum in another order, which the
    # cancellations of window sums amplify, but never beyond the round-off margin
    np.testing.assert_allclose(some, every[starts], rtol=0, atol=margin * np.sqrt(3))


def _one_pass_prefix_sums(pts, dil, products):
    """strided_prefix_sums as one pass: every row filled, then np.cumsum over all of it."""
    m, d = pts.shape
    pairs = [(a, a) for a in range(d)] + [(a, b) for a in range(d) for b in range(a + 1, d)]
    pairs = pairs[:d] if products == "squares" else pairs if products else []
    buf = np.zeros((d + 1 + len(pairs), -(-m // dil) + 1, dil))
    flat = buf.reshape(buf.shape[0], -1)
    flat[:d, dil : dil + m] = pts.T
    for i, (a, b) in enumerate(pairs):
        flat[d + 1 + i, dil : dil + m] = flat[a, dil : dil + m] * flat[b, dil : dil + m]
    for a in range(d):
        flat[d, dil : dil + m] += flat[a, dil : dil + m] * flat[a, dil : dil + m]
    radius = float(np.sqrt(flat[d].max())) if m else 0.0
    np.cumsum(buf, axis=1, out=buf)
    return flat, np.abs(flat).max(axis=1), radius


@pytest.mark.parametrize("dil", [1, 2, 3])
@pytest.mark.parametrize("m", [0, 1, 5, (1 << 14) - 2, (1 << 14) + 7, 40_000])
def test_prefix_sums_by_spans_equal_one_pass_to_the_last_bit(dil, m):
    # spans of columns summed in cache, two sequences at once as complex numbers: the same
    # additions in the same order as one np.cumsum over everything (signs of zeros too)
    rng = np.random.default_rng(m + dil)
    pts = rng.normal(size=(m, 3)) * 10.0 ** rng.uniform(-3, 3, size=(m, 1))
    pts[rng.random(m) < 0.05] = -0.0
    for products in (False, "squares", True):
        got = strided_prefix_sums(pts, dil, products)
        want = _one_pass_prefix_sums(pts, dil, products)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(np.signbit(got[0]), np.signbit(want[0]))
        np.testing.assert_array_equal(got[1], want[1])
        assert got[2] == want[2]


@pytest.mark.parametrize("rows", [slice(0, 3), slice(0, 4), slice(4, 7), slice(0, 10)])
def test_gathered_columns_are_the_fancy_index_in_its_layout(rows):
    # the bounds' gathered columns (np.take row by row) hold the values psum[rows, idx]
    # holds, laid out as it lays them: the arithmetic after it (np.einsum among it) then
    # gives the same bits
    rng = np.random.default_rng(rows.start + rows.stop)
    psum = rng.normal(size=(10, 5000))
    starts = np.sort(rng.choice(4000, size=700, replace=False))
    for view in (psum, psum[:, 100:]):
        got = _columns(view, rows, starts, 50, 650, 17)
        want = view[rows, starts[50:650] + 17]
        np.testing.assert_array_equal(got, want)
        assert got.strides == want.strides
