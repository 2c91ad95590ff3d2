"""The probe's up-front rejection (``_reject``): its per-primitive bound never exceeds the
exact Kabsch RMSD of any piece of the primitive (sampled between samples too), in every
rotation family, and it rejects what is plainly too large while keeping a stored copy."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from primlib.match import BankIndex, kabsch
from primlib.match._interp import cubic_at
from primlib.match._reject import lower_bounds, rejects, row_groups
from primlib.store import Bank


def _bank(rng, d: int) -> BankIndex:
    pieces = []
    for n in (40, 90, 150):
        walk = np.cumsum(rng.normal(size=(n, d)), axis=0) * rng.uniform(0.1, 20.0)
        pieces.append(walk + rng.normal(size=d) * 100)
    return BankIndex(Bank.from_samples(pieces, dt=0.01))


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), d=st.sampled_from([2, 3]), k=st.integers(8, 80))
def test_bound_never_exceeds_the_exact_rmsd_of_any_piece(seed, d, k):
    rng = np.random.default_rng(seed)
    index = _bank(rng, d)
    env = index.envelope()
    q = np.cumsum(rng.normal(size=(k, d)), axis=0) * rng.uniform(0.01, 50.0)
    rotations = ["full", "none"] + (["z"] if d == 3 else [])
    for rotation in rotations:
        lb = lower_bounds(env, q, rotation)
        for j in range(index.k):
            n = int(index.counts[j])
            x0 = rng.uniform(0, n - 1, size=30)
            x1 = np.minimum(x0 + rng.uniform(0.5, n, size=30), n - 1)
            x = x0[:, None] + (x1 - x0)[:, None] * np.linspace(0, 1, k)
            p = cubic_at(index.points, index.offsets[j], n, x.ravel()).reshape(30, k, d)
            exact = kabsch(p, np.broadcast_to(q, p.shape), rotation=rotation).rmsd
            assert np.all(lb[j] <= exact + 1e-9 * (1 + exact)), (rotation, j, lb[j], exact.min())


@pytest.mark.parametrize("rotation", ["full", "none", "z"])
def test_rejects_a_piece_far_larger_than_every_primitive_but_not_a_copy(rotation):
    rng = np.random.default_rng(1)
    index = _bank(rng, 3)
    env = index.envelope()
    copy = index.points_of(1)[10:60] @ Rotation.from_euler("z", 30, degrees=True).as_matrix().T
    assert not rejects(env, copy, 49, 0.25, rotation, eps=1e-6)
    t = np.linspace(0, 6, 80)
    big = 50.0 * np.max(env.radius) * np.c_[np.cos(t), np.sin(t), np.zeros(80)]
    assert rejects(env, big, 79, 0.25, rotation, eps=1.0)
    # too long for every primitive at the slowest allowed time scale
    assert rejects(env, copy, 10_000, 0.25, rotation, eps=1e6)


def test_row_groups_cover_whole_primitives_in_order():
    rng = np.random.default_rng(5)
    for _ in range(50):
        counts = rng.integers(2, 400, size=rng.integers(1, 60))
        offsets = np.concatenate([[0], np.cumsum(counts)])
        rows = int(rng.integers(1, 2000))
        groups = row_groups(offsets, rows)
        assert groups[0][0] == 0 and groups[-1][1] == counts.size
        assert all(g1 > g0 for g0, g1 in groups)
        assert all(a[1] == b[0] for a, b in zip(groups[:-1], groups[1:], strict=True))
        # past its first primitive (which starts a new block of rows), a group holds fewer
        # than rows samples
        for g0, g1 in groups:
            assert offsets[g1] - offsets[g0 + 1] < rows or g1 == g0 + 1


def test_envelope_over_several_row_groups_is_each_primitives_own():
    # 40 primitives of 2,000 samples: the samples are read in more than one group
    rng = np.random.default_rng(6)
    pieces = [np.cumsum(rng.normal(size=(2000, 3)), axis=0) + rng.normal(size=3) * 50
              for _ in range(40)]  # fmt: skip
    index = BankIndex(Bank.from_samples(pieces, dt=0.01))
    assert len(row_groups(index.offsets)) > 1
    env = index.envelope()
    for j, p in enumerate(pieces):
        lo, hi = p.min(axis=0), p.max(axis=0)
        c = 0.5 * (lo + hi)
        margin = 0.5 * np.linalg.norm(np.diff(p, axis=0), axis=1).max()
        np.testing.assert_allclose(env.half[j], 0.5 * (hi - lo) + margin, rtol=1e-12)
        far = np.sqrt(((p - c) ** 2).sum(axis=1).max())
        far_xy = np.sqrt(((p - c)[:, :2] ** 2).sum(axis=1).max())
        np.testing.assert_allclose(env.radius[j], far + margin, rtol=1e-12)
        np.testing.assert_allclose(env.radius_xy[j], far_xy + margin, rtol=1e-12)
        assert env.last[j] == 1999
