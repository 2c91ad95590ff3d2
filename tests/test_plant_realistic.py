import json
import math
import time
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from primlib import InputError
from primlib.ilc import learn
from primlib.plant import Machine, RealisticMachine, TrialRunner, typical_scales

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
XYZ = Machine.from_json(DATA / "xyz.json")
PID = {"kp": 3.0, "ki": 1.0, "kd": 0.05, "tf": 0.01}


def xyz(feedback=None, **departures) -> RealisticMachine:
    base = Machine("xyz", XYZ.dt, XYZ.axes, XYZ.plants, feedback)
    return RealisticMachine.from_machine(base, **departures)


def test_example_json_dispatches_by_kind_and_round_trips():
    rm = Machine.from_json(DATA / "realistic-xyz.json")
    assert isinstance(rm, RealisticMachine) and rm.kind == "realistic"
    assert rm.axes == ("x", "y", "z") and rm.seed == 0 and rm.substeps == 4
    x = rm.departures["x"]
    assert (x["coulomb"], x["ripple"], x["ripple_pitch"], x["noise"]) == (0.3, 0.3, 5.0, 0.001)
    assert x["resonance_hz"] == 0.0
    assert rm.nominal().plants.keys() == XYZ.plants.keys()
    for a in XYZ.axes:
        np.testing.assert_array_equal(rm.plants[a][1], XYZ.plants[a][1])
    again = Machine.from_dict(json.loads(json.dumps(rm.to_dict())))
    assert again == rm and isinstance(again, RealisticMachine)
    assert again.to_dict()["note"] == rm.to_dict()["note"]


@pytest.mark.parametrize("machine", ["xyz.json", "xy-pdccilc.json"])
@pytest.mark.parametrize("closed", [False, True])
def test_every_departure_off_is_exactly_the_nominal_machine(machine, closed):
    base = Machine.from_json(DATA / machine)
    fb = {a: PID for a in base.axes} if closed else None
    base = Machine(base.name, base.dt, base.axes, base.plants, fb)
    rm = RealisticMachine.from_machine(base)
    rng = np.random.default_rng(0)
    u = rng.normal(size=(1500, base.dim))
    r = np.cumsum(rng.normal(size=u.shape), axis=0) * 0.01
    want = base.simulate(u, r)
    for trial in (0, 3):
        got = rm.simulate(u, r, start=np.full(base.dim, 7.0), trial=trial, noise=True)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    np.testing.assert_array_equal(rm.impulse_response(40), base.impulse_response(40))
    np.testing.assert_array_equal(rm.lifted(10), base.lifted(10))
    assert rm.nominal() == base


@pytest.mark.parametrize("resonance", [0.0, 20.0])  # the two-state and the general loop
@pytest.mark.parametrize("closed", [False, True])
def test_the_per_sample_loop_is_the_zoh_model_without_coulomb_and_ripple(closed, resonance):
    # the loop (needed for friction and ripple) against the vectorised linear path on the
    # linear departures: viscous friction, resonance, disturbance, noise through the PID
    fb = {a: PID for a in "xyz"} if closed else None
    rm = xyz(fb, viscous=0.05, resonance_hz=resonance)
    rng = np.random.default_rng(1)
    u = rng.normal(size=(2000, 3))
    r = np.cumsum(rng.normal(size=u.shape), axis=0) * 0.01 if closed else None
    nz = 0.01 * rng.normal(size=u.shape)
    lin = rm._motion(u, r, np.zeros(3), nz)
    loop = rm._motion(u, r, np.zeros(3), nz, loop={0, 1, 2})
    # open loop both are exact ZOH up to rounding; in the PID loop with a 20 Hz mode the
    # closed loop's poles cluster near 1 and three independent double-precision evaluations
    # (state recursion, sections, expanded polynomials) spread by ~3e-9 of the output
    tol = 3e-8 if closed else 1e-10
    np.testing.assert_allclose(loop, lin, rtol=0, atol=tol * np.abs(lin).max())
    np.testing.assert_allclose(lin, rm.linear_part().simulate(u, None if r is None else r - nz))


def test_coulomb_friction_holds_below_the_static_level_and_slides_above():
    c, rs, cv = 0.3, 1.5, 0.02
    rm = xyz(coulomb=c, static_ratio=rs, viscous=cv, stribeck_velocity=1.0)
    y = rm.simulate(np.full((400, 3), 0.99 * rs * c))
    assert np.all(y == 0.0)
    u = 10.0
    y = rm.simulate(np.full((4000, 3), u))
    v_end = (y[-1] - y[-2]) / rm.dt
    # steady velocity of K / (T s^2 + s) driven by u - c sgn(v) - c_v v, the Stribeck
    # term exp(-(v / 1 mm/s)^2) below 1e-40 at these speeds: v = K (u - c) / (1 + K c_v)
    k = np.array([XYZ.plants[a][0][-1] / XYZ.plants[a][1][-2] for a in XYZ.axes])
    np.testing.assert_allclose(v_end, k * (u - c) / (1 + k * cv), rtol=1e-9)


