"""The roughness bound of large banks (``_rough_diff``): R_j from the differences holds over
every inside window of a primitive and, with its ends' terms, over every window; its lower
bounds never exceed the exact Kabsch RMSD; and where a primitive's ends move it is far below
the table's, whose R_j its ends set."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_match_rough import _bank

from primlib.match import BankIndex, kabsch, segment_path
from primlib.match._interp import cubic_at
from primlib.match._rough import Roughness, query_roughness
from primlib.match._rough_diff import DiffRoughness, constants, diff_scales
from primlib.store import Bank


def _waves(rng, d: int) -> BankIndex:
    """Smooth primitives of a few sinusoids whose ends move at speed (as 1,000 random
    primitives' do), of a few sizes, and one rough one."""
    pieces = []
    for n in (40, 120, 300):
        t = np.linspace(0.0, 1.0, n)[:, None, None]
        f = np.arange(1, 4)[None, :, None]
        amp = rng.normal(size=(1, 3, d)) * rng.uniform(1.0, 30.0) / f**1.5
        pieces.append((amp * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3, (1, 3, d)))).sum(1))
    pieces.append(np.cumsum(rng.normal(size=(60, d)), axis=0))
    return BankIndex(Bank.from_samples(pieces, dt=0.01))


def _any_bank(rng, d: int, waves: bool) -> BankIndex:
    return _waves(rng, d) if waves else _bank(rng, d)


def _windows(rng, index: BankIndex, j: int, k: int, h_lo: float, h_hi: float, inside: bool,
             m: int = 40):  # fmt: skip
    """m windows of k points of primitive j at steps in [h_lo, h_hi]: with ``inside`` all
    their points in [1, n − 2], else starting anywhere (the first interval among them); None
    when the primitive cannot hold one."""
    n = int(index.counts[j])
    room = n - 3 if inside else n - 1
    h = np.concatenate([[h_lo, h_hi], rng.uniform(h_lo, h_hi, m - 2)])
    h = h[(k - 1) * h <= room]
    if h.size == 0:
        return None
    x0 = rng.uniform(0, 1, h.size) * (room - (k - 1) * h)
    if not inside:
        x0[: h.size // 4] = rng.uniform(0, 1, h.size // 4)  # a quarter in the first interval
    x = (1.0 if inside else 0.0) + x0[:, None] + h[:, None] * np.arange(k)
    return cubic_at(index.points, index.offsets[j], n, x.ravel()).reshape(h.size, k, -1)


def _projected(w: np.ndarray, p: int) -> np.ndarray:
    """‖(I − P_p) w‖ of each window (m, k, d), P_p the polynomials of degree p."""
    k = w.shape[1]
    t = np.arange(k, dtype=float) - 0.5 * (k - 1)
    basis = np.linalg.qr(np.vander(t, p + 1, increasing=True))[0]
    res = w - np.einsum("kc,lc,mld->mkd", basis, basis, w)
    return np.sqrt(np.einsum("mkd,mkd->m", res, res))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.sampled_from([2, 3]), k=st.integers(5, 16),
       lo=st.floats(0.2, 4.0), width=st.floats(1.0, 4.0), p=st.sampled_from([2, 3]),
       waves=st.booleans())  # fmt: skip
def test_no_window_is_rougher_than_its_primitives_bound(seed, d, k, lo, width, p, waves):
    rng = np.random.default_rng(seed)
    index = _any_bank(rng, d, waves)
    inside, every = DiffRoughness(index.points, index.offsets).bound(k, lo, lo * width, p)
    assert np.all(inside <= every)
    for j in range(index.k):
        for part, bound in ((True, inside), (False, every)):
            w = _windows(rng, index, j, k, lo, lo * width, part)
            if w is not None:
                assert np.all(_projected(w, p) <= bound[j]), (j, part, _projected(w, p).max())


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(5, 16), noise=st.floats(0.01, 3.0),
       waves=st.booleans())  # fmt: skip
def test_the_lower_bounds_never_exceed_the_exact_rmsd(seed, k, noise, waves):
    rng = np.random.default_rng(seed)
    index = _any_bank(rng, 3, waves)
    j = int(rng.integers(1, index.k))
    piece = _windows(rng, index, j, k, 0.5, 2.0, False, m=3)[2]
    q = piece + rng.normal(size=piece.shape) * noise + rng.normal(size=3) * 50
    # steps = (k − 1): h of a window at time scale s is s, so (0.5, 2) is the range drawn
    table = DiffRoughness(index.points, index.offsets)
    for p in (2, 3):
        rq = query_roughness(q, p)
        for part, r in zip((True, False), table.bound(k, 0.5, 2.0, p), strict=True):
            lb = (rq - r) / np.sqrt(k)
            for j2 in range(index.k):
                w = _windows(rng, index, j2, k, 0.5, 2.0, part)
                if w is None:
                    continue
                for rotation in ("full", "none", "z"):
                    exact = kabsch(w, np.broadcast_to(q, w.shape), rotation=rotation).rmsd
                    assert np.all(lb[j2] <= exact), (p, rotation, j2, part, lb[j2], exact.min())


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(5, 16), noise=st.floats(0.05, 3.0),
       share=st.floats(0.3, 0.9), waves=st.booleans())  # fmt: skip
