import json
from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.contour import OnlineContourEstimator, contour_error, ellipse_contour_error
from primlib.mfac import (
    CFDLMFAC,
    PID,
    MFACGains,
    cross_coupled,
    mfac_increment,
    ppd_update,
    run_contouring,
)
from primlib.plant import LinearMotor

JSON = Path(__file__).resolve().parents[1] / "data" / "machines" / "linear-motor.json"


def test_ppd_update_is_eq18_and_resets():
    g = MFACGains(eta=0.7, mu=0.5, reset=1e-6)
    phi, du, dy, phi0 = np.array([0.2, 0.3]), np.array([0.1, -0.2]), np.array([0.05, -0.1]), 0.2
    want = phi + 0.7 * du / (0.5 + du**2) * (dy - phi * du)
    np.testing.assert_allclose(ppd_update(phi, du, dy, phi0, g), want, rtol=1e-15)
    # a vanishing input change, a vanishing or sign-flipped estimate: back to phi0
    assert ppd_update([0.2], [1e-9], [0.0], 0.2, g)[0] == 0.2
    assert ppd_update([0.2], [1.0], [-5.0], 0.2, g)[0] == 0.2  # estimate turns negative
    # with mu -> 0 and eta = 1 one step recovers the true PPD exactly
    g1 = MFACGains(eta=1.0, mu=1e-12)
    np.testing.assert_allclose(ppd_update([0.5], [0.3], [0.3 * 1.7], 0.5, g1), [1.7], rtol=1e-9)


def test_mfac_increment_sums_to_a_pi_law():
    g = MFACGains(rho=2.0, lam=0.5, k1=3.0)
    phi = np.array([0.4])
    gain = 2.0 * 0.4 / (0.5 + 0.16)
    rng = np.random.default_rng(0)
    err = rng.normal(size=20)
    u = np.cumsum([mfac_increment(phi, err[k], err[k - 1] if k else 0.0, g)[0] for k in range(20)])
    np.testing.assert_allclose(u, gain * (3.0 * err + np.cumsum(err)), rtol=1e-12)


def test_mfac_regulates_a_first_order_plant_without_offset():
    # y(k+1) = 0.9 y(k) + 0.05 u(k): static gain 0.5; MFAC's sum term removes the offset
    c = CFDLMFAC(MFACGains(rho=0.6, lam=1.0, k1=0.0, eta=0.5, mu=1.0), phi0=[0.05])
    y = np.zeros(1)
    for _ in range(3000):
        u = c.step(y, np.array([1.0]))
        y = 0.9 * y + 0.05 * u
    np.testing.assert_allclose(y, 1.0, atol=1e-6)
    assert c.phi[0] > 0


def test_cross_coupling_pushes_back_to_the_path():
    # path along +x, point 0.1 to its left (error +0.1, left normal +y): push toward -y
    e = contour_error(
        np.c_[np.linspace(0, 1, 5), np.zeros(5)],
        np.linspace(0, 1, 5),
        np.c_[np.linspace(0, 1, 5), np.full(5, 0.1)],
        "linear",
    )
    U = cross_coupled(np.zeros((5, 2)), e, np.tile([0.0, 1.0], (5, 1)), 2.0)
    np.testing.assert_allclose(U, np.tile([0.0, -0.2], (5, 1)), atol=1e-12)


def _motor(K=1.0):
    d = json.loads(JSON.read_text())
    for axis in d["motors"]:
        d["motors"][axis]["K"] = K
    return LinearMotor.from_dict(d)


def test_pid_loop_equals_machine_feedback():
    gains = {"kp": 6.5, "ki": 250.0, "kd": 0.04, "tf": 0.0}
    d = json.loads(JSON.read_text())
    for axis in d["motors"]:
        d["motors"][axis]["K"] = 1.0
    d["feedback"] = {"x": gains, "y": gains}
    m = LinearMotor.from_dict(d)
    n = 600
    t = np.arange(n + 1) * m.dt
    ref = np.c_[10 * np.sin(t), 5 * np.cos(t)]
    start = ref[0]
    y = m.simulate(np.zeros((n, 2)), ref[:n] - start, start=start)
    open_loop = _motor(1.0)
    run = run_contouring(open_loop, ref, PID(6.5, 250.0, 0.04, m.dt))
    np.testing.assert_allclose(run.actual - start, y, atol=1e-12)


