"""The roughness bound (``_rough``): R_j holds over every window of a primitive (sampled
between samples, at every step in the range), the lower bound never exceeds the exact Kabsch
RMSD in any rotation family, and a noisy path is cut as without it, with fewer windows."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from match_helpers import bundled_bank

from primlib.match import BankIndex, kabsch, segment_path
from primlib.match import _step_back as step_back
from primlib.match._interp import cubic_at
from primlib.match._rough import (
    BANK_MAX,
    Roughness,
    query_roughness,
    rough_bounds,
    rough_scales,
)
from primlib.store import Bank


def _bank(rng, d: int) -> BankIndex:
    """Smooth walks (splines of a few knots) and one rough one, of a few sizes."""
    pieces = []
    for n, knots in ((12, 3), (90, 6), (150, 12), (60, 60)):
        at = np.linspace(0, 1, knots)
        ctrl = np.cumsum(rng.normal(size=(knots, d)), axis=0) * rng.uniform(0.5, 20.0)
        t = np.linspace(0, 1, n)
        pieces.append(np.stack([np.interp(t, at, ctrl[:, a]) for a in range(d)], axis=1))
    return BankIndex(Bank.from_samples(pieces, dt=0.01))


def _windows(rng, index: BankIndex, j: int, k: int, h_lo: float, h_hi: float, m: int = 40):
    """m windows of k points of primitive j at steps in [h_lo, h_hi] (starts anywhere, the
    range's ends among them), or None when the primitive cannot hold one."""
    n = int(index.counts[j])
    h = np.concatenate([[h_lo, h_hi], rng.uniform(h_lo, h_hi, m - 2)])
    h = h[(k - 1) * h <= n - 1]
    if h.size == 0:
        return None
    x0 = rng.uniform(0, 1, h.size) * (n - 1 - (k - 1) * h)
    x = x0[:, None] + h[:, None] * np.arange(k)
    return cubic_at(index.points, index.offsets[j], n, x.ravel()).reshape(h.size, k, -1)


def _projected(w: np.ndarray) -> np.ndarray:
    """‖(I − P) w‖ of each window (m, k, d), P the cubics in the sample index."""
    k = w.shape[1]
    t = np.arange(k, dtype=float) - 0.5 * (k - 1)
    basis = np.linalg.qr(np.vander(t, 4, increasing=True))[0]
    res = w - np.einsum("kc,lc,mld->mkd", basis, basis, w)
    return np.sqrt(np.einsum("mkd,mkd->m", res, res))


@pytest.mark.parametrize("tight", [False, True])
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.sampled_from([2, 3]), k=st.integers(5, 16),
       lo=st.floats(0.2, 4.0), width=st.floats(1.0, 4.0))  # fmt: skip
def test_no_window_is_rougher_than_its_primitives_bound(tight, seed, d, k, lo, width):
    rng = np.random.default_rng(seed)
    index = _bank(rng, d)
    rough = Roughness(index.points, index.offsets)
    bound = rough.bound(k, lo, lo * width, tight=tight)
    for j in range(index.k):
        w = _windows(rng, index, j, k, lo, lo * width)
        if w is not None:
            assert np.all(_projected(w) <= bound[j]), (j, _projected(w).max(), bound[j])


@pytest.mark.parametrize("tight", [False, True])
@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(5, 16), noise=st.floats(0.01, 3.0))
def test_the_lower_bound_never_exceeds_the_exact_rmsd(tight, seed, k, noise):
    rng = np.random.default_rng(seed)
    index = _bank(rng, 3)
    j = int(rng.integers(1, index.k))
    piece = _windows(rng, index, j, k, 0.5, 2.0, m=3)[2]
    q = piece + rng.normal(size=piece.shape) * noise + rng.normal(size=3) * 50
    # steps = (k − 1): h of a window at time scale s is s, so (0.5, 2) is the range drawn
    rough = Roughness(index.points, index.offsets)
    lb = rough_bounds(rough, q, k - 1.0, (0.5, 2.0), eps=0.0, tight=tight)
    assert lb is not None
    for r in range(index.k):
        w = _windows(rng, index, r, k, 0.5, 2.0)
        if w is None:
            continue
        for rotation in ("full", "none", "z"):
            exact = kabsch(w, np.broadcast_to(q, w.shape), rotation=rotation).rmsd
            assert np.all(lb[r] <= exact), (rotation, r, lb[r], exact.min())


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(5, 16), noise=st.floats(0.05, 3.0),
       share=st.floats(0.3, 0.9))  # fmt: skip
