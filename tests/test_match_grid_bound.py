"""The grid's bounds that drop windows before they are resampled (``_grid_bound``): each is
below what it bounds, and the pruned grid returns the seeds of every window scored."""

import math

import numpy as np
import pytest
from _reference_search import every_window_seeds
from match_helpers import every_window_score, smooth_walk
from numpy.lib.stride_tricks import sliding_window_view

from primlib.match import BankIndex, kabsch
from primlib.match._bounds import gyration_bound
from primlib.match._grid import GridSearch, _Query
from primlib.match._grid_bound import (
    Best,
    beyond,
    endpoint_gap,
    gyration_below,
    speed_bounds,
    window_energies,
)
from primlib.match._interp import cubic_at
from primlib.match._options import PathPiece, SearchOptions
from primlib.store import Bank

DT = 0.01
K = 16


def _rotation(rng, rotation: str) -> np.ndarray:
    if rotation == "none":
        return np.eye(3)
    if rotation == "z":
        t = rng.uniform(0, 2 * np.pi)
        return np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    r = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    return r * np.sign(np.linalg.det(r))


def _walk(rng, n: int, speed: float, dwell: bool = False) -> np.ndarray:
    """A smooth random 3-D curve of n samples moving ~``speed`` a sample (a stop in the
    middle with ``dwell``)."""
    return smooth_walk(rng, n, speed, rest=slice(n // 3, n // 2) if dwell else None)


def _bank(rng, k: int = 6, n: int = 300, still: bool = True) -> BankIndex:
    """Smooth primitives; with ``still``, some stop a while, one never moves."""
    prims = [_walk(rng, n, rng.uniform(0.02, 0.3), dwell=still and i % 3 == 0) for i in range(k)]
    if still:
        prims.append(rng.normal(size=3) + np.zeros((40, 3)))
    prims.append(_walk(rng, 3, 0.1))  # and one of 3 samples
    return BankIndex(Bank.from_samples(prims, DT))


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
def test_the_endpoint_bound_is_below_the_rmsd(rotation):
    # K ρ² >= |e_1|² + |e_K|² >= |R c_w − c_q|²/2 >= g(c_w)²/2 for every motion
    rng = np.random.default_rng(1)
    q = _walk(rng, K, 0.1)
    near = q @ _rotation(rng, rotation).T + rng.normal(size=(400, K, 3)) * 0.01
    far = rng.normal(size=(400, K, 3)) * rng.uniform(0.001, 3.0, (400, 1, 1))
    for w in (near, far, np.repeat(q[None], 3, axis=0)):
        rmsd = kabsch(w, np.broadcast_to(q, w.shape), rotation=rotation).rmsd
        gap = endpoint_gap(w[:, -1] - w[:, 0], q[-1] - q[0], rotation) / math.sqrt(2 * K)
        assert np.all(gap <= rmsd + 1e-12)
    # g is the least |R c − c_q| of the family: a rotation of c_q's own chord reaches 0
    c = q[-1] - q[0]
    np.testing.assert_allclose(endpoint_gap((c @ _rotation(rng, rotation).T)[None], c, rotation),
                               0.0, atol=1e-12)  # fmt: skip


def test_the_speed_bound_is_above_the_interpolants_speed():
    # |P'| <= |d_i| + max(|d_{i−1} − d_i|, |d_{i+1} − d_i|)/2 on the interval i, ends clamped
    rng = np.random.default_rng(2)
    prims = [rng.normal(size=(n, 3)) * s for n, s in ((2, 1.0), (3, 5.0), (50, 0.1), (60, 3.0))]
    prims.append(_walk(rng, 80, 0.2))
    bank = BankIndex(Bank.from_samples(prims, DT))
    speed = speed_bounds(bank.points, bank.offsets)
    for p in range(bank.k):
        count = int(bank.counts[p])
        x = np.linspace(0.0, count - 1, 4001)
        _, dx = cubic_at(bank.points, bank.offsets[p], count, x, derivative=True)
        interval = np.minimum(np.floor(x).astype(int), count - 2)
        bound = speed[bank.offsets[p] + interval]
        assert np.all(np.linalg.norm(dx, axis=1) <= bound * (1 + 1e-12) + 1e-15)


def _query(bank: BankIndex, rng, kind: str, rotation: str) -> tuple[PathPiece, float]:
    """A path piece and eps: a noisy, rotated, time-scaled copy of a stored stretch, a
    stationary piece, a piece of 3 samples, or a slow piece against faster primitives."""
    if kind == "stationary":
        pts = np.zeros((30, 3)) + rng.normal(size=3) + rng.normal(size=(30, 3)) * 1e-9
        return PathPiece(pts, 29 * DT), 1e-3
    if kind == "slow":
        return PathPiece(_walk(rng, 34, 0.004), 33 * DT), 0.002
    p = int(rng.integers(0, bank.k - 2))
    s0 = int(rng.integers(0, bank.counts[p] - 70))
    n = 3 if kind == "tiny" else int(rng.integers(20, 60))
    x = np.linspace(s0, s0 + rng.uniform(0.6, 1.6) * (n - 1), n)
    pts = cubic_at(bank.points, bank.offsets[p], bank.counts[p], x)
    pts = pts @ _rotation(rng, rotation).T + rng.normal(size=pts.shape) * 1e-3
    return PathPiece(pts, (n - 1) * DT), 0.02


@pytest.mark.parametrize("rotation", ["full", "z", "none"])
@pytest.mark.parametrize("kind", ["copy", "stationary", "tiny", "slow"])
@pytest.mark.parametrize(("seed", "few"), [(0, 0), (1, 0), (2, 0), (0, None), (1, None)])
def test_the_pruned_grid_returns_the_seeds_of_every_window_scored(rotation, kind, seed, few):
    # no window that could be a seed is dropped: the same windows as scoring every one,
    # their RMSDs those of one Kabsch call per window to round-off
    rng = np.random.default_rng(100 * seed + len(kind))
    bank = _bank(rng, still=kind != "slow")
    path, eps = _query(bank, rng, kind, rotation)
    a, b = (0.0, 1.0) if seed != 2 else (0.25, 0.75)
    opts = SearchOptions(rotation=rotation, time_scale=(0.5, 2.0) if seed else (1.0, 1.0))
    pruned = GridSearch(bank, opts)
    if few is not None:  # stretches of s > 1 windows at every scale (s = 1 on small ones)
        pruned.few = few
    got = pruned.seeds(path, a, b, eps)
    every = GridSearch(bank, opts)
    want = every_window_seeds(every, path, a, b, eps, every_window_score(rotation, K))
    assert [(c.prim, c.x0, c.x1) for c in got] == [(c.prim, c.x0, c.x1) for c in want]
    # ρ from moments loses ~u·(Σ|p̃|² + Σ|q̃|²)/(2Kρ) to cancellation, its eigenvalue route
    # depending on the batch it is in: ~1e-14 here
    np.testing.assert_allclose([c.score for c in got], [c.score for c in want], rtol=1e-9,
                               atol=1e-12)  # fmt: skip
    q = path.at(np.linspace(a, b, K))
    for c in got:
        pts = cubic_at(bank.points, bank.offsets[c.prim], bank.counts[c.prim],
                       np.linspace(c.x0, c.x1, K))  # fmt: skip
        assert c.score == pytest.approx(kabsch(pts, q, rotation=rotation).rmsd, abs=1e-9)
    assert pruned.stats.windows == every.stats.windows
    assert pruned.stats.scored <= every.stats.scored
    if kind == "slow":  # a slow piece against fast primitives: nearly every window out
        assert pruned.stats.scored < 0.05 * every.stats.scored


def test_a_stretch_bound_is_below_every_window_of_its_stretch_and_its_gate_above():
    rng = np.random.default_rng(7)
    bank = _bank(rng, k=5, n=400)
    path, eps = _query(bank, rng, "copy", "full")
    for rotation in ("full", "z", "none"):
        grid = GridSearch(bank, SearchOptions(rotation=rotation))
        q = path.at(np.linspace(0.0, 1.0, K))
        query = _Query.of(q, rotation)
        for sc in grid._scales(path, 0.0, 1.0):
            for few in (0, grid.few):
                grid.few = few
                _check_stretches(grid, grid._stretches(sc, query, eps), sc, q, eps)


def _check_stretches(grid: GridSearch, st, sc, q: np.ndarray, eps: float) -> None:
    """Every window of every stretch: its endpoint bound at or above the stretch's, its
    gate at or below the stretch's."""
    bank, rotation = grid.bank, grid.opts.rotation
    m = st.first[:, None] + np.arange(st.s)
    ok = np.arange(st.s) < st.count[:, None]
    mm, pp = m[ok], np.broadcast_to(st.prim[:, None], m.shape)[ok]
    assert mm.size == sc.n_start.sum()  # each window in one stretch
    ends = cubic_at(bank.points, bank.offsets[pp], bank.counts[pp], (mm + K - 1) * sc.h)
    starts = cubic_at(bank.points, bank.offsets[pp], bank.counts[pp], mm * sc.h)
    gap = endpoint_gap(ends - starts, q[-1] - q[0], rotation) / math.sqrt(2 * K)
    assert np.all(gap >= np.broadcast_to(st.bound[:, None], m.shape)[ok] - 1e-12)
    slack = grid._slack(pp, mm * sc.h, sc)
    assert np.all(eps + slack <= np.broadcast_to(st.gate[:, None], m.shape)[ok])


def test_best_keeps_the_best_windows_by_rmsd_then_window():
    best = Best(3)
    assert best.limit() == math.inf
    best.add(np.array([0.3, 0.1, 0.2]), np.array([5, 1, 2]), np.array([0.0, 4.0, 1.0]))
    best.add(np.array([0.1, 0.2, 0.05]), np.array([0, 2, 9]), np.array([9.0, 0.5, 3.0]))
    assert best.rmsd.tolist() == [0.05, 0.1, 0.1]
    assert best.prim.tolist() == [9, 0, 1] and best.limit() == 0.1


def test_a_bound_is_beyond_a_limit_only_past_the_round_off_margin():
    # at the limit (and within ~1e-9 relative) a window is kept: its RMSD may round below
    assert not beyond(np.array([0.1]), 0.1, 1.0, 0.0)[0]
    assert not beyond(np.array([0.1 + 1e-12]), 0.1, 1.0, 0.0)[0]
    assert beyond(np.array([0.1001]), 0.1, 1.0, 0.0)[0]
    assert not beyond(np.array([0.1001]), 0.1, 1.0, 1e-3)[0]  # within the chords' slack
    assert beyond(np.array([1.0]), math.inf, 1.0, 0.0).tolist() == [False]


@pytest.mark.parametrize("offset", [0.0, 1e3])
def test_stretch_energies_hold_the_centred_ones_and_their_gyration_bound(offset):
    # stretches of 20 points, far from the origin or not, moving fast, slowly or not at all:
    # the energies from running sums lie within their margin of the windows centred on their
    # own means (as GridSearch._score takes them), and the bound from that interval is below
    # the radius-of-gyration bound the centred energies give
    rng = np.random.default_rng(7 + int(offset))
    speed = np.array([0.0, 1e-9, 1e-4, 0.3])[rng.integers(0, 4, 240)]
    steps = rng.normal(size=(240, 20, 3)) * speed[:, None, None]
    rows = offset + rng.normal(size=(240, 1, 3)) + np.cumsum(steps, axis=1)
    energy, err = window_energies(rows, K, float(np.abs(rows).max()))
    win = sliding_window_view(rows, K, axis=1)  # (n, 5, 3, K)
    win = win - win.mean(axis=3, keepdims=True)
    centred = np.einsum("ntdk,ntdk->nt", win, win)
    assert energy.shape == centred.shape == (240, 5)
    assert np.all(np.abs(energy - centred) <= err)
    for q_energy in (0.0, float(np.median(centred)), 10.0 * float(centred.max())):
        exact = gyration_bound(centred.ravel(), q_energy, K).reshape(centred.shape)
        below = gyration_below(energy, err, q_energy, K)
        assert np.all(below <= exact)
        # and not much below: within the margin's effect where the energy is well above it
        tight = energy > 1e3 * err
        assert np.allclose(below[tight], exact[tight], rtol=1e-6, atol=1e-9 * (1 + offset))