def test_stick_slip_neither_chatters_nor_creeps():
    rm = xyz(coulomb=0.3, static_ratio=1.5)
    n = 4000
    t = np.arange(n) * rm.dt
    # 10 periods of an input above the static level (0.45): 20 half-cycles
    u = np.tile((0.6 * np.sin(2 * np.pi * 0.5 * t))[:, None], (1, 3))
    y = rm.simulate(u)
    v = np.diff(y, axis=0)
    for i in range(3):
        s = np.sign(v[:, i])
        s = s[s != 0]
        assert int(np.sum(s[1:] != s[:-1])) == 19  # one reversal per half-cycle, no chatter
        stuck = (v[:, i] == 0.0).astype(int)
        # it sticks exactly at rest at the start and at the end of every half-cycle
        assert 1 + int(np.sum(np.diff(stuck) == 1)) == 21
        assert 20 * 10 < stuck.sum() < n
    # a push, then nothing: the axis coasts to a stop and stays there exactly
    u = np.zeros((1500, 3))
    u[:100] = 2.0
    y = rm.simulate(u)
    assert np.all(np.diff(y[1000:], axis=0) == 0.0) and np.all(y[-1] > 0)


def test_ripple_depends_on_the_absolute_position():
    pitch = 5.0
    rm = xyz(ripple=0.3, ripple_pitch=pitch)
    u = np.full((800, 3), 8.0)
    u[400:] = -8.0
    start = np.array([1.0, 2.0, 3.0])
    y0 = rm.simulate(u, start=start)
    y1 = rm.simulate(u, start=start + pitch)
    y_half = rm.simulate(u, start=start + pitch / 2)
    np.testing.assert_allclose(y1, y0, rtol=0, atol=1e-9 * np.abs(y0).max())
    assert np.min(np.abs(y_half - y0).max(axis=0)) > 1e-3 * np.abs(y0).max()
    # and it is a force of the set amplitude: against the nominal motion, a bounded bias
    lin = rm.nominal().simulate(u)
    assert 1e-3 < np.abs(y0 - lin).max() / np.abs(lin).max() < 0.1


def test_the_ripple_integrates_to_second_order_in_the_substep():
    # the ripple is taken half-way through each substep (midpoint rule): 4 substeps are
    # within (w v h)^2 / 24 of 64 (w v h = 0.08 here, so ~3e-4 of the ripple's effect);
    # taken at the substep's start they were w v h / 2 = 4 % off
    u = np.full((400, 3), 40.0)
    start = np.array([1.0, 2.0, 3.0])
    ys = {k: xyz(ripple=0.3, ripple_pitch=5.0, substeps=k).simulate(u, start=start)
          for k in (4, 64)}  # fmt: skip
    effect = np.abs(ys[64] - XYZ.simulate(u)).max()
    assert effect > 1e-3
    assert np.abs(ys[4] - ys[64]).max() < 1e-3 * effect


def test_measurement_noise_is_off_by_default_seeded_and_of_the_asked_std():
    rm = xyz(noise=0.001, viscous=0.05)
    u = np.full((20000, 3), 1.0)
    true = rm.simulate(u)
    np.testing.assert_array_equal(rm.simulate(u, noise=False), true)
    meas = rm.simulate(u, noise=True)
    np.testing.assert_array_equal(rm.simulate(u, noise=True), meas)
    e = meas - true
    # std of 20000 Gaussian samples: relative standard error 1 / sqrt(2 n) = 0.5 %, 5 sigma
    np.testing.assert_allclose(e.std(axis=0), 0.001, rtol=0.025)
    np.testing.assert_allclose(e.mean(axis=0), 0.0, atol=5 * 0.001 / math.sqrt(20000))
    assert np.abs(np.corrcoef(e[1:, 0], e[:-1, 0])[0, 1]) < 5 / math.sqrt(20000)
    other = rm.simulate(u, noise=True, trial=1) - true
    assert np.abs(np.corrcoef(e[:, 0], other[:, 0])[0, 1]) < 5 / math.sqrt(20000)
    reseeded = RealisticMachine.from_dict(rm.to_dict() | {"seed": 1})
    assert not np.array_equal(reseeded.simulate(u, noise=True), meas)