def test_no_window_outside_a_primitives_time_scales_is_within_eps(seed, k, noise, share):
    # the time scales rough_scales keeps per primitive: every window at a time scale outside
    # them is at least eps from the piece (any rotation), and a primitive keeps none exactly
    # where the bound over the whole range excludes it
    rng = np.random.default_rng(seed)
    index = _bank(rng, 3)
    j = int(rng.integers(1, index.k))
    piece = _windows(rng, index, j, k, 0.5, 2.0, m=3)[2]
    q = piece + rng.normal(size=piece.shape) * noise
    eps = share * query_roughness(q) / np.sqrt(k)  # rough enough to narrow something
    rough = Roughness(index.points, index.offsets)
    lo, hi = rough_scales(rough, q, k - 1.0, (0.25, 4.0), eps)  # h of a window = its scale
    lb = rough_bounds(rough, q, k - 1.0, (0.25, 4.0), eps)
    assert np.array_equal(lo > hi, lb >= eps * (1 + 1e-9))
    for r in range(index.k):
        assert lo[r] > hi[r] or 0.25 <= lo[r] <= hi[r] <= 4.0
        for a, b in ((0.25, min(lo[r], 4.0)), (max(hi[r], 0.25), 4.0)):
            w = _windows(rng, index, r, k, a, b) if b > a * (1 + 1e-6) else None
            if w is None:
                continue
            exact = kabsch(w, np.broadcast_to(q, w.shape), rotation="full").rmsd
            assert np.all(exact >= eps * (1 - 1e-9)), (r, a, b, exact.min(), eps)


def test_catmull_rom_holds_quadratics_and_misses_a_cubic_by_the_periodic_error():
    m = np.arange(-3.0, 9.0)
    pts = np.stack([m**3, m**2, m], axis=1)
    f = np.linspace(0.0, 1.0, 101)
    x = 4.0 + f  # well inside: sample 3 is m = 0
    v = cubic_at(pts, 0, m.size, x + 3.0)
    g = f * (1 - f) * (1 - 2 * f)
    assert np.allclose(v[:, 0], x**3 + g, atol=1e-12)
    assert np.allclose(v[:, 1:], np.stack([x**2, x], axis=1), atol=1e-12)
    assert np.max(np.abs(g)) <= np.sqrt(3) / 18 + 1e-12


def test_a_smooth_piece_asks_for_nothing_and_a_large_bank_builds_no_table():
    # (a large bank's bound is from the differences instead: tests/test_match_rough_diff.py)
    rng = np.random.default_rng(3)
    index = _bank(rng, 3)
    smooth = index.points_of(2)[10:22]
    assert query_roughness(smooth[:4]) == 0.0
    assert rough_bounds(index.roughness(), smooth, 11.0, (0.25, 4.0), eps=1.0) is None
    big = BankIndex(Bank.from_samples([np.zeros((BANK_MAX + 1, 3))], dt=0.01))
    assert not isinstance(big.roughness(), Roughness)


@pytest.mark.parametrize("level", [0.001, 0.01])
def test_a_noisy_path_is_cut_as_without_the_bound_with_fewer_windows(level, monkeypatch):
    # a stored piece with white noise at a quarter of the eps the noise needs (issue 13's
    # unmatched queries): the same segments either way, fewer windows bounded with it
    bank = bundled_bank()
    index = BankIndex(bank)
    rng = np.random.default_rng(7)
    clean = index.points_of(5)[100:340]
    sigma = level * float(np.ptp(clean, axis=0).max())
    pts = clean + rng.normal(size=clean.shape) * sigma
    eps = sigma * np.sqrt(3) / 4
    runs = []
    for off in (True, False):
        if off:
            monkeypatch.setattr(BankIndex, "roughness", lambda self: None)
        else:
            monkeypatch.undo()
        # every start searched, as before the noisy starts were skipped (test_match_step_back)
        monkeypatch.setattr(step_back, "noisy_start", lambda *args: False)
        segs, info = segment_path(BankIndex(bank), pts, 0.005, eps)
        runs.append(([(s.end, s.primitive) for s in segs], [s.rmsd for s in segs], info))
    (cuts0, rmsd0, info0), (cuts1, rmsd1, info1) = runs
    assert cuts1 == cuts0
    assert np.allclose(rmsd1, rmsd0, rtol=1e-6, equal_nan=True)
    assert info1["bounded"] < info0["bounded"]
