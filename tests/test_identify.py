"""primlib.identify: output-error identification and the excitation generator.

Tolerances: noise-free records are simulated by the same ZOH Machine the fit simulates, so
the true coefficients are a zero of the residual and least squares (tolerance 1e-12)
recovers them to ~1e-7 relative; with white output noise of standard deviation sigma the
estimate's standard uncertainty scales as sigma / sqrt(n), so four times the record halves
it (a ratio within [0.3, 0.75] allows the uncertainty of the uncertainty at these lengths).
"""

from __future__ import annotations

import numpy as np
import pytest

from primlib import InputError
from primlib.identify import STRUCTURES, excite, identify
from primlib.plant import Machine

DT = 0.005

# one plant per structure, poles well inside the excited band (0.13 .. 20 Hz)
PLANTS = {
    "integrator": ([2.5], [1.0, 0.0]),
    "first-order": ([6.0], [1.0, 3.0]),
    "second-order": ([-0.3, 8.0], [1.0, 4.0, 0.0]),
}


def record(num, den, n=1500, noise=0.0, seed=0, pid=None, axes=1, sigma=0.0, periods=4):
    u = excite(n * DT, 1.0, axes, DT, periods=periods)
    plants = {a: (num, den) for a in "xyz"[:axes]}
    fb = None if pid is None else {a: pid for a in plants}
    m = Machine("true", DT, tuple(plants), plants, fb)
    y = m.simulate(u)
    rng = np.random.default_rng(seed)
    y = y + (noise * np.std(y, axis=0) + sigma) * rng.standard_normal(y.shape)
    return u, y - y[0]


@pytest.mark.parametrize("name", list(PLANTS))
def test_recovers_each_structure_from_noise_free_data(name):
    num, den = PLANTS[name]
    u, y = record(num, den)
    res = identify(u, y, DT, structure=name, axes=("x",))
    got_num, got_den = res.machine.plants["x"]
    np.testing.assert_allclose(got_num, num, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(got_den, den, rtol=1e-6, atol=1e-7)
    assert res.nrmse[0] < 1e-6


def test_recovers_the_plant_inside_a_pid_loop():
    # the PDCCILC paper's y axis, non-minimum phase, in its PID (Table 1)
    num, den = [-0.0631, 2.132], [1.0, 2.76, 2.127]
    pid = {"kp": 3.0, "ki": 1.0, "kd": 0.0}
    u, y = record(num, den, pid=pid)
    res = identify(u, y, DT, structure="second-order", pid=pid, axes=("x",))
    got_num, got_den = res.machine.plants["x"]
    np.testing.assert_allclose(got_num, num, rtol=1e-6)
    np.testing.assert_allclose(got_den, den, rtol=1e-6)
    assert res.machine.feedback == {"x": {"kp": 3.0, "ki": 1.0, "kd": 0.0, "tf": 0.0}}


@pytest.mark.slow
def test_uncertainty_shrinks_with_record_length():
    # poles at 10 and 30 rad/s, inside the band of the 1 s period (1 .. 20 Hz)
    num, den = [-6.0, 2400.0], [1.0, 40.0, 300.0]
    stds = []
    for n in (800, 3200):  # the same 200-sample period, 4 or 16 times
        u, y = record(num, den, n=n, sigma=0.01, seed=3, periods=n // 200)
        res = identify(u, y, DT, structure="second-order", axes=("x",))
        unc = res.uncertainty["x"]
        stds.append(np.concatenate([unc["num"], unc["den"][1:]]))
        # the estimate lies within 5 standard uncertainties of the truth
        got = np.concatenate([res.fits[0].num, res.fits[0].den[1:]])
        truth = np.concatenate([num, den[1:]])
        assert np.all(np.abs(got - truth) <= 5 * stds[-1] + 1e-12)
    ratio = stds[1] / stds[0]
    assert np.all((ratio > 0.3) & (ratio < 0.75)), ratio


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PLANTS))
def test_auto_picks_the_right_structure(name):
    num, den = PLANTS[name]
    u, y = record(num, den, noise=0.01, seed=1)
    res = identify(u, y, DT, axes=("x",))
    assert res.fits[0].structure == name, res.candidates
    assert set(res.candidates[0]) == set(STRUCTURES)
    assert res.nrmse[0] < 0.02  # the noise floor is 1 %


def test_machine_note_carries_the_fit_quality_and_round_trips(tmp_path):
    u, y = record(*PLANTS["integrator"], axes=2)
    res = identify(u, y, DT, structure="integrator", name="stage", machine_dt=0.01)
    d = res.machine.to_dict()
    assert d["dt"] == 0.01 and d["name"] == "stage"
    assert "held-out NRMSE" in d["note"] and "x: integrator" in d["note"]
    res.machine.to_json(tmp_path / "m.json")
    assert Machine.from_json(tmp_path / "m.json") == res.machine