def test_disturbance_differs_between_trials_and_repeats_per_trial():
    sigma, bw = 0.2, 10.0
    rm = xyz(disturbance=sigma, disturbance_bandwidth=bw)
    n = 40000
    d0, d1 = rm.disturbance(n, 0), rm.disturbance(n, 1)
    np.testing.assert_array_equal(rm.disturbance(n, 0), d0)
    assert np.abs(np.corrcoef(d0[:, 0], d1[:, 0])[0, 1]) < 0.1
    # first-order low pass: correlation a = exp(-2 pi f_b dt) at lag 1, std sigma from
    # the first sample (stationary); n / (2 tau) ~ 2500 independent samples: 4 % at 3 sigma
    a = math.exp(-2 * math.pi * bw * rm.dt)
    np.testing.assert_allclose(d0.std(axis=0), sigma, rtol=0.06)
    np.testing.assert_allclose(np.corrcoef(d0[1:, 1], d0[:-1, 1])[0, 1], a, atol=0.02)
    # it enters at the input: on a linear machine the trials differ by G (d1 - d0)
    u = np.zeros((3000, 3))
    y0, y1 = rm.simulate(u, trial=0), rm.simulate(u, trial=1)
    want = rm.nominal().simulate(rm.disturbance(3000, 1) - rm.disturbance(3000, 0))
    np.testing.assert_allclose(y1 - y0, want, rtol=0, atol=1e-10 * np.abs(want).max())
    assert np.abs(want).max() > 0.1


@pytest.mark.parametrize("coulomb", [0.0, 1e-4])
def test_resonance_shows_a_peak_at_its_frequency(coulomb):
    f0, zeta = 20.0, 0.05
    rm = xyz(resonance_hz=f0, resonance_damping=zeta, coulomb=coulomb)
    rng = np.random.default_rng(3)
    u = rng.normal(size=(2**14, 3)) * 20.0
    y = rm.simulate(u)
    y_nom = rm.nominal().simulate(u)
    fs = 1 / rm.dt
    f, p_uy = signal.csd(u[:, 0], y[:, 0], fs=fs, nperseg=1024)
    _, p_un = signal.csd(u[:, 0], y_nom[:, 0], fs=fs, nperseg=1024)
    ratio = np.abs(p_uy / p_un)  # |R(j w)| estimated
    peak = f[np.argmax(ratio)]
    # |R| peaks at f0 sqrt(1 - 2 zeta^2) with height 1 / (2 zeta sqrt(1 - zeta^2)) ~ 10;
    # bins are fs / 1024 ~ 0.2 Hz apart
    assert abs(peak - f0 * math.sqrt(1 - 2 * zeta**2)) < 0.3
    assert 7 < ratio.max() < 12
    np.testing.assert_allclose(ratio[f < 2], 1.0, rtol=0.05)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (
            {"departures": {"x": {"friction": 0.1}}},
            "departures of axis 'x': got unknown parameter 'friction'",
        ),
        (
            {"departures": {"x": {"coulomb": -0.1}}},
            "departure coulomb of axis 'x': expected a number >= 0",
        ),
        (
            {"departures": {"y": {"noise": float("nan")}}},
            "departure noise of axis 'y': expected a finite number",
        ),
        (
            {"departures": {"y": {"ripple_pitch": 0.0}}},
            "departure ripple_pitch of axis 'y': expected a number > 0",
        ),
        (
            {"departures": {"z": {"static_ratio": 0.5}}},
            "departure static_ratio of axis 'z': expected a number >= 1",
        ),
        (
            {"departures": {"z": {"ripple": "0.1"}}},
            "departure ripple of axis 'z': expected a number",
        ),
        ({"departures": {"w": {}}}, "departures: got parameters for unknown axis 'w'"),
        ({"departures": [1, 2]}, "departures: expected a mapping"),
        ({"seed": -1}, "seed: expected an integer >= 0"),
        ({"seed": 1.5}, "seed: expected an integer >= 0"),
        ({"substeps": 0}, "substeps: expected an integer >= 1"),
        ({"friction": 1}, "machine: got unknown key 'friction'"),
    ],
)
def test_json_validation_names_the_field(change, match):
    d = json.loads((DATA / "realistic-xyz.json").read_text()) | change
    with pytest.raises(InputError, match=match):
        Machine.from_dict(d)


def test_friction_needs_a_force_to_position_plant():
    base = Machine.from_json(DATA / "xy-pdccilc.json")  # relative degree 0 and 1
    with pytest.raises(InputError, match="departures of axis 'x': .* relative degree >= 2, got 0"):
        RealisticMachine.from_machine(base, coulomb=0.1)
    rm = RealisticMachine.from_machine(base, viscous=0.1, noise=0.01)  # linear: fine
    assert rm.simulate(np.ones((10, 2))).shape == (10, 2)


