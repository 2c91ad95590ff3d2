"""What a finished trial series stores (TrialLearner.stored_input): the best trial's input,
or the mean input of settled trials where a trial-varying disturbance was learned into each
input (primlib.ilc._settled)."""

from __future__ import annotations

import numpy as np
import pytest

from primlib.ilc import TrialLearner
from primlib.ilc._noise import pooled_noise
from primlib.ilc._settled import MIN_RUN, settled_runs
from primlib.plant import Machine, RealisticMachine, invert, typical_scales

DT = 0.002


def _brute(reference, outputs, sigma2):
    err = reference[None] - outputs
    rms = np.sqrt(np.mean(np.sum(err**2, axis=2), axis=1))
    settled = rms <= 3.0 * np.median(rms[len(rms) // 2 :])
    best = None
    for k0 in range(len(rms)):
        for k1 in range(k0 + MIN_RUN, len(rms) + 1):
            if settled[k0:k1].all():
                mean = err[k0:k1].mean(axis=0)
                e = np.sqrt(np.mean(np.sum(mean**2, axis=1)) + sigma2 / (k1 - k0))
                if best is None or e < best[2]:
                    best = (k0, k1, e)
    return best


@pytest.mark.parametrize("seed", range(4))
def test_the_window_is_the_exhaustive_searchs(seed):
    rng = np.random.default_rng(seed)
    ref = rng.standard_normal((40, 2))
    out = ref[None] + rng.standard_normal((12, 40, 2)) * rng.uniform(0.5, 2.0, (12, 1, 1))
    out[rng.integers(0, 12)] += 50.0  # an unsettled trial no window may cross
    got, want = settled_runs(ref, out, 0.3), _brute(ref, out, 0.3)
    assert got[:2] == want[:2]
    assert got[2] == pytest.approx(want[2], rel=1e-9)


def test_no_run_of_settled_trials_is_none():
    ref = np.zeros((10, 1))
    out = np.ones((MIN_RUN - 1, 10, 1))
    assert settled_runs(ref, out, 0.0) is None


def _series(machine, model, ref, trials: int):
    learner = TrialLearner(model, ref)
    runner = machine.trials(start=[0.0, 0.0])
    inputs, outputs, u = [], [], invert(model, ref)
    for _ in range(trials):
        outputs.append(runner.run(u))
        inputs.append(u)
        u = learner.update(np.stack(inputs), np.stack(outputs)).u
    return learner, np.stack(inputs), np.stack(outputs)


def _stage(**departures) -> tuple[Machine, RealisticMachine]:
    """The example stage's linear part and it with departures scaled to the path's input."""
    plants = {"x": ([12000.0], [0.2, 24.0, 0.0]), "y": ([12000.0], [0.26, 33.0, 0.0])}
    model = Machine("stage", DT, ["x", "y"], plants)
    u_typ, v_typ = typical_scales(model, [invert(model, _ref())])
    return model, RealisticMachine.from_machine(
        model, typical_input=u_typ, typical_velocity=v_typ, seed=3, **departures
    )


def _ref() -> np.ndarray:
    s = np.linspace(0.0, 1.0, 751)
    s = s**3 * (10 - 15 * s + 6 * s**2)
    return np.c_[30 * s + 8 * np.sin(2 * np.pi * s), 12 * (1 - np.cos(2 * np.pi * s))]


@pytest.mark.slow
def test_under_a_trial_varying_disturbance_the_mean_input_leaves_less_and_says_so():
    model, machine = _stage(disturbance=0.02, disturbance_bandwidth=2.0)
    _, calm = _stage()
    ref = _ref()
    learner, u, y = _series(machine, model, ref, 16)
    best, worth = learner.best_input(u, y)
    stored, err, (k0, k1) = learner.stored_input(u, y)
    assert k1 - k0 >= MIN_RUN
    np.testing.assert_array_equal(stored, u[k0:k1].mean(axis=0))

    def own(v):
        return float(np.sqrt(np.mean(np.sum((ref - calm.simulate(v, start=[0, 0])) ** 2, 1))))

    # each input carries a copy of a draw; their mean about 1/sqrt(K) of one
    assert own(stored) < 0.5 * own(u[best])
    assert err < worth
    # the estimate is the mean input's error, not the measured mean error's telescoped rest
    assert own(stored) / 3 < err < 3 * own(stored)


def test_without_anything_trial_varying_the_best_trials_input_is_stored():
    model, machine = _stage(coulomb=0.02, viscous=0.02)
    learner, u, y = _series(machine, model, _ref()[::3], 8)
    best, worth = learner.best_input(u, y)
    stored, err, run = learner.stored_input(u, y)
    assert run == (best, best + 1) and err == worth
    np.testing.assert_array_equal(stored, u[best])


@pytest.mark.slow
def test_the_pooled_floor_is_the_series_draws_size_not_its_lucky_pairs():
    # a 2 Hz input disturbance has a few degrees of freedom a trial: the measured errors of
    # settled trials scatter by 4x, and the lowest is a lucky draw; the floor pooled over
    # the settled pairs must be what the series' draws moved the machine by (here 0.45 mm
    # RMS, one draw 0.13-0.9), not what the pairs of the small ones say (0.29 by the 3x
    # rule alone). The model is the machine's linear part, so each pair's floor is exactly
    # half its two draws' difference: the pool is unbiased up to the draws' own scatter
    model, machine = _stage(disturbance=0.02, disturbance_bandwidth=2.0)
    _, calm = _stage()
    ref = _ref()
    learner = TrialLearner(model, ref)
    runner = machine.trials(start=[0.0, 0.0])
    inputs, outputs, draws, u = [], [], [], invert(model, ref)
    for _ in range(16):
        outputs.append(runner.run(u))
        inputs.append(u)
        draws.append(runner.true[-1] - calm.simulate(u, start=[0.0, 0.0]))
        u = learner.update(np.stack(inputs), np.stack(outputs)).u
    floor_axes, _ = pooled_noise(learner._h, ref, np.stack(inputs), np.stack(outputs))
    draw = np.sqrt(np.mean(np.sum(np.square(draws), axis=2)))
    assert 0.8 < np.sqrt(np.sum(floor_axes**2)) / draw < 1.25
