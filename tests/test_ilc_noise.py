"""Noise-aware trial-by-trial learning: the noise floor, the averaged law and the stop rule."""

from __future__ import annotations

import numpy as np
import pytest

from primlib import InputError
from primlib.ilc import TrialLearner, estimate_noise
from primlib.plant import Machine, invert

DT = 0.002
SIGMA = 0.01  # 10 um on the measured output, mm


def _stage(mass: float = 1.0, damping: float = 1.0) -> Machine:
    """The example stage's linear part (K / (M s^2 + B s), mm per V), scaled M and B."""
    plants = {
        "x": ([12000.0], [0.2 * mass, 24.0 * damping, 0.0]),
        "y": ([12000.0], [0.26 * mass, 33.0 * damping, 0.0]),
    }
    return Machine("stage", DT, ["x", "y"], plants)


def _glyph() -> np.ndarray:
    """The walk-through's loop (examples/stage/paths.py), relative to its start."""
    t = np.arange(1001) * DT
    s = t / 2.0
    s = s**3 * (10 - 15 * s + 6 * s**2)
    return np.c_[
        30 * s + 12 * np.sin(2 * np.pi * s),
        16 * (1 - np.cos(2 * np.pi * s)) - 6 * np.sin(4 * np.pi * s),
    ]


def test_the_floor_is_the_noise_whatever_the_inputs():
    # with the exact model the moved errors differ by the noise only, however far apart
    # the inputs: sigma_a^2 from 5 residual degrees of freedom x 1001 samples (1 % precision)
    m = _stage()
    ref = _glyph()
    rng = np.random.default_rng(1)
    u = rng.standard_normal((6, *ref.shape)).cumsum(axis=1) * 0.01
    y = np.stack([m.simulate(ui) for ui in u]) + SIGMA * rng.standard_normal(u.shape)
    est = estimate_noise(m.impulse_response(len(ref)), ref, u, y)
    np.testing.assert_allclose(est.floor_axes, SIGMA, rtol=0.05)
    np.testing.assert_allclose(est.floor, SIGMA * np.sqrt(2), rtol=0.05)
    assert est.trials == 6 and est.averaged.shape == ref.shape


def _run(law: TrialLearner, plant: Machine, u0: np.ndarray, trials: int, seed: int):
    rng = np.random.default_rng(seed)
    ref = law.reference
    inputs, outputs, true, steps = [u0], [], [], []
    for _ in range(trials):
        y = plant.simulate(inputs[-1])
        true.append(np.sqrt(np.mean(np.sum((ref - y) ** 2, axis=1))))
        outputs.append(y + SIGMA * rng.standard_normal(y.shape))
        step = law.update(np.array(inputs), np.array(outputs))
        steps.append(step)
        inputs.append(step.u)
    return np.array(true), steps


@pytest.mark.slow
def test_the_noise_aware_law_halves_the_plain_laws_true_error_and_stops_at_the_floor():
    # the model is the data sheet's (mass 20 % light, damping 15 % low), the plant the
    # stage's linear part; both laws start from the model inverse and see sigma = 10 um
    model, plant = _stage(0.8, 0.85), _stage()
    ref = _glyph()
    u0 = invert(model, ref)
    plain = TrialLearner(model, ref, noise_aware=False, average=1)
    true_plain, _ = _run(plain, plant, u0, 16, seed=0)
    aware = TrialLearner(model, ref)
    true_aware, steps = _run(aware, plant, u0, 24, seed=0)
    floor = SIGMA * np.sqrt(2)
    # the plain law learns the noise: its true error settles near a third of sigma
    reached = float(np.mean(true_plain[6:]))
    assert 0.2 * SIGMA < reached < 0.6 * SIGMA
    stop = next(k for k, s in enumerate(steps) if s.converged)
    assert true_aware[stop] <= 0.5 * reached
    # the floor is reached when the true error is within the margin of the noise floor
    reach = int(np.flatnonzero(true_aware <= aware.margin * floor)[0])
    assert abs(stop - reach) <= 2, (stop, reach, true_aware / SIGMA)
    np.testing.assert_allclose(steps[stop].noise_floor, floor, rtol=0.1)


def test_the_next_input_is_a_function_of_the_recorded_trials_only():
    m = _stage()
    ref = _glyph()[::4]
    mm = Machine("s", DT * 4, ["x", "y"], m.plants)
    rng = np.random.default_rng(2)
    u = rng.standard_normal((4, *ref.shape)) * 1e-3
    y = np.stack([mm.simulate(ui) for ui in u]) + SIGMA * rng.standard_normal(u.shape)
    a = TrialLearner(mm, ref).update(u, y)
    b = TrialLearner(mm, ref).update(u.copy(), y.copy())
    np.testing.assert_array_equal(a.u, b.u)
    assert a.q_cutoff == b.q_cutoff and a.noise_floor == b.noise_floor


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"law": "q"}, "law: expected one of p, pd, pid, norm-optimal, got 'q'"),
        ({"average": 0}, "average: expected an integer >= 1, got 0"),
        ({"margin": -1.0}, r"margin: expected a number in \(0, 10\), got -1.0"),
    ],
)
def test_bad_options_are_refused(kw, match):
    with pytest.raises(InputError, match=match):
        TrialLearner(_stage(), _glyph(), **kw)


def test_a_history_of_the_wrong_shape_is_refused():
    law = TrialLearner(_stage(), _glyph())
    with pytest.raises(InputError, match=r"trials: expected inputs and outputs of shape"):
        law.update(np.zeros((1, 10, 2)), np.zeros((1, 10, 2)))
    bad = np.zeros((1, 1001, 2))
    bad[0, 3, 1] = np.nan
    with pytest.raises(InputError, match="trials: expected finite inputs and outputs"):
        law.update(np.zeros((1, 1001, 2)), bad)