def test_no_window_outside_its_time_scales_is_within_eps(seed, k, noise, share, waves):
    # the time scales diff_scales keeps per primitive, for its inside windows and for all:
    # every window at a time scale outside its range is at least eps from the piece
    rng = np.random.default_rng(seed)
    index = _any_bank(rng, 3, waves)
    j = int(rng.integers(1, index.k))
    piece = _windows(rng, index, j, k, 0.5, 2.0, False, m=3)[2]
    q = piece + rng.normal(size=piece.shape) * noise
    eps = share * query_roughness(q, 3) / np.sqrt(k)  # rough enough to narrow something
    table = DiffRoughness(index.points, index.offsets)
    lo_in, hi_in, lo_all, hi_all = diff_scales(table, q, k - 1.0, (0.25, 4.0), eps)
    for r in range(index.k):
        for part, lo, hi in ((True, lo_in[r], hi_in[r]), (False, lo_all[r], hi_all[r])):
            assert lo > hi or 0.25 <= lo <= hi <= 4.0
            for a, b in ((0.25, min(lo, 4.0)), (max(hi, 0.25), 4.0)):
                w = _windows(rng, index, r, k, a, b, part) if b > a * (1 + 1e-6) else None
                if w is None:
                    continue
                exact = kabsch(w, np.broadcast_to(q, w.shape), rotation="full").rmsd
                assert np.all(exact >= eps * (1 - 1e-9)), (r, part, a, b, exact.min(), eps)
        # the inside keeps no more than the whole primitive
        assert lo_in[r] > hi_in[r] or lo_all[r] <= lo_in[r] <= hi_in[r] <= hi_all[r]


def test_moving_ends_set_the_tables_bound_and_not_the_insides():
    # smooth primitives that start and stop moving at speed: the table's R_j (every support,
    # the ghost's kink among them) is the ends'; the inside's is more than 20 times smaller,
    # and the ends' terms are most of this module's bound on every window (below the table's)
    t = np.linspace(0.0, 1.0, 400)[:, None]
    f = np.arange(1, 4)[None, :]
    pieces = [np.stack([np.sin(2 * np.pi * (f * t + a)).sum(axis=1) * 20 for a in (0.1, 0.3, 0.7)],
                       axis=1) for _ in range(2)]  # fmt: skip
    index = BankIndex(Bank.from_samples(pieces, dt=0.01))
    table = Roughness(index.points, index.offsets).bound(8, 1.0, 2.0)
    inside, every = DiffRoughness(index.points, index.offsets).bound(8, 1.0, 2.0, 3)
    assert np.all(inside < 0.05 * table)
    assert np.all((every > 5.0 * inside) & (every < table))


def test_a_polynomial_is_its_own_fit_and_the_constants_grow_with_the_support():
    m = np.arange(12.0)[:, None]
    for p in (2, 3):
        poly = np.hstack([m**p, m, np.ones_like(m)])
        assert query_roughness(poly, p) == 0.0
        assert query_roughness(poly + np.eye(12)[:, :3], p) > 0.5
    for p in (2, 3):
        c = [constants(n, p)[0] for n in range(p + 2, 30)]
        assert np.all(np.diff(c) > 0)
    # a fourth-degree sequence: its (I − P_3) residual is c_3 · its fourth difference at most
    x = (np.arange(20.0) ** 4 / 24.0)[:, None]
    assert query_roughness(x, 3) <= constants(20, 3)[0] * 1.0 + 1e-9


@pytest.mark.parametrize("n", [3, 4])
def test_a_primitive_too_short_for_the_differences_is_never_excluded(n):
    pts = np.concatenate([np.zeros((n, 3)), np.arange(30.0)[:, None] * np.ones(3)])
    table = DiffRoughness(pts, np.array([0, n, n + 30]))
    inside, every = table.bound(5, 1.0, 1.0, 3)
    assert np.isinf(inside[0]) and np.isinf(every[0])
    assert np.isfinite(inside[1]) and inside[1] < 1e-4  # a straight line: the round-off margin


def test_a_large_banks_search_keeps_the_windows_that_read_a_ghost(monkeypatch):
    # a piece copied from a primitive's first samples, where its interpolant reads the
    # ghost: rough (its end moves fast), so every primitive's inside is excluded, and the
    # windows near the ends alone are searched; the copy is found there
    import primlib.match._bank as bank_module

    monkeypatch.setattr(bank_module, "BANK_MAX", 1000)  # this bank is "large"
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.0, 1000)[:, None, None]
    f = np.arange(1, 4)[None, :, None]
    pieces = [(rng.normal(size=(1, 3, 3)) * 40.0 / f**1.5
               * np.sin(2 * np.pi * f * t + rng.uniform(0, 6.3, (1, 3, 3)))).sum(1)
              for _ in range(12)]  # fmt: skip
    index = BankIndex(Bank.from_samples(pieces, dt=0.01))
    assert isinstance(index.roughness(), DiffRoughness)
    j, k = 7, 12
    x = 0.3 + np.arange(k, dtype=float)
    piece = cubic_at(index.points, index.offsets[j], int(index.counts[j]), x)
    piece = piece + rng.normal(size=piece.shape) * 1e-4
    eps = 0.6 * query_roughness(piece, 3) / np.sqrt(k)
    table = index.roughness()
    lo_in, hi_in, lo_all, hi_all = diff_scales(table, piece, k - 1.0, (0.6, 1.0), eps)
    assert np.all(lo_in > hi_in)  # no inside window of any primitive is within eps
    assert lo_all[j] <= hi_all[j] == 1.0  # but the ends of the copied one are kept
    segs, _ = segment_path(index, piece, 0.01, eps, time_scale=(0.6, 1.0))
    assert len(segs) == 1 and segs[0].primitive == index.ids[j] and segs[0].rmsd < eps
