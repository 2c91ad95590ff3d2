"""Basic ILC: convergence on the papers' machines, divergence detection, the lifted check
against dense matrices, the Q-filter, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import linalg, signal

from primlib import InputError
from primlib.ilc import (
    ConvergenceWarning,
    LearnOptions,
    MasterSlave,
    MasterSlaveResult,
    NormOptimal,
    PDLaw,
    PIDLaw,
    PLaw,
    QFilter,
    check_learning,
    design_gains,
    law_from_name,
    learn,
)
from primlib.plant import Machine, pid_polynomials

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
XYZ = Machine.from_json(DATA / "xyz.json")
XY = Machine.from_json(DATA / "xy-pdccilc.json")


def _path(machine, n):
    """A smooth rest-to-rest path (relative to its start), amplitude about 10."""
    s = np.linspace(0.0, 1.0, n)
    bump = 10 * s**3 - 15 * s**4 + 6 * s**5
    cols = [
        10 * np.sin(np.pi * s) ** 2 * np.cos(2 * np.pi * s),
        10 * bump,
        5 * np.sin(2 * np.pi * s) ** 3 * bump,
    ]
    ref = np.column_stack(cols[: machine.dim])
    return ref - ref[0]


def _true_xyz():
    """+8 % gain, +15 % time constant and a 12 ms first-order lag on every axis."""
    plants = {}
    for axis, (num, den) in XYZ.plants.items():
        k, tau = num[0] / den[1], den[0] / den[1]
        plants[axis] = ([1.08 * k], np.polymul([1.15 * tau, 1.0, 0.0], [0.012, 1.0]))
    return Machine("xyz-true", XYZ.dt, XYZ.axes, plants)


@pytest.mark.slow
def test_norm_optimal_converges_monotonically_on_xyz():
    ref = _path(XYZ, 401)
    res = learn(XYZ, ref, law="norm-optimal", iterations=6)
    assert res.check.monotonic and res.check.max_singular_value < 1
    assert np.all(np.diff(res.rms_total) < 0), res.rms_total
    amplitude = np.max(np.abs(ref))
    assert res.rms_total[-1] < 1e-3 * amplitude
    assert res.stopped == "iterations"
    assert res.rms.shape == (7, 3) and res.rms_total.shape == (7,)
    assert len(res.inputs) == len(res.outputs) == len(res.errors) == 7
    np.testing.assert_array_equal(res.u, res.inputs[-1])
    # the record is consistent: each output is the plant's response to its input
    np.testing.assert_allclose(res.outputs[3], XYZ.simulate(res.inputs[3]), atol=1e-12)
    np.testing.assert_allclose(res.errors[3], ref - res.outputs[3], atol=1e-12)
    np.testing.assert_allclose(res.rms_total, np.sqrt(np.sum(res.rms**2, axis=1)), rtol=1e-12)
    if res.rms_contour is not None:
        assert res.rms_contour.shape == (7,)
        assert res.rms_contour[-1] < 1e-3 * amplitude


def test_default_pd_is_d_type_on_integrating_axes_and_monotonic():
    ref = _path(XYZ, 401)
    res = learn(XYZ, ref, law="pd", iterations=8)
    # integrating axes: no useful P action; kd near 1/K (c = K kd in (0, 2))
    assert np.all(np.abs(res.gains["kp"]) < 1e-6)
    c = res.gains["kd"] * np.array([1.066, 1.1746, 2.0523])
    assert np.all((c > 0.3) & (c < 2.0)), c
    assert res.check.monotonic
    assert np.all(np.diff(res.rms_total) < 0)
    assert res.rms_total[-1] < 0.1 * res.rms_total[0]


@pytest.mark.slow
def test_warm_start_from_the_converged_input_starts_converged():
    ref = _path(XYZ, 401)
    first = learn(XYZ, ref, law="norm-optimal", iterations=4)
    again = learn(XYZ, ref, first.u, law="norm-optimal", iterations=0)
    assert again.rms_total[0] == pytest.approx(first.rms_total[-1], rel=1e-12)
    assert again.stopped == "iterations" and again.iterations == 0


def test_model_mismatch_still_converges():
    ref = _path(XYZ, 401)
    res = learn(_true_xyz(), ref, model=XYZ, law="norm-optimal", iterations=6)
    assert np.all(np.diff(res.rms_total) < 0)
    assert res.rms_total[-1] < 2e-3 * np.max(np.abs(ref))


def test_known_divergent_gain_warns_and_stops():
    ref = _path(XYZ, 301)
    h_r = XYZ.impulse_response(2)[1]
    with pytest.warns(ConvergenceWarning, match="monotonic convergence is not assured"):
        res = learn(XYZ, ref, law=PLaw(kp=3.0 / h_r), iterations=10)
    # diagonal of I - L G is 1 - 3 = -2: the spectral radius is exactly 2
    np.testing.assert_allclose(res.check.spectral_radius_axes, 2.0, rtol=1e-12)
    assert not res.check.convergent
    assert res.stopped == "diverged"
    assert res.rms_total[-1] > res.rms_total[-2]
    assert len(res.inputs) < 11


def test_callback_sees_every_trial():
    seen = []
    options = LearnOptions(callback=lambda k, r: seen.append((k, r)))
    res = learn(XYZ, _path(XYZ, 201), law="pd", iterations=3, options=options)
    assert [k for k, _ in seen] == [0, 1, 2, 3]
    np.testing.assert_array_equal(np.array([r for _, r in seen]), res.rms)


def test_tol_stops():
    ref = _path(XYZ, 301)
    res = learn(XYZ, ref, law="norm-optimal", iterations=20, tol=1e-2)
    assert res.stopped == "tol"
    assert res.rms_total[-1] <= 1e-2 < res.rms_total[-2]


def test_norm_optimal_is_monotonic_by_construction_on_long_nmp_trials():
    # sigma_min(G) of the NMP axes is exponentially small in n: the value rounds to 1.0,
    # the law still contracts, and no warning is raised
    chk = check_learning(XY, 1500, "norm-optimal")
    assert chk.monotonic and chk.max_singular_value <= 1.0


def test_norm_optimal_on_the_nonminimum_phase_pid_stage():
    ref = _path(XY, 601)
    res = learn(XY, ref, law="norm-optimal", iterations=4)
    # x has direct feedthrough (relative degree 0), y relative degree 1
    np.testing.assert_array_equal(XY.relative_degree, [0, 1])
    assert res.check.monotonic
    assert np.all(np.diff(res.rms_total) < 0)
    assert res.rms_total[-1] < 1e-3 * res.rms_total[0]


def test_q_filter_caps_learning_and_is_zero_phase():
    q = QFilter(5.0, 0.005)
    t = np.arange(2000) * 0.005
    slow = np.sin(2 * np.pi * 0.5 * t)
    fast = np.sin(2 * np.pi * 40 * t)
    # zero phase: the slow sine comes out scaled by |B|^2 at 0.5 Hz, not delayed
    gain = q.response(np.array([2 * np.pi * 0.5 * 0.005]))[0]
    inner = slice(200, -200)
    np.testing.assert_allclose(q(slow)[inner], gain * slow[inner], atol=1e-9)
    assert np.max(np.abs(q(fast)[inner])) < 1e-3
    # the lifted matrix is the symmetric Toeplitz matrix of the kernel, and a contraction
    Q = q.matrix(300)
    np.testing.assert_allclose(Q, q.toeplitz(300), atol=1e-12)
    assert np.linalg.norm(Q, 2) <= 1.0 + 1e-12
    x = np.random.default_rng(0).standard_normal((300, 2))
    np.testing.assert_allclose(Q @ x, q(x), atol=1e-12)


def _dense_arimoto(model, n, i, gains, q=None):
    r = int(model.relative_degree[i])
    G = model.lifted(n)[i][r:, : n - r]
    c, den = pid_polynomials(
        gains["kp"][i], gains.get("ki", [0] * 3)[i], gains["kd"][i], 0.0, model.dt
    )
    imp = np.zeros(n - r)
    imp[0] = 1.0
    ell = signal.lfilter(c, den, imp)
    L = linalg.toeplitz(ell, np.r_[ell[0], np.zeros(n - r - 1)])
    M = np.eye(n - r) - L @ G
    if q is not None:
        M = q.matrix(n - r) @ M
    return np.max(np.abs(np.linalg.eigvals(M))), np.linalg.norm(M, 2)


@pytest.mark.parametrize("dense_limit", [0, 10_000])
def test_check_agrees_with_dense_pd(dense_limit):
    n = 240
    gains = {"kp": np.array([0.5, 0.4, 0.3]), "kd": np.array([0.9, 0.8, 0.5])}
    chk = check_learning(XYZ, n, PDLaw(**gains), dense_limit=dense_limit)
    for i in range(3):
        rho, sigma = _dense_arimoto(XYZ, n, i, gains)
        # rho: exact from the diagonal either way; the dense eigenvalues of a defective
        # (Jordan) lower-triangular matrix are only accurate to ~eps^(1/n), so compare
        # with its exact value, the diagonal, and bound the dense estimate loosely
        assert chk.spectral_radius_axes[i] == pytest.approx(
            abs(
                1 - (0.0 + gains["kp"][i] + gains["kd"][i] / XYZ.dt) * XYZ.impulse_response(2)[1, i]
            ),
            rel=1e-12,
        )
        assert abs(rho - chk.spectral_radius_axes[i]) < 0.2
        np.testing.assert_allclose(chk.max_singular_value_axes[i], sigma, rtol=1e-6)


def test_check_agrees_with_dense_pd_with_q():
    n = 200
    q = QFilter(8.0, XYZ.dt)
    gains = design_gains(XYZ, n, PDLaw(q_cutoff=8.0))
    law = PDLaw(**gains, q_cutoff=8.0)
    exact = check_learning(XYZ, n, law, dense_limit=10_000)
    approx = check_learning(XYZ, n, law, dense_limit=0)
    for i in range(3):
        rho, sigma = _dense_arimoto(XYZ, n, i, gains, q)
        np.testing.assert_allclose(exact.spectral_radius_axes[i], rho, rtol=1e-9)
        np.testing.assert_allclose(exact.max_singular_value_axes[i], sigma, rtol=1e-9)
    # the FFT path: Lanczos for sigma_max (converges from below), Gelfand's estimate of rho
    np.testing.assert_allclose(
        approx.max_singular_value_axes, exact.max_singular_value_axes, rtol=1e-5
    )
    for est, rho, sigma in zip(
        approx.spectral_radius_axes,
        exact.spectral_radius_axes,
        exact.max_singular_value_axes,
        strict=True,
    ):
        assert 0.9 * rho <= est <= sigma * (1 + 1e-5)
    assert "FFT operators" in approx.method and "dense" in exact.method


@pytest.mark.parametrize("dense_limit", [0, 10_000])
def test_check_agrees_with_dense_norm_optimal(dense_limit):
    n = 200
    w = np.array([1e-6, 2e-6, 3e-6])
    chk = check_learning(XYZ, n, NormOptimal(w=w), dense_limit=dense_limit)
    for i in range(3):
        G = XYZ.lifted(n)[i][1:, : n - 1]
        M = np.eye(n - 1) - np.linalg.solve(G.T @ G + w[i] * np.eye(n - 1), G.T @ G)
        np.testing.assert_allclose(chk.max_singular_value_axes[i], np.linalg.norm(M, 2), rtol=1e-6)
        np.testing.assert_allclose(
            chk.spectral_radius_axes[i], np.max(np.abs(np.linalg.eigvals(M))), rtol=1e-6
        )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"law": "pi"},
            "law: expected one of p, pd, pid, norm-optimal, tdilc, tdccilc, pdilc, pdccilc, "
            "got 'pi'",
        ),
        ({"law": 3}, "law: expected one of p, pd, .*, got 3"),
        (
            {"law": PDLaw(kp=[1.0, 2.0])},
            r"gains kp: expected a finite number or one per axis \(3\)",
        ),
        ({"law": NormOptimal(w=0.0)}, "gains w: expected weights > 0"),
        ({"iterations": -1}, "iterations: expected an integer >= 0, got -1"),
        ({"iterations": 2.5}, "iterations: expected an integer >= 0, got 2.5"),
        ({"tol": 0.0}, r"tol: expected a finite tolerance > 0, got 0\.0"),
        (
            {"law": PDLaw(q_cutoff=100.0)},
            "q_cutoff: expected a cut-off frequency in Hz between 0 and the Nyquist",
        ),
        ({"law": PDLaw(q_cutoff=-1.0)}, "q_cutoff: expected a cut-off frequency"),
        ({"model": XY}, r"model: expected the plant's dt 0\.005 and axes \['x', 'y', 'z'\]"),
        ({"u0": np.zeros((5, 3))}, r"u0: expected the reference's shape \(50, 3\)"),
    ],
)
def test_bad_input(kwargs, message):
    ref = _path(XYZ, 50)
    with pytest.raises(InputError, match=message):
        learn(XYZ, ref, **kwargs)


def test_contour_needs_two_axes():
    one = Machine("x", XYZ.dt, ["x"], {"x": XYZ.plants["x"]})
    with pytest.raises(InputError, match="contour: expected a path with 2 or 3 axes, got 1"):
        learn(one, _path(XYZ, 50)[:, :1], contour=True)


def test_bad_reference():
    with pytest.raises(InputError, match=r"reference: expected an array of shape \(n, 3\)"):
        learn(XYZ, np.zeros((50, 2)))
    with pytest.raises(InputError, match="reference: expected finite values"):
        learn(XYZ, np.full((50, 3), np.nan))
    with pytest.raises(
        InputError,
        match=r"reference: expected at least 3 samples for axis 0 \(relative degree 1\), got 2",
    ):
        learn(XYZ, np.zeros((2, 3)), law=PDLaw(q_cutoff=5.0))


def test_law_names_and_objects_give_the_same_run():
    ref = _path(XYZ, 201)
    by_name = learn(XYZ, ref, law="pd", iterations=3)
    by_object = learn(XYZ, ref, law=PDLaw(), iterations=3)
    np.testing.assert_array_equal(by_name.u, by_object.u)
    assert by_name.law == by_object.law == "pd"
    # designed gains passed back in reproduce the run exactly
    again = learn(XYZ, ref, law=PDLaw(**by_name.gains), iterations=3)
    np.testing.assert_array_equal(again.u, by_name.u)
    assert law_from_name("NORM-OPTIMAL") == NormOptimal()
    assert law_from_name("pdccilc") == MasterSlave("pdccilc")
    assert isinstance(law_from_name("pid"), PIDLaw)


def test_gain_left_none_beside_a_given_one_is_zero():
    ref = _path(XYZ, 101)
    res = learn(XYZ, ref, law=PIDLaw(kd=0.5), iterations=1)
    np.testing.assert_array_equal(res.gains["kp"], 0.0)
    np.testing.assert_array_equal(res.gains["ki"], 0.0)
    np.testing.assert_array_equal(res.gains["kd"], 0.5)


def test_master_slave_law_runs_through_learn():
    th = np.pi * np.linspace(0, 1, 401)
    r = np.column_stack([10 * (1 - np.cos(th)), 10 * np.sin(th)])
    res = learn(XY, r, law=MasterSlave("tdccilc"), iterations=2, options=LearnOptions(check=False))
    assert isinstance(res, MasterSlaveResult) and res.law == "tdccilc"
    assert res.rms_contour.shape == (3,) and res.rms_contour[-1] < res.rms_contour[0]
    with pytest.raises(InputError, match="law: expected one of p, pd, pid, norm-optimal here"):
        check_learning(XY, 100, "pdccilc")