def test_start_and_trial_are_checked():
    rm = xyz(ripple=0.1)
    with pytest.raises(InputError, match="start: expected 3 finite coordinates"):
        rm.simulate(np.zeros((5, 3)), start=[0.0, np.nan, 0.0])
    with pytest.raises(InputError, match="trial: expected an integer >= 0"):
        rm.simulate(np.zeros((5, 3)), trial=-1)


def test_fractions_of_the_typical_input():
    u = np.random.default_rng(5).normal(size=(500, 3)) * [3.0, 2.0, 1.0]
    big_u, big_v = typical_scales(XYZ, [u, u])
    np.testing.assert_allclose(big_u, np.sqrt(np.mean(u**2, axis=0)))
    v = np.gradient(XYZ.simulate(u), XYZ.dt, axis=0)
    np.testing.assert_allclose(big_v, np.sqrt(np.mean(v**2, axis=0)))
    rm = RealisticMachine.from_machine(
        XYZ,
        typical_input=big_u,
        typical_velocity=big_v,
        coulomb=0.02,
        viscous=0.02,
        ripple=[0.01, 0.02, 0.03],
        noise=0.001,
    )
    for i, a in enumerate(XYZ.axes):
        dep = rm.departures[a]
        assert dep["coulomb"] == pytest.approx(0.02 * big_u[i])
        assert dep["viscous"] * big_v[i] == pytest.approx(0.02 * big_u[i])
        assert dep["ripple"] == pytest.approx([0.01, 0.02, 0.03][i] * big_u[i])
        assert dep["noise"] == 0.001  # lengths are absolute
    with pytest.raises(InputError, match="typical_velocity: expected the typical speed"):
        RealisticMachine.from_machine(XYZ, typical_input=1.0, viscous=0.02)
    with pytest.raises(InputError, match="departures: got unknown parameter 'stiction'"):
        RealisticMachine.from_machine(XYZ, stiction=0.02)


def test_a_trial_runner_learns_on_the_machine_with_fresh_noise_each_trial():
    rm = Machine.from_json(DATA / "realistic-xyz.json")
    s = np.linspace(0.0, 1.0, 301)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    ref = np.column_stack([10 * blend, 5 * blend, 2 * blend])
    runner = rm.trials(start=[3.0, 4.0, 5.0])
    assert isinstance(runner, TrialRunner)
    res = learn(runner, ref, law="norm-optimal", model=rm.nominal(), iterations=4)
    k = len(res.rms_total)
    assert k >= 3 and runner.trial == k and len(runner.true) == k
    rms_true = [np.sqrt(np.mean((ref - y) ** 2)) for y in runner.true]
    assert rms_true[-1] < 0.5 * rms_true[0]
    # what ILC saw is the measurement: true motion + that trial's noise
    e_last = ref - runner.true[-1] - rm.measurement_noise(len(ref), k - 1)
    np.testing.assert_allclose(np.sqrt(np.mean(np.sum(e_last**2, axis=1))), res.rms_total[-1])


def test_speed_of_ten_thousand_samples_on_three_axes():
    rm = Machine.from_json(DATA / "realistic-xyz.json")
    u = np.cumsum(np.random.default_rng(7).normal(size=(10_000, 3)), axis=0) * 0.3
    t0 = time.process_time()
    y = rm.simulate(u, start=[1.0, 2.0, 3.0], trial=2, noise=True)
    assert time.process_time() - t0 < 4.0 and np.all(np.isfinite(y))


@pytest.mark.parametrize("ripple", [0.0, 0.1])
def test_the_written_out_three_state_axis_is_the_general_loop(ripple):
    # an axis with a lag has three states: its written-out step is the general loop's
    # arithmetic in the same order, so the same floats through stick, slip and reversals
    from primlib.plant._realistic_loop import _stepper, loop_kernel

    plants = {a: (n, np.convolve(d, [0.012, 1.0])) for a, (n, d) in XYZ.plants.items()}
    rm = RealisticMachine.from_machine(
        Machine("xyz", XYZ.dt, XYZ.axes, plants), coulomb=0.3, ripple=ripple, ripple_pitch=5.0
    )
    kern = loop_kernel("x", *rm.plants["x"], rm.departures["x"], rm.dt, rm.substeps)
    assert len(kern[1]) == 3
    fast, general = _stepper(kern, 2.0), _stepper(kern, 2.0, general=True)
    t = np.arange(600) * rm.dt
    states = [((0.0, 0.0, 0.0), 0.0), ([0.0, 0.0, 0.0], 0.0)]
    for cmd in 0.8 * np.sin(2 * np.pi * 1.3 * t):  # sticks at each reversal
        states = [fast(*states[0], cmd), general(*states[1], cmd)]
        assert tuple(states[0][0]) == tuple(states[1][0]) and states[0][1] == states[1][1]
