"""Batched sampling (primlib.nurbs.sample_many) and the store's batch insert path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from primlib import InputError
from primlib.nurbs import Trajectory, sample_many
from primlib.plant import Machine
from primlib.store import Store

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


def curve(seed: int, d: int = 3, steps: int = 240, m: int = 7, p: int = 3, rational=False):
    """A random clamped NURBS of duration steps * DT; seed 0..2 share their knots."""
    rng = np.random.default_rng(seed)
    knots_rng = np.random.default_rng(seed % 3)
    interior = np.sort(knots_rng.uniform(0.05, 0.95, m - p - 1))
    knots = np.concatenate([np.zeros(p + 1), interior, np.ones(p + 1)])
    ctrl = rng.uniform(-50, 50, (m, d))
    w = rng.uniform(0.5, 2.0, m) if rational else np.ones(m)
    return Trajectory.from_definition(p, knots, ctrl, w, steps * DT)


def _close(got: np.ndarray, want: np.ndarray) -> None:
    # the same basis values summed in another order: a few ulp of the largest coordinate;
    # the goal is 1e-12 relative to the curve's size
    scale = np.abs(want).max()
    assert np.abs(got - want).max() <= 1e-12 * scale


@settings(max_examples=25, deadline=None)
@given(
    specs=st.lists(
        st.tuples(
            st.integers(0, 2**20),  # seed (seed % 3 picks the knots: groups form)
            st.sampled_from([8, 31, 240]),  # steps
            st.sampled_from([5, 7, 12]),  # control points
            st.sampled_from([1, 2, 3, 5]),  # degree
            st.booleans(),  # rational
        ),
        min_size=1,
        max_size=12,
    ),
    d=st.sampled_from([2, 3]),
)
def test_sample_many_equals_each_trajectory_s_sample(specs, d):
    paths = [curve(s, d=d, steps=n, m=max(m, p + 1), p=p, rational=r) for s, n, m, p, r in specs]
    points, offsets = sample_many(paths, DT)
    assert offsets[0] == 0 and offsets[-1] == len(points)
    for i, path in enumerate(paths):
        want = path.sample(DT)
        got = points[offsets[i] : offsets[i + 1]]
        assert got.shape == want.shape
        _close(got, want)
        # the ends are the end control points exactly, as in Trajectory.sample
        np.testing.assert_array_equal(got[[0, -1]], path.ctrlpts[[0, -1]])


@pytest.mark.parametrize("rational", [False, True])
@pytest.mark.parametrize("p", [1, 3, 5])
def test_sample_many_shares_one_basis_across_a_group(p, rational):
    # seeds 0, 3, 6, ... share their knots: groups of 40 go through the sparse basis product
    # (in chunks of 32), beside a singleton of other knots sampled on its own
    paths = [curve(s, m=9, p=p, rational=rational) for s in range(0, 120, 3)] + [curve(1)]
    points, offsets = sample_many(paths, DT)
    for i, path in enumerate(paths):
        _close(points[offsets[i] : offsets[i + 1]], path.sample(DT))


def test_sample_many_on_fitted_paths_sharing_knots():
    t = np.arange(601) * DT
    paths = [
        Trajectory.from_samples(np.column_stack([np.cos(a * t), np.sin(t), t * a]), dt=DT)
        for a in (1.0, 1.3, 1.7, 2.0)
    ]
    points, offsets = sample_many(paths, DT)
    for i, path in enumerate(paths):
        _close(points[offsets[i] : offsets[i + 1]], path.sample(DT))


def test_sample_many_of_nothing_is_empty():
    points, offsets = sample_many([], DT)
    assert points.shape[0] == 0 and offsets.tolist() == [0]


def test_sample_many_refuses_mixed_dimensions_and_a_dt_that_does_not_divide():
    with pytest.raises(InputError, match=r"trajectories: expected one dimension, got \[2, 3\]"):
        sample_many([curve(0, d=2), curve(1, d=3)], DT)
    with pytest.raises(InputError, match="dt: expected a step that divides the duration"):
        sample_many([curve(0)], 0.007)


class _DuckPath:
    """A path that is not a Trajectory but quacks like one (the store samples it itself)."""

    def __init__(self, inner: Trajectory) -> None:
        self._inner = inner
        self.duration, self.dim = inner.duration, inner.dim

    def definition(self):
        return self._inner.definition()

    def sample(self, dt):
        return self._inner.sample(dt)


def test_add_many_stores_the_same_points_for_trajectories_and_other_paths():
    paths = [curve(s, rational=bool(s % 2)) for s in range(6)]
    items = [
        (_DuckPath(p) if i in (1, 4) else p, np.full((241, 3), float(i)), f"p{i}")
        for i, p in enumerate(paths)
    ]
    with Store() as lib:
        lib.add_machine(Machine.from_json(DATA / "xyz.json"))
        ids = lib.add_many(items, "xyz")
        for pid, path in zip(ids, paths, strict=True):
            _close(lib.get(pid).points, path.sample(DT))


def test_add_many_names_the_item_whose_path_samples_to_nan():
    class Broken(_DuckPath):
        def sample(self, dt):
            out = super().sample(dt)
            out[5, 1] = np.nan
            return out

    with Store() as lib:
        lib.add_machine(Machine.from_json(DATA / "xyz.json"))
        with pytest.raises(InputError, match=r"item 1 \('b'\): expected the path to sample to"):
            lib.add_many(
                [(curve(0), np.zeros((241, 3)), "a"), (Broken(curve(1)), np.zeros((241, 3)), "b")],
                "xyz",
            )
        assert lib.primitives() == []


def test_a_big_batch_is_written_to_the_file_at_commit_not_left_in_the_wal(tmp_path):
    # 16 MiB of points and signals needs 2 * k * n * 3 * 8 >= 2**24 bytes: k >= 146
    # primitives of n = 2,401 samples; 150 of them (17.3 MB).
    machine = Machine.from_json(DATA / "xyz.json")
    dt = machine.dt
    steps = 2400
    base = curve(0)
    path = Trajectory.from_definition(
        base.degree, base.knots, base.ctrlpts, base.weights, steps * dt
    )
    rng = np.random.default_rng(0)
    us = [rng.standard_normal((steps + 1, 3)) for _ in range(150)]
    db = tmp_path / "big.duckdb"
    with Store(db) as lib:
        lib.add_machine(machine)
        threads = lib._con.sql("SELECT current_setting('threads')").fetchall()[0][0]
        ids = lib.add_many([(path, u) for u in us], machine.name)
        wal = Path(str(db) + ".wal")
        assert not wal.exists() or wal.stat().st_size < 2**20
        # the connection's settings are back as they were
        assert lib._con.sql("SELECT current_setting('threads')").fetchall()[0][0] == threads
        assert lib._con.sql("SELECT current_setting('checkpoint_threshold')").fetchall()[0][0] == (
            "16.0 MiB"
        )
    with Store(db, read_only=True) as lib:
        np.testing.assert_array_equal(lib.signal(ids[7]), us[7])
        np.testing.assert_array_equal(lib.bank(machine.name).signals[: steps + 1], us[0])