def test_plot_draws_measured_and_model(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    u, y = record(*PLANTS["integrator"], n=400, axes=2)
    res = identify(u, y, DT, structure="integrator")
    ax = res.plot()
    assert len(ax) == 2 and len(ax[0].lines) == 2
    np.testing.assert_allclose(ax[1].lines[1].get_ydata(), res.y_model[:, 1])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"y": np.zeros((10, 2))}, r"y: expected the shape of u \(400, 1\)"),
        ({"dt": -1.0}, "dt: expected a finite number > 0"),
        ({"holdout": 1.5}, r"holdout: expected a finite number in \(0, 1\)"),
        ({"structure": "third-order"}, "structure: expected one of integrator"),
        ({"u": np.zeros((400, 1))}, "input of axis 'x' is zero throughout"),
        ({"pid": {"kp": "a"}}, "pid kp of axis 'x': expected a number"),
        ({"pid": {"q": {"kp": 1.0}}}, "pid: got gains for unknown axis 'q'"),
        ({"holdout": 0.01}, "expected at least 20 samples"),
    ],
)
def test_bad_input_says_what_and_where(kwargs, match):
    u, y = record(*PLANTS["integrator"], n=400)
    y_nan = y.copy()
    args = {"u": u, "y": y, "dt": DT, **kwargs}
    with pytest.raises(InputError, match=match):
        identify(args.pop("u"), args.pop("y"), args.pop("dt"), **args)
    y_nan[5, 0] = np.nan
    with pytest.raises(InputError, match="y: expected finite values, got nan at sample 5"):
        identify(u, y_nan, DT)


# --------------------------------------------------------------------------- excite
@pytest.mark.parametrize("kind", ["multisine", "prbs"])
def test_excitation_respects_amplitude_and_rate(kind):
    u = excite(10.0, 2.0, 3, DT, kind=kind, max_rate=40.0, seed=4)
    assert u.shape == (2000, 3)
    assert np.max(np.abs(u)) <= 2.0 + 1e-12
    rate = np.max(np.abs(np.diff(u, axis=0, prepend=0.0))) / DT
    assert rate <= 40.0 * (1 + 1e-9)
    # the axes are distinct and nearly uncorrelated
    c = np.corrcoef(u.T)
    assert np.max(np.abs(c - np.eye(3))) < 0.2


def test_multisine_has_a_low_crest_factor_and_starts_at_rest():
    u = excite(20.0, 1.0, 1, DT, periods=1)[:, 0]
    core = u[len(u) // 10 : -len(u) // 10]  # away from the fades
    crest = np.max(np.abs(core)) / np.sqrt(np.mean(core**2))
    assert crest < 2.0  # aligned phases would give sqrt(2 K) ~ 16 for K ~ 80 harmonics
    assert u[0] == 0.0 and abs(u[-1]) < 1e-3


def test_velocity_limit_uses_the_nominal_model():
    m = Machine.from_json("data/machines/xyz.json")
    u = excite(10.0, 5.0, 3, DT, max_velocity=2.0, machine=m)
    vel = np.max(np.abs(np.diff(m.simulate(u), axis=0))) / DT
    np.testing.assert_allclose(vel, 2.0, rtol=1e-9)
    with pytest.raises(InputError, match="max_velocity: expected a nominal machine"):
        excite(10.0, 5.0, 3, DT, max_velocity=2.0)
    with pytest.raises(InputError, match="machine: expected 2 axes and dt = 0.005 s, got 3"):
        excite(10.0, 5.0, 2, DT, max_velocity=2.0, machine=m)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"duration": 0.0}, "duration: expected a finite number > 0"),
        ({"kind": "chirp"}, "kind: expected one of multisine, prbs"),
        ({"axes": 0}, "axes: expected a number of axes >= 1"),
        ({"band": (30.0, 200.0)}, "band: expected 0 <= low < high <= the Nyquist"),
        ({"band": (0.01, 0.05)}, "band: expected at least one harmonic"),
    ],
)
def test_bad_excitation_options(kwargs, match):
    args = {"duration": 10.0, "amplitude": 1.0, "axes": 2, "dt": DT, **kwargs}
    with pytest.raises(InputError, match=match):
        excite(
            args.pop("duration"), args.pop("amplitude"), args.pop("axes"), args.pop("dt"), **args
        )


def test_a_closed_loop_record_with_a_moving_reference():
    # the reference excites the loop as well as the feedforward; both enter the model
    num, den = [-0.0631, 2.132], [1.0, 2.76, 2.127]
    pid = {"kp": 3.0, "ki": 1.0, "kd": 0.0}
    u = excite(6.0, 1.0, 1, DT)
    r = 0.5 * excite(6.0, 1.0, 1, DT, periods=2)
    true = Machine("true", DT, ("x",), {"x": (num, den)}, {"x": pid})
    y = true.simulate(u, reference=r)
    res = identify(u, y, DT, structure="second-order", pid=pid, reference=r, axes=("x",))
    np.testing.assert_allclose(res.machine.plants["x"][1], den, rtol=1e-6)
    with pytest.raises(InputError, match=r"reference: expected the shape of u \(1200, 1\)"):
        identify(u, y, DT, pid=pid, reference=r[:-1], axes=("x",))


def test_an_output_that_stops_before_the_held_out_part_is_refused():
    u, y = record(*PLANTS["integrator"], n=400)
    y[250:] = y[250]
    with pytest.raises(InputError, match="y: axis 'x' does not move in the held-out part"):
        identify(u, y, DT, axes=("x",))
