"""Machine: simulation against scipy.signal.dlsim, lifted matrices, JSON, bad input, invert."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from primlib import InputError
from primlib.plant import Machine, invert, machine_kinds, register_kind
from primlib.plant import _machine as machine_module

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"

# eq. (24), primitive-matching paper
XYZ = {
    "x": ([1.066], [0.1876, 1.0, 0.0]),
    "y": ([1.1746], [0.2687, 1.0, 0.0]),
    "z": ([2.0523], [0.3138, 1.0, 0.0]),
}
# eq. (33), master-slave PDCCILC paper (non-minimum-phase, x biproper)
XY = {
    "x": ([6.878e-5, -0.1402, 5.291], [1.0, 5.795, 5.564]),
    "y": ([-0.0631, 2.132], [1.0, 2.76, 2.127]),
}
PID_TABLE1 = {"kp": 3.0, "ki": 1.0, "kd": 0.0}  # Table 1, master-slave PDCCILC paper


_CACHE: dict = {}


def _machines():
    if not _CACHE:
        _CACHE.update(_build_machines())
    return _CACHE


def _build_machines():
    return {
        "xyz": Machine("xyz", 0.005, ["x", "y", "z"], XYZ),
        "xyz-pid": Machine(
            "xyz-pid",
            0.005,
            ["x", "y", "z"],
            XYZ,
            {
                "x": {"kp": 20.0, "ki": 5.0, "kd": 0.2, "tf": 0.01},
                "y": {"kp": 15.0, "ki": 0.0, "kd": 0.1},
                "z": {"kp": 10.0, "ki": 2.0},
            },
        ),
        "xy": Machine("xy", 0.005, ["x", "y"], XY),
        "xy-pid": Machine("xy-pid", 0.005, ["x", "y"], XY, {"x": PID_TABLE1, "y": PID_TABLE1}),
    }


def _closed_loop_ss(machine, i):
    """Independent closed loop: ZOH state space of the plant, PID state space, algebraic loop
    solved, assembled into one discrete state-space system with inputs (u, r)."""
    axis = machine.axes[i]
    num, den = machine.plants[axis]
    A, B, C, D, _ = signal.cont2discrete(signal.tf2ss(num, den), machine.dt, method="zoh")
    pid = (machine.feedback or {}).get(axis)
    if pid is None:
        return A, np.hstack([B, 0 * B]), C, np.hstack([D, 0 * D])
    dt, kp, ki, kd, tf = machine.dt, pid["kp"], pid["ki"], pid["kd"], pid.get("tf", 0.0)
    # PID states: integral I_k = I_{k-1} + ki dt e_k, filtered derivative
    # D_k = (tf D_{k-1} + kd (e_k - e_{k-1})) / (tf + dt); controller state xc = (I_{k-1},
    # D_{k-1}, e_{k-1}); output c_k = kp e_k + I_k + D_k = Cc xc + Dc e_k
    Cc = np.array([[1.0, tf / (tf + dt), -kd / (tf + dt)]])
    Dc = np.array([[kp + ki * dt + kd / (tf + dt)]])
    # next controller state from (xc, e_k): (I_k, D_k, e_k)
    Ac = np.array([[1.0, 0.0, 0.0], [0.0, tf / (tf + dt), -kd / (tf + dt)], [0.0, 0.0, 0.0]])
    Bc = np.array([[ki * dt], [kd / (tf + dt)], [1.0]])
    # v = u + c, e = r - y, y = C x + D v  =>  y = (C x + D u + D Cc xc + D Dc r) / (1 + D Dc)
    s = 1.0 / (1.0 + D[0, 0] * Dc[0, 0])
    Cy = s * np.hstack([C, D @ Cc])
    Dy = s * np.hstack([D, D @ Dc])
    # e = r - y, v = u + Cc xc + Dc e
    Ce = -Cy
    De = np.array([[0.0, 1.0]]) - Dy
    Cv = np.hstack([np.zeros_like(C), Cc]) + Dc @ Ce
    Dv = np.array([[1.0, 0.0]]) + Dc @ De
    nx, nc = A.shape[0], Ac.shape[0]
    Acl = np.block([[A, np.zeros((nx, nc))], [np.zeros((nc, nx)), Ac]])
    Acl = Acl + np.vstack([B @ Cv, Bc @ Ce])
    Bcl = np.vstack([B @ Dv, Bc @ De])
    return Acl, Bcl, Cy, Dy


@pytest.mark.parametrize("key", ["xyz", "xyz-pid", "xy", "xy-pid"])
def test_simulate_matches_dlsim(key):
    m = _machines()[key]
    rng = np.random.default_rng(0)
    n = 3000
    u = rng.standard_normal((n, m.dim))
    r = np.cumsum(rng.standard_normal((n, m.dim)), axis=0) * 0.01
    y = m.simulate(u, reference=r)
    for i in range(m.dim):
        A, B, C, D = _closed_loop_ss(m, i)
        _, y_ref, _ = signal.dlsim((A, B, C, D, m.dt), np.column_stack([u[:, i], r[:, i]]))
        scale = np.max(np.abs(y_ref))
        # both are exact recursions of the same system; the difference is rounding in
        # ~n operations on numbers of size `scale`
        np.testing.assert_allclose(y[:, i], y_ref[:, 0], rtol=0, atol=1e-10 * scale)


@pytest.mark.parametrize("key", ["xyz", "xy-pid"])
def test_reference_response_is_simulate_with_zero_u(key):
    m = _machines()[key]
    r = np.random.default_rng(1).standard_normal((500, m.dim))
    np.testing.assert_array_equal(m.reference_response(r), m.simulate(np.zeros_like(r), r))


@pytest.mark.parametrize("key", ["xyz", "xyz-pid", "xy", "xy-pid"])
def test_lifted_times_u_is_simulate(key):
    m = _machines()[key]
    n = 400
    u = np.random.default_rng(2).standard_normal((n, m.dim))
    T = m.lifted(n)
    assert T.shape == (m.dim, n, n)
    assert np.all(np.triu(T, 1) == 0)
    y = m.simulate(u)
    lifted_y = np.einsum("dij,jd->id", T, u)
    np.testing.assert_allclose(lifted_y, y, rtol=0, atol=1e-12 * np.max(np.abs(y)))


def test_impulse_response_matches_dimpulse():
    m = _machines()["xy"]
    h = m.impulse_response(300)
    for i in range(m.dim):
        A, B, C, D = _closed_loop_ss(m, i)
        _, (h_ref, _) = signal.dimpulse((A, B, C, D, m.dt), n=300)
        np.testing.assert_allclose(h[:, i], h_ref[:, 0], rtol=0, atol=1e-14)


def test_relative_degree():
    ms = _machines()
    np.testing.assert_array_equal(ms["xyz"].relative_degree, [1, 1, 1])
    # x of eq. (33) has direct feedthrough 6.878e-5 (numerator degree 2 = denominator degree)
    np.testing.assert_array_equal(ms["xy-pid"].relative_degree, [0, 1])
    assert ms["xy"].impulse_response(2)[0, 0] == pytest.approx(6.878e-5, rel=1e-12)


def test_pid_closed_loop_is_stable_and_tracks_a_step():
    m = Machine.from_json(DATA / "xy-pdccilc.json")
    for _, _, den in m.closed_loop():
        assert np.max(np.abs(np.roots(den))) < 1.0
    n = int(40 / m.dt)
    y = m.reference_response(np.ones((n, 2)))
    # integral action: zero steady-state error to a step
    np.testing.assert_allclose(y[-1], 1.0, atol=1e-3)


@given(st.floats(-3, 3), st.floats(-3, 3), st.integers(0, 50), st.sampled_from(["xyz-pid", "xy"]))
@settings(max_examples=25, deadline=None)
def test_simulate_is_linear_and_time_invariant(alpha, beta, shift, key):
    m = _machines()[key]
    rng = np.random.default_rng(3)
    u1, u2 = rng.standard_normal((2, 200, m.dim))
    y = m.simulate(alpha * u1 + beta * u2)
    ref = alpha * m.simulate(u1) + beta * m.simulate(u2)
    np.testing.assert_allclose(y, ref, atol=1e-11 * (1 + np.max(np.abs(ref))))
    shifted = np.zeros_like(u1)
    shifted[shift:] = u1[: 200 - shift]
    np.testing.assert_allclose(
        m.simulate(shifted)[shift:], m.simulate(u1)[: 200 - shift], atol=1e-12
    )


# ----------------------------------------------------------------------------- JSON


@pytest.mark.parametrize("name", ["xyz.json", "xy-pdccilc.json"])
def test_bundled_machines_round_trip(name, tmp_path):
    m = Machine.from_json(DATA / name)
    assert m.kind == "lti"
    out = tmp_path / name
    m.to_json(out)
    again = Machine.from_json(out)
    assert again == m
    assert again.to_dict() == m.to_dict()
    assert Machine.from_dict(json.loads(out.read_text())) == m


def test_io_reads_and_writes_machine_json_as_dicts(tmp_path):
    # io knows files and JSON, plant knows machines: no import cycle between them
    from primlib.io import read_machine_json, write_machine_json

    m = Machine.from_json(DATA / "xy-pdccilc.json")
    out = tmp_path / "m.json"
    write_machine_json(out, m.to_dict())
    assert read_machine_json(out) == m.to_dict()
    assert Machine.from_json(out) == m
    with pytest.raises(InputError, match=r"missing\.json: expected a machine JSON file, got no"):
        read_machine_json(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{", encoding="utf-8")
    with pytest.raises(InputError, match=r"bad\.json: expected valid JSON, got .* at line 1"):
        Machine.from_json(tmp_path / "bad.json")
    (tmp_path / "list.json").write_text("[1]", encoding="utf-8")
    with pytest.raises(InputError, match=r"list\.json: machine: expected a JSON object, got list"):
        read_machine_json(tmp_path / "list.json")


def test_bundled_xyz_is_eq24():
    m = Machine.from_json(DATA / "xyz.json")
    assert m.axes == ("x", "y", "z") and m.dt == 0.005 and m.feedback is None
    for axis, (num, den) in XYZ.items():
        np.testing.assert_array_equal(m.plants[axis][0], num)
        np.testing.assert_array_equal(m.plants[axis][1], den)


def test_api_example_without_kind():
    d = {
        "name": "xyz",
        "dt": 0.005,
        "axes": ["x", "y", "z"],
        "plants": {a: {"num": n, "den": dd} for a, (n, dd) in XYZ.items()},
        "feedback": None,
    }
    m = Machine.from_dict(d)
    assert m == _machines()["xyz"]
    assert m.to_dict()["kind"] == "lti"


def test_register_kind_dispatch(monkeypatch):
    class Other(Machine):
        kind = "other-test"

        @classmethod
        def from_dict(cls, d):
            d = {k: v for k, v in d.items() if k != "kind"}
            return super().from_dict(d) if cls is not Other else cls._make(d)

        @classmethod
        def _make(cls, d):
            return cls(d["name"], d["dt"], d["axes"], d["plants"], d.get("feedback"))

    monkeypatch.setitem(machine_module._KINDS, "other-test", Other)
    d = _machines()["xy"].to_dict() | {"kind": "other-test"}
    m = Machine.from_dict(d)
    assert type(m) is Other and m.kind == "other-test"
    assert "other-test" in machine_kinds()
    with pytest.raises(InputError, match="kind: expected a non-empty string"):
        register_kind("", Other)
    with pytest.raises(InputError, match="expected a class with a from_dict method"):
        register_kind("nope", object())


# ----------------------------------------------------------------------------- bad input

_GOOD = {"x": ([1.0], [0.2, 1.0, 0.0])}


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"dt": 0.0}, r"dt: expected a finite sample time > 0 s, got 0\.0"),
        ({"dt": -1}, r"dt: expected a finite sample time > 0 s, got -1"),
        ({"dt": "fast"}, r"dt: expected a sample time in seconds, got 'fast'"),
        ({"name": ""}, "name: expected a non-empty string"),
        ({"axes": []}, "axes: expected at least one axis"),
        ({"axes": "x"}, "axes: expected a list of non-empty axis names"),
        ({"axes": ["x", "x"]}, "axes: expected distinct axis names"),
        ({"axes": ["x", "y"]}, "plants: expected a transfer function for axis 'y'"),
        ({"plants": {"x": _GOOD["x"], "q": _GOOD["x"]}}, "unknown axis 'q'"),
        (
            {"plants": {"x": ([1.0, 2.0, 3.0], [1.0, 1.0])}},
            "axis 'x': expected a proper transfer function .*got numerator degree 2",
        ),
        (
            {"plants": {"x": ([1.0], [0.0, 1.0, 0.0])}},
            "denominator of axis 'x': expected a non-zero leading coefficient",
        ),
        (
            {"plants": {"x": ([np.nan], [1.0, 1.0])}},
            "numerator of axis 'x': expected finite coefficients",
        ),
        (
            {"plants": {"x": ([1.0], [1.0, np.inf])}},
            "denominator of axis 'x': expected finite coefficients",
        ),
        (
            {"plants": {"x": ([1.0], [1.0, -2.0])}},
            r"plant of axis 'x': expected no pole with positive real part, got 2",
        ),
        ({"plants": {"x": ([0.0], [1.0, 2.0])}}, "numerator of axis 'x': expected a non-zero"),
        ({"plants": {"x": ("a", [1.0])}}, "numerator of axis 'x': expected a list of numbers"),
        ({"plants": {"x": {"num": [1.0]}}}, "plant of axis 'x': expected keys num and den"),
        ({"plants": {"x": 3}}, r"plant of axis 'x': expected \(num, den\)"),
        ({"feedback": {"x": {"kp": 1, "kq": 2}}}, "feedback of axis 'x': .*unknown \\['kq'\\]"),
        ({"feedback": {"y": {"kp": 1}}}, "feedback: got gains for unknown axis 'y'"),
        ({"feedback": {"x": {"kp": "big"}}}, "feedback kp of axis 'x': expected a number"),
        ({"feedback": {"x": {"kp": np.inf}}}, "feedback kp of axis 'x': expected a finite"),
        ({"feedback": {"x": {"kp": 1, "tf": -1}}}, "feedback tf of axis 'x': expected a filter"),
        (
            {"feedback": {"x": {"kp": -1.0}}},
            "feedback of axis 'x': expected an asymptotically stable closed loop",
        ),
    ],
)
def test_bad_machine(kwargs, message):
    args = {"name": "m", "dt": 0.005, "axes": ["x"], "plants": _GOOD, "feedback": None} | kwargs
    with pytest.raises(InputError, match=message):
        Machine(**args)


def test_unstable_loop_with_huge_gain_is_rejected():
    # ZOH delay destabilises a stiff proportional loop on an integrating plant
    with pytest.raises(InputError, match=r"axis 'x': expected an asymptotically stable.*\|z\|"):
        Machine("m", 0.005, ["x"], _GOOD, {"x": {"kp": 1e4}})


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"colour": "red"}, "machine: got unknown key 'colour'"),
        ({"kind": "warp-drive"}, "machine kind: expected one of .*lti.*, got 'warp-drive'"),
        ({"axes": "xyz"}, "axes: expected a list of axis names"),
        ({"note": 3}, "note: expected a string"),
    ],
)
def test_bad_dict(change, message):
    d = _machines()["xyz"].to_dict() | change
    with pytest.raises(InputError, match=message):
        Machine.from_dict(d)


def test_missing_key_and_not_a_mapping():
    d = _machines()["xyz"].to_dict()
    del d["dt"]
    with pytest.raises(InputError, match="machine: expected key 'dt', got none"):
        Machine.from_dict(d)
    with pytest.raises(InputError, match="machine: expected a JSON object, got list"):
        Machine.from_dict([1, 2])


def test_bad_json_files_name_the_file(tmp_path):
    missing = tmp_path / "none.json"
    with pytest.raises(InputError, match="none.json: expected a machine JSON file, got no such"):
        Machine.from_json(missing)
    broken = tmp_path / "broken.json"
    broken.write_text('{"name": "x",')
    with pytest.raises(InputError, match="broken.json: expected valid JSON, got .* at line 1"):
        Machine.from_json(broken)
    unstable = tmp_path / "unstable.json"
    d = _machines()["xyz"].to_dict()
    d["plants"]["y"]["den"] = [1.0, -1.0]
    unstable.write_text(json.dumps(d))
    with pytest.raises(
        InputError, match="unstable.json: plant of axis 'y': expected no pole with positive"
    ):
        Machine.from_json(unstable)


@pytest.mark.parametrize(
    ("u", "reference", "message"),
    [
        (np.zeros((10, 2)), None, r"u: expected an array of shape \(n, 3\) for axes x,y,z, got"),
        (np.full((10, 3), np.nan), None, "u: expected finite values, got NaN or inf"),
        (np.zeros((10, 3)), np.zeros((9, 3)), r"reference: expected the shape of u \(10, 3\)"),
        (np.zeros((10, 3)), np.zeros((10, 1)), r"reference: expected an array of shape \(n, 3\)"),
    ],
)
def test_bad_signals(u, reference, message):
    with pytest.raises(InputError, match=message):
        _machines()["xyz"].simulate(u, reference)


@pytest.mark.parametrize("n", [0, -3, 2.5, True])
def test_bad_n(n):
    with pytest.raises(InputError, match="n: expected a number of samples >= 1"):
        _machines()["xyz"].lifted(n)


# ----------------------------------------------------------------------------- invert


def _smooth(m, n=1201, scale=1.0):
    s = np.linspace(0, 1, n)
    bump = 10 * s**3 - 15 * s**4 + 6 * s**5  # rest to rest
    return scale * np.column_stack([(i + 1) * bump for i in range(m.dim)])


def test_invert_is_exact_for_minimum_phase_axes():
    m = _machines()["xyz"]
    yd = _smooth(m)
    u = invert(m, yd)
    np.testing.assert_allclose(m.simulate(u), yd, rtol=0, atol=1e-9)


@pytest.mark.parametrize("key", ["xy", "xy-pid"])
def test_invert_nonminimum_phase_is_bounded_and_close(key):
    m = _machines()[key]
    yd = _smooth(m, n=2401)
    r = yd if m.feedback else None
    y_target = yd
    u = invert(m, y_target, reference=r)
    assert np.all(np.isfinite(u))
    # the truncated pre-actuation leaves an error confined to the start, small because the
    # desired output starts at rest (third-order contact)
    err = m.simulate(u, r) - y_target
    assert np.max(np.abs(err)) < 1e-4 * np.max(np.abs(yd))
    # forcing the causal inverse on the NMP axis blows up: that is why "auto" avoids it
    u_bad = invert(m, y_target, reference=r, method="causal")
    with np.errstate(invalid="ignore"):
        assert not np.all(np.abs(u_bad) < 1e6 * np.max(np.abs(u)))


def test_invert_lifted_agrees():
    m = _machines()["xy-pid"]
    yd = _smooth(m, n=801)
    u = invert(m, yd, reference=yd, method="lifted", reg=1e-12)
    err = m.simulate(u, yd) - yd
    # as with "stable", exact tracking of the first samples of an NMP axis would need
    # pre-actuation; the regularised solve trades a small error there for a bounded input
    assert np.max(np.abs(err)) < 1e-4 * np.max(np.abs(yd))
    assert np.max(np.abs(err[100:])) < 1e-8 * np.max(np.abs(yd))
    u_stable = invert(m, yd, reference=yd)
    assert np.max(np.abs(u)) < 1.5 * np.max(np.abs(u_stable))


def test_invert_bad_input():
    m = _machines()["xyz"]
    with pytest.raises(InputError, match="method: expected one of auto, causal"):
        invert(m, _smooth(m), method="magic")
    with pytest.raises(InputError, match="reg: expected a finite regularisation weight > 0"):
        invert(m, _smooth(m), reg=0.0)
    with pytest.raises(InputError, match=r"y_desired: expected an array of shape \(n, 3\)"):
        invert(m, np.zeros((5, 2)))
    with pytest.raises(InputError, match="method 'lifted' solves a dense n x n system"):
        invert(m, np.zeros((6001, 3)), method="lifted")


# ----------------------------------------------------------------------------- properties


@st.composite
def _stable_tf(draw):
    """A random proper transfer function with poles in the closed left half plane (at most
    one integrator), real or complex pairs."""
    n_real = draw(st.integers(0, 2))
    n_pair = draw(st.integers(0, 1))
    integrator = draw(st.booleans())
    poles = [-draw(st.floats(0.5, 50.0)) for _ in range(n_real)]
    for _ in range(n_pair):
        sigma, omega = draw(st.floats(0.5, 20.0)), draw(st.floats(0.5, 30.0))
        poles += [complex(-sigma, omega), complex(-sigma, -omega)]
    if integrator or not poles:
        poles.append(0.0)
    den = np.real(np.poly(poles))
    n_num = draw(st.integers(1, len(den)))
    num = [draw(st.floats(-3.0, 3.0)) for _ in range(n_num)]
    if abs(num[0]) < 1e-3:
        num[0] = 1.0
    return num, den.tolist()


@given(_stable_tf(), st.sampled_from([None, {"kp": 0.5, "ki": 0.1}]))
@settings(max_examples=30, deadline=None)
def test_random_machines_round_trip_and_match_dlsim(tf, pid):
    try:
        m = Machine("rand", 0.005, ["x"], {"x": tf}, None if pid is None else {"x": pid})
    except InputError as exc:
        # a random PID may not stabilise a random plant: the message says so
        assert "asymptotically stable closed loop" in str(exc)
        return
    assert Machine.from_dict(json.loads(json.dumps(m.to_dict()))) == m
    u = np.random.default_rng(4).standard_normal((400, 1))
    A, B, C, D = _closed_loop_ss(m, 0)
    _, y_ref, _ = signal.dlsim((A, B, C, D, m.dt), np.column_stack([u[:, 0], 0 * u[:, 0]]))
    y = m.simulate(u)
    # Two routes to the same ZOH model (transfer-function filter vs state space) differ by
    # rounding in the polynomial coefficients, whose sensitivity to the poles grows like
    # prod 1/|1 - z_i| when discrete poles cluster near z = 1 (e.g. s(s+1)(s^2+2s+2) at
    # 5 ms: four poles within 0.007 of 1, kappa ~ 1e9): tolerance 1e-9 plus eps * kappa.
    z = np.linalg.eigvals(A)
    kappa = float(np.prod(1.0 / np.maximum(np.abs(1.0 - z), m.dt)))
    tol = (1e-9 + np.finfo(float).eps * kappa) * (1 + np.abs(y_ref).max())
    np.testing.assert_allclose(y[:, 0], y_ref[:, 0], rtol=0, atol=tol)


# ---------------------------------------------------------------- issue 12: machine JSON
def _xyz_json(**change):
    """The bundled xyz machine's JSON with ``key__sub__leaf=value`` changes (feedback created
    as needed)."""
    d = json.loads((DATA / "xyz.json").read_text(encoding="utf-8"))
    for key, value in change.items():
        *path, leaf = key.split("__")
        node = d
        for p in path:
            if node.get(p) is None:
                node[p] = {}
            node = node[p]
        node[leaf] = value
    return d


@pytest.mark.parametrize(
    ("case", "change", "message"),
    [
        (
            "dt_1e6",
            {"dt": 1e6},
            r"dt: expected a sample time between 1e-07 s and 10 s, got 1e\+06 s",
        ),
        (
            "dt_1e-12",
            {"dt": 1e-12},
            r"dt: expected a sample time between 1e-07 s and 10 s, got 1e-12",
        ),
        ("dt_string", {"dt": "0.005"}, r"dt: expected a sample time in seconds, got '0\.005'"),
        ("dt_bool", {"dt": True}, r"dt: expected a sample time in seconds, got True"),
        (
            "num_string",
            {"plants__x__num": ["1.066"]},
            r"numerator of axis 'x': expected a list of numbers, got \['1\.066'\]",
        ),
        (
            "den_huge",
            {"plants__x__den": [1e300, 1.0, 0.0]},
            r"denominator of axis 'x': expected coefficients of magnitude <= 1e\+09",
        ),
        (
            "kp_string",
            {"feedback__x__kp": "3"},
            r"feedback kp of axis 'x': expected a number, got '3'",
        ),
        (
            "kd_huge",
            {"feedback__x__kd": 1e12},
            r"feedback kd of axis 'x': expected a finite number of magnitude <= 1e\+09, got 1e\+12",
        ),
        (
            "kind_unknown",
            {"kind": "warp-drive"},
            r"machine kind: expected one of .*, got 'warp-drive'",
        ),
    ],
)
def test_machine_json_with_bad_number_is_refused_naming_file_and_key(
    tmp_path, case, change, message
):
    path = tmp_path / f"{case}.json"
    path.write_text(json.dumps(_xyz_json(**change)), encoding="utf-8")
    with pytest.raises(InputError, match=rf"^{re.escape(str(path))}: {message}") as err:
        Machine.from_json(path)
    assert "\n" not in str(err.value)


def test_machine_json_dt_string_is_refused_by_machine_add_with_exit_2(tmp_path):
    from click.testing import CliRunner

    from primlib.cli import main

    path = tmp_path / "m.json"
    path.write_text(json.dumps(_xyz_json(dt="0.005")), encoding="utf-8")
    db = tmp_path / "lib.duckdb"
    res = CliRunner().invoke(main, ["--db", str(db), "machine", "add", str(path)])
    assert res.exit_code == 2
    assert "m.json: dt: expected a sample time in seconds, got '0.005'" in res.output
    assert not db.exists()


def test_machine_dt_range_bounds_are_accepted():
    for dt in (1e-7, 10.0):
        assert Machine("m", dt, ["x"], _GOOD).dt == dt


def test_linear_motor_json_with_string_parameter_is_refused_naming_the_key(tmp_path):
    d = json.loads((DATA / "linear-motor.json").read_text(encoding="utf-8"))
    d["motors"]["x"]["M"] = "0.18"
    path = tmp_path / "motor.json"
    path.write_text(json.dumps(d), encoding="utf-8")
    with pytest.raises(InputError, match=r"motor\.json: motor M of axis 'x': expected a number"):
        Machine.from_json(path)
    d["motors"]["x"]["M"] = 0.18
    d["length_unit"] = "1e-3"
    path.write_text(json.dumps(d), encoding="utf-8")
    with pytest.raises(InputError, match=r"motor\.json: length_unit: expected a number, got"):
        Machine.from_json(path)
