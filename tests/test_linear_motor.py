import copy
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from primlib import InputError
from primlib.plant import LinearMotor, Machine

JSON = Path(__file__).resolve().parents[1] / "data" / "machines" / "linear-motor.json"


def spec(**motor):
    # the physics tests drive forces directly: K = 1 N per input unit unless given
    d = json.loads(JSON.read_text())
    for axis in d["motors"]:
        d["motors"][axis].update({"K": 1.0} | motor)
    return d


def test_json_is_table1_and_dispatches_by_kind():
    m = Machine.from_json(JSON)
    assert isinstance(m, LinearMotor) and m.kind == "linear-motor"
    assert m.axes == ("x", "y") and m.dim == 2
    x, y = m.motors["x"], m.motors["y"]
    assert (x["M"], x["B"], x["Af"], x["Cc"], x["D"]) == (0.18, 26.34, 0.024, 2.25, 0.012)
    assert (y["M"], y["B"], y["Af"], y["Cc"], y["D"]) == (0.24, 35.07, 0.037, 0.27, 0.005)
    assert x["stribeck_velocity"] == 0.1 and x["stribeck_exponent"] == 1.0
    again = Machine.from_dict(json.loads(json.dumps(m.to_dict())))
    assert again == m and isinstance(again, LinearMotor)


@pytest.mark.parametrize("feedback", [None, {"kp": 6.5, "ki": 250.0, "kd": 0.04, "tf": 0.0}])
def test_without_friction_and_ripple_it_is_the_zoh_nominal_model(feedback):
    d = spec(Af=0.0, Cc=0.0, D=0.0)
    if feedback:
        d["feedback"] = {"x": feedback, "y": feedback}
    m = LinearMotor.from_dict(d)
    rng = np.random.default_rng(0)
    n = 800
    u = rng.normal(size=(n, 2))
    r = np.c_[np.sin(np.arange(n) * 3e-3), np.cos(np.arange(n) * 3e-3) - 1]
    nominal = m.nominal()
    y = m.simulate(u, r)
    want = nominal.simulate(u, r)
    # exact exponential integration of the linear part: equal up to rounding
    np.testing.assert_allclose(y, want, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(m.impulse_response(50), nominal.impulse_response(50))
    assert m.lifted(20).shape == (2, 20, 20)


def test_stiction_holds_below_the_static_level_and_slides_above():
    d = spec(Cc=0.0, D=0.0)
    m = LinearMotor.from_dict(d)
    static = np.array([0.024, 0.037]) * 1.5
    y = m.simulate(np.tile(0.99 * static, (300, 1)))
    assert np.all(y == 0.0)
    u = np.tile(3.0 * static, (3000, 1))
    y = m.simulate(u)
    assert np.all(y[-1] > 0)
    # terminal velocity: B v + A_f (1 + (r_s - 1) exp(-v / v_s)) = K u
    for i, (B, Af) in enumerate([(26.34, 0.024), (35.07, 0.037)]):
        v_end = (y[-1, i] - y[-2, i]) / m.dt * m.length_unit
        f = u[0, i]

        def balance(v, B=B, Af=Af, f=f):
            return B * v + Af * (1 + 0.5 * np.exp(-v / 0.1)) - f

        want = brentq(balance, 0, 1)
        np.testing.assert_allclose(v_end, want, rtol=1e-6)


def test_friction_stops_a_coasting_motor_for_good():
    m = LinearMotor.from_dict(spec(Cc=0.0, D=0.0))
    state = np.array([[0.0, 0.0], [0.01, -0.02]])
    for _ in range(400):
        state = m.advance(state, np.zeros(2))
    assert np.all(state[1] == 0.0)
    # it travelled less than the frictionless coast M v0 / B
    assert np.all(np.abs(state[0]) < np.abs([0.01 * 0.18 / 26.34, 0.02 * 0.24 / 35.07]))
    held = m.advance(state, np.zeros(2))
    np.testing.assert_array_equal(held, state)


def test_ripple_depends_on_the_absolute_start():
    m = LinearMotor.from_dict(spec(Af=0.0, D=0.0))
    u = np.zeros((200, 2))
    # at x = 0 and x = pitch/2 the ripple force is zero but its slope has opposite signs;
    # at a quarter pitch it pushes at full amplitude (-C_c)
    assert np.all(m.simulate(u, start=[0.0, 0.0]) == 0.0)
    y = m.simulate(u, start=[7.5, 7.5])
    assert np.all(y[-1] < 0)


def test_substeps_converge():
    d = spec()
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(scale=0.05, size=(1000, 2)), axis=0)
    d4 = copy.deepcopy(d)
    d32 = copy.deepcopy(d)
    d32["substeps"] = 32
    y4 = LinearMotor.from_dict(d4).simulate(u, start=[3.0, 1.0])
    y32 = LinearMotor.from_dict(d32).simulate(u, start=[3.0, 1.0])
    assert np.max(np.abs(y4 - y32)) <= 1e-3 * np.max(np.abs(y32))


def test_bad_input():
    d = spec()
    del d["motors"]["x"]["M"]
    with pytest.raises(InputError, match="motor of axis 'x': expected parameter 'M', got none"):
        Machine.from_dict(d)
    with pytest.raises(InputError, match="motor B of axis 'x': expected a number > 0, got -1"):
        LinearMotor.from_dict(spec(B=-1.0))
    with pytest.raises(InputError, match="got unknown parameter 'mass'"):
        LinearMotor.from_dict(spec(mass=1.0))
    d = spec()
    d["substeps"] = 0
    with pytest.raises(InputError, match="substeps: expected an integer >= 1, got 0"):
        LinearMotor.from_dict(d)
    d = spec()
    d["speed"] = 1
    with pytest.raises(InputError, match="machine: got unknown key 'speed'"):
        LinearMotor.from_dict(d)
    d = spec()
    del d["motors"]["y"]
    with pytest.raises(InputError, match="motors: expected parameters for axis 'y'"):
        LinearMotor.from_dict(d)
    m = LinearMotor.from_dict(spec())
    with pytest.raises(InputError, match=r"start: expected 2 finite coordinates"):
        m.simulate(np.zeros((5, 2)), start=[1.0])
    with pytest.raises(InputError, match=r"u: expected an array of shape \(n, 2\)"):
        m.simulate(np.zeros((5, 3)))
    with pytest.raises(InputError, match="length_unit: expected a number > 0"):
        LinearMotor("m", 0.001, ["x"], {"x": spec()["motors"]["x"]}, length_unit=0.0)
