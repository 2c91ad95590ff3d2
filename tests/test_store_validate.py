"""Store validation (issue 12): what poisons a library is refused at the door, file unchanged."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.defaults import MAX_ABS_VALUE
from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import Store

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


def arc(n: int = 121, scale: float = 1.0, offset: float = 0.0) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return scale * np.column_stack([10 * np.sin(s), 10 * (1 - np.cos(s)), 2 * s]) + offset


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def db(tmp_path) -> Path:
    db = tmp_path / "lib.duckdb"
    with Store(db) as store:
        store.add_machine(Machine.from_json(DATA / "xyz.json"))
        traj = Trajectory.from_samples(arc(), DT)
        store.add(traj, np.zeros((121, 3)), machine="xyz", name="seed")
    return db


def _refused(db: Path, items, match: str) -> None:
    before = sha(db)
    with Store(db) as store, pytest.raises(InputError, match=match):
        store.add_many(items, "xyz")
    assert sha(db) == before


def test_a_signal_beyond_max_abs_value_is_refused_and_nothing_written(db):
    traj = Trajectory.from_samples(arc(), DT)
    u = np.zeros((121, 3))
    u[40, 1] = 1e308
    _refused(db, [(traj, u, "huge")], r"item 0 \('huge'\): expected signal values within")


def test_a_non_finite_signal_is_refused(db):
    traj = Trajectory.from_samples(arc(), DT)
    u = np.zeros((121, 3))
    u[3, 0] = np.inf
    _refused(db, [(traj, u, "inf")], "expected a finite signal, got NaN or inf")


def test_a_path_beyond_max_abs_value_is_refused_and_nothing_written(db):
    # fitted from in-range samples, then moved out of range: no Trajectory can be built
    # from it (the first door), so none can reach the store
    good = Trajectory.from_samples(arc(), DT)
    with pytest.raises(InputError, match=r"magnitude at most 1e\+09"):
        Trajectory.from_definition(
            good.degree, good.knots, good.ctrlpts + 10 * MAX_ABS_VALUE, good.weights, good.duration
        )
    with Store(db) as store:
        assert len(store.primitives("xyz")) == 1


def test_a_path_that_does_not_move_is_refused(db):
    still = Trajectory.from_samples(np.tile([[5.0, -2.0, 1.0]], (121, 1)), DT)
    _refused(db, [(still, np.zeros((121, 3)), "still")], "expected a path that moves")


def test_in_a_batch_the_first_path_that_does_not_move_is_named_and_nothing_written(db):
    # the paths are checked all at once (one pass over every sample): the message still
    # names the first failing item and where it stays
    moving = [Trajectory.from_samples(arc(offset=k), DT) for k in (1.0, 2.0)]
    still = [Trajectory.from_samples(np.tile(p, (121, 1)), DT) for p in ([5, -2, 1], [7, 7, 7])]
    u = np.zeros((121, 3))
    items = [(moving[0], u, "a"), (still[0], u, "still"), (moving[1], u, "b"), (still[1], u, "c")]
    _refused(db, items, r"item 1 \('still'\): expected a path that moves, got one that stays "
             r"at \(5, -2, 1\) \(extent ")  # fmt: skip


def test_a_path_that_moves_a_little_far_from_the_origin_is_accepted(db):
    # 5e-4 of motion at 1e4 from the origin: 5e-8 of its size, above MIN_EXTENT_REL (1e-9)
    small = Trajectory.from_samples(arc(scale=1e-4, offset=1e4), DT)
    with Store(db) as store:
        store.add(small, np.zeros((121, 3)), machine="xyz", name="small")
        assert len(store.primitives("xyz")) == 2


@pytest.mark.parametrize("name", ["", "two\nlines", "   ", "tab\there"])
def test_a_name_that_is_empty_or_not_one_printable_line_is_refused(db, name):
    traj = Trajectory.from_samples(arc(), DT)
    text = f"expected name to be non-empty printable text on one line, got {name!r}"
    _refused(db, [(traj, np.ones((121, 3)), name)], re.escape(text))