def test_mfac_contouring_on_the_motor_tracks_and_estimates():
    m = _motor(12.0)
    n = 800
    t = np.arange(n + 1) * m.dt
    ref = np.c_[10 * np.sin(t), 5 * np.cos(t)]
    est = OnlineContourEstimator(ref, t, "exact", ellipse=(10, 5, (0, 0), True))
    phi0 = 12.0 * m.dt / np.array([26.34, 35.07])
    run = run_contouring(m, ref, CFDLMFAC(MFACGains(), phi0), est, ccc_gain=1.0, scale=1e-3)
    true = ellipse_contour_error(10, 5, run.actual)
    np.testing.assert_allclose(run.estimate, true, atol=1e-12)
    assert np.max(np.abs(true)) < 0.1  # mm: tracks the ellipse from the first revolution
    assert np.all(run.phi > 0)


def test_diverging_gains_stop_with_an_error():
    m = _motor(1.0)
    n = 400
    t = np.arange(n + 1) * m.dt
    ref = np.c_[10 * np.sin(t), 5 * np.cos(t)]
    phi0 = m.dt / np.array([26.34, 35.07])  # u a force in N: loop gain far too high
    with pytest.raises(InputError, match="gains: the closed loop diverged at t ="):
        run_contouring(m, ref, CFDLMFAC(MFACGains(), phi0 * 1e-3 * 1e3), scale=1.0)


@pytest.mark.parametrize("method", ["linear", "circular"])
def test_online_estimator_equals_batch(method):
    t = np.linspace(0, 2, 401)
    ref = np.c_[3 * np.sin(1.5 * t) + t, 2 * np.cos(t)]
    rng = np.random.default_rng(1)
    actual = ref + rng.normal(scale=0.02, size=ref.shape)
    online = OnlineContourEstimator(ref, t, method)
    got = np.array([online(k, actual[k])[0] for k in range(len(t))])
    np.testing.assert_allclose(got, contour_error(ref, t, actual, method), atol=1e-12)
    general = OnlineContourEstimator(ref, t, "exact")
    got = np.array([general(k, actual[k])[0] for k in range(0, len(t), 40)])
    np.testing.assert_allclose(got, contour_error(ref, t, actual)[::40], atol=1e-12)


def test_online_estimator_counter_clockwise_ellipse_sign():
    t = np.linspace(0, 6, 601)
    ref = np.c_[10 * np.cos(t), 5 * np.sin(t)]  # counter-clockwise: left is inside
    est = OnlineContourEstimator(ref, t, "exact", ellipse=(10, 5, (0, 0), False))
    e, n = est(100, 0.98 * ref[100])
    assert e > 0
    np.testing.assert_allclose(e, contour_error(ref, t, 0.98 * ref)[100], atol=1e-9)


def test_bad_input():
    with pytest.raises(InputError, match="rho: expected a finite number > 0, got -1"):
        MFACGains(rho=-1)
    with pytest.raises(InputError, match="eta: expected a step in"):
        MFACGains(eta=2.5)
    with pytest.raises(InputError, match="phi0: expected finite non-zero initial PPDs"):
        CFDLMFAC(MFACGains(), [0.0, 1.0])
    m = _motor()
    ref = np.zeros((10, 2))
    with pytest.raises(InputError, match="estimator: expected a contour estimator"):
        run_contouring(m, ref, PID(1, 0, 0, m.dt), ccc_gain=1.0)
    with pytest.raises(InputError, match=r"reference: expected an array of shape \(n \+ 1, 2\)"):
        run_contouring(m, ref[:, :1], PID(1, 0, 0, m.dt))
    with pytest.raises(InputError, match="controller: expected a CFDLMFAC or PID"):
        run_contouring(m, ref, object())
    with pytest.raises(InputError, match="path: expected a 2-D path"):
        OnlineContourEstimator(np.zeros((5, 3)) + np.arange(5)[:, None], np.arange(5.0))
