"""The moment screen of unmatched starts (``_screen``): its bound never exceeds k·rmsd² of
any stored piece in the duration range (sampled between samples, near-copies included), in
every rotation family; it rejects a piece no primitive can follow and keeps a copy; and
the segmentation is the same with and without it (it only skips what provably fails)."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from primlib.match import BankIndex, _segment, default_eps, kabsch, segment_path
from primlib.match._interp import cubic_at
from primlib.match._screen import SlopeRanges, min_bound, screens
from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import Bank

ROOT = Path(__file__).resolve().parents[1]


def _bank(rng, d: int) -> BankIndex:
    pieces = []
    for n in (40, 90, 150):
        # smooth and rough alike: the bound holds for any samples
        walk = np.cumsum(np.cumsum(rng.normal(size=(n, d)), axis=0), axis=0) * 0.1
        walk += rng.normal(size=(n, d)) * rng.uniform(0.0, 0.5)
        pieces.append(walk * rng.uniform(0.1, 20.0) + rng.normal(size=d) * 100)
    return BankIndex(Bank.from_samples(pieces, dt=0.01))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.sampled_from([2, 3]), k=st.integers(8, 40))
def test_bound_never_exceeds_k_rmsd2_of_any_piece_in_the_duration_range(seed, d, k):
    rng = np.random.default_rng(seed)
    index = _bank(rng, d)
    slopes = SlopeRanges(index.points, index.offsets)
    s = np.linspace(0.0, 1.0, k)
    j0 = int(rng.integers(index.k))
    n0 = int(index.counts[j0])
    d_lo = rng.uniform(0.5, 0.3 * (n0 - 1))
    d_hi = d_lo * rng.uniform(1.0, 4.0)
    # the path piece: a stored piece (so the best pieces come close), moved, with noise
    x0 = rng.uniform(0.0, n0 - 1 - d_lo)
    base = cubic_at(index.points, index.offsets[j0], n0, x0 + d_lo * s)
    q = base + rng.normal(size=(k, d)) * rng.choice([0.0, 1e-3, 0.1]) + rng.normal(size=d)
    rotations = ["full", "none"] + (["z"] if d == 3 else [])
    for rotation in rotations:
        bound = min_bound(slopes, q, d_lo, d_hi, rotation)
        for j in range(index.k):
            n = int(index.counts[j])
            dur = rng.uniform(d_lo, d_hi, size=40)
            dur[:2] = d_lo, d_hi
            ok = dur <= n - 1
            if not np.any(ok):
                continue
            dur = dur[ok]
            x = rng.uniform(0.0, 1.0, size=dur.size) * (n - 1 - dur)
            if j == j0:
                x[0], dur[0] = x0, d_lo  # the piece q was made from
            xs = x[:, None] + dur[:, None] * s
            p = cubic_at(index.points, index.offsets[j], n, xs.ravel()).reshape(-1, k, d)
            exact = kabsch(p, np.broadcast_to(q, p.shape), rotation=rotation).rmsd
            cost = k * exact**2
            assert bound <= cost.min() * (1 + 1e-9) + 1e-12, (rotation, j, bound, cost.min())


@pytest.mark.parametrize("rotation", ["none", "z"])
def test_screens_a_piece_no_primitive_can_follow_but_not_a_copy(rotation):
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 300)[:, None]
    flat = [np.c_[np.cos(4 * t + a), np.sin(3 * t), 0 * t] * 10 for a in rng.uniform(0, 6, 3)]
    index = BankIndex(Bank.from_samples(flat, dt=0.01))
    slopes = SlopeRanges(index.points, index.offsets)
    # a stretch climbing in z: every primitive lies in z = 0, and neither a translation nor a
    # turn about z lifts it
    climb = np.c_[np.zeros(12), np.zeros(12), np.linspace(0.0, 1.0, 12) ** 1.5]
    assert screens(slopes, climb, 3.0, 40.0, rotation, eps=0.05)
    copy = index.points_of(1)[100:120]
    if rotation == "z":
        copy = copy @ Rotation.from_euler("z", 40, degrees=True).as_matrix().T
    assert not screens(slopes, copy + 5.0, 15.0, 25.0, rotation, eps=1e-6)


def _bundled():
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    pieces = [
        Trajectory.from_csv(f).sample(machine.dt)
        for f in sorted((ROOT / "data" / "library").glob("*.csv"))
        if not f.name.endswith(".signal.csv")
    ]
    return Bank.from_samples(pieces, machine.dt), machine.dt


def _walk(rng, n: int, dt: float, m: int) -> Trajectory:
    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 12.0, axis=0)
    knots = np.concatenate([np.zeros(3), np.linspace(0.0, 1.0, m - 2), np.ones(3)])
    return Trajectory.from_definition(3, knots, ctrl, None, (n - 1) * dt)


@pytest.mark.parametrize("rotation", ["none", "z"])
def test_the_segmentation_is_the_same_with_and_without_the_screen(rotation, monkeypatch):
    bank, dt = _bundled()
    n = 1200
    path = _walk(np.random.default_rng(102), n, dt, 8)
    pts = path.at(np.linspace(0.0, 1.0, n))
    eps = default_eps(path)
    runs = []
    for limit in (0, _segment._SCREEN_MAX):
        monkeypatch.setattr(_segment, "_SCREEN_MAX", limit)
        segs, info = segment_path(BankIndex(bank), pts, path.duration / (n - 1), eps,
                                  rotation=rotation)  # fmt: skip
        cuts = [(s.start, s.end, s.primitive, s.rmsd if s.primitive is not None else None)
                for s in segs]  # fmt: skip
        runs.append((cuts, info))
    (without, info0), (with_, info1) = runs
    assert with_ == without
    assert any(p is None for _, _, p, _ in with_)  # unmatched stretches: the screen's case
    assert any(p is not None for _, _, p, _ in with_)
    assert info1["rejected"] > info0["rejected"]  # it screened starts
    assert info1["queries"] < info0["queries"]  # whose searches it spared
