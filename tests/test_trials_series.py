"""The trial-series API: plants, the stop rule's use, finishing, and the library growing."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.plant import Machine, invert
from primlib.store import TrialStore
from primlib.trials import Plant, TrialSeries, first_input, pending, start, status, step

ROOT = Path(__file__).resolve().parents[1]
STAGE = Machine.from_json(ROOT / "examples" / "stage" / "stage.json")
SIGMA = 0.01


def _datasheet() -> Machine:
    plants = {
        a: ([p["K"] / STAGE.length_unit], [0.8 * p["M"], 0.85 * p["B"], 0.0])
        for a, p in STAGE.motors.items()
    }
    return Machine("stage", STAGE.dt, STAGE.axes, plants)


def _glyph(start=(40.0, 25.0), angle: float = 0.0, duration: float = 2.0) -> Trajectory:
    t = np.arange(round(duration / STAGE.dt) + 1) * STAGE.dt
    s = t / duration
    s = s**3 * (10 - 15 * s + 6 * s**2)
    pts = np.c_[30 * s + 12 * np.sin(2 * np.pi * s), 16 * (1 - np.cos(2 * np.pi * s))]
    a = np.deg2rad(angle)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return Trajectory.from_samples(pts @ R.T + np.asarray(start), STAGE.dt)


class NoisyStage:
    """The nonlinear example stage with seeded noise, as a user's hardware class would be."""

    def __init__(self, start, seed: int = 0) -> None:
        self.start = np.asarray(start, dtype=float)
        self.rng = np.random.default_rng(seed)

    def run(self, u):
        y = STAGE.simulate(u, start=self.start)
        return y + SIGMA * self.rng.standard_normal(y.shape)


def test_machines_and_hardware_classes_are_plants():
    assert isinstance(STAGE, Plant) and isinstance(_datasheet(), Plant)
    assert isinstance(NoisyStage((0, 0)), Plant)
    u = np.zeros((20, 2))
    u[3:] = 0.1
    np.testing.assert_array_equal(_datasheet().run(u), _datasheet().simulate(u))


@pytest.mark.slow
def test_a_finished_series_gives_a_moved_rotated_copy_a_warm_start_twice_as_good():
    with Library() as lib:
        lib.add_machine(_datasheet())
        glyph = _glyph(duration=1.2)
        s = TrialSeries.start(lib, glyph, "stage", margin=0.5)
        assert s.status().record.start == "inverse"  # nothing learned yet
        result = s.run(NoisyStage(glyph.at([0.0])[0]), max_trials=14)
        assert result.stopped == "converged", [r.rms for r in result.steps]
        pid = s.finish()
        info = lib.info(pid)
        assert info.source.startswith(f"trial series {s.id}: {len(result.steps)} trials")
        assert TrialStore(lib).for_primitive(pid) == s.id
        moved = _glyph(start=(120.0, 60.0), angle=35.0, duration=1.2)
        warm = start(lib, moved, "stage")
        assert warm.start == "warm"
        pts = moved.sample(STAGE.dt)
        ref = pts - pts[0]

        def true_rms(u):
            y = STAGE.simulate(u, start=pts[0])
            return float(np.sqrt(np.mean(np.sum((ref - y) ** 2, axis=1))))

        e_warm, e_inverse = true_rms(warm.u), true_rms(invert(_datasheet(), ref))
        assert e_warm <= 0.5 * e_inverse, (e_warm, e_inverse)


def test_finish_refuses_a_series_that_has_not_converged_unless_forced():
    with Library() as lib:
        lib.add_machine(_datasheet())
        glyph = _glyph(duration=0.4)
        sid = start(lib, glyph, "stage", first="cold").series
        with pytest.raises(InputError, match=f"trial series {sid} has no measured trial yet"):
            TrialSeries(lib, sid).finish()
        _, _, u = pending(lib, sid)
        y = NoisyStage(glyph.at([0.0])[0]).run(u) + glyph.at([0.0])[0]
        res = step(lib, sid, y)
        assert res.trial == 0 and not res.converged
        assert status(lib, sid).verdict == "learning"
        with pytest.raises(InputError, match=f"trial series {sid} has not converged"):
            TrialSeries(lib, sid).finish()
        pid = TrialSeries(lib, sid).finish(force=True)
        assert status(lib, sid).verdict == "finished"
        with pytest.raises(
            InputError, match=rf"trial series {sid} is finished \(primitive {pid}\)"
        ):
            TrialSeries(lib, sid).finish(force=True)
        with pytest.raises(InputError, match="first: expected one of warm, inverse, cold"):
            start(lib, glyph, "stage", first="hot")
        with pytest.raises(InputError, match="options: expected among .* got unknown 'gain'"):
            start(lib, glyph, "stage", gain=2.0)


def test_first_input_is_what_a_series_starts_from_and_says_where_it_came_from():
    with Library() as lib:
        lib.add_machine(_datasheet())
        glyph = _glyph(duration=0.6)
        pts = glyph.sample(STAGE.dt)
        # an empty library: the machine model's inverse, said to be one
        u0, kind, notes = first_input(lib, glyph, "stage")
        assert kind == "inverse" and "nothing in the library matches" in notes[0]
        np.testing.assert_array_equal(u0, invert(_datasheet(), pts - pts[0]))
        assert np.count_nonzero(first_input(lib, glyph, "stage", first="cold")[0]) == 0
        with pytest.raises(InputError, match="first: expected one of"):
            first_input(lib, glyph, "stage", first="zero")
        flat = Trajectory.from_samples(np.c_[pts, np.zeros(len(pts))], STAGE.dt)
        with pytest.raises(InputError, match="path: expected 2 axes for machine 'stage'"):
            first_input(lib, flat, "stage")
        started = start(lib, glyph, "stage")
        np.testing.assert_array_equal(started.u, u0)
