"""Master–slave cross-coupled ILC family: laws, lifted analysis, learning loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from primlib._errors import InputError
from primlib.ilc import MasterSlave
from primlib.ilc._check import ConvergenceWarning
from primlib.ilc._lifted import lifted_master_slave
from primlib.ilc._master_slave import learn_master_slave
from primlib.ilc._ms_law import (
    LAWS,
    MasterSlaveGains,
    contour_error_estimate,
    coupling_gains,
    gaussian_q_kernel,
    master_slave_law,
)
from primlib.plant import Machine

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
DT = 0.005


@pytest.fixture(scope="module")
def paper_machine():
    return Machine.from_json(DATA / "xy-pdccilc.json")


@pytest.fixture(scope="module")
def proper_machine():
    # strictly proper on both axes (no feedthrough): the lifted matrix can be triangular
    return Machine(
        "sp",
        DT,
        ("x", "y"),
        {"x": ([5.0], [1.0, 5.8, 5.6]), "y": ([2.0], [1.0, 2.8, 2.1])},
        {"x": {"kp": 3, "ki": 1, "kd": 0}, "y": {"kp": 3, "ki": 1, "kd": 0}},
    )


def semicircle(n, radius=10.0):
    th = np.pi * np.linspace(0, 1, n)
    return np.column_stack([radius * (1 - np.cos(th)), radius * np.sin(th)])


def spiral(n, radius=10.0, turns=2):
    tau = np.linspace(0, 1, n)
    th = 2 * np.pi * turns * tau
    return np.column_stack([radius * tau * np.cos(th), radius * tau * np.sin(th)])


# ----------------------------------------------------------------- contour error (eqs. 1-4)
def test_coupling_gains_are_the_unit_normal_of_the_tangent():
    r = semicircle(201)
    normal = coupling_gains(r)
    np.testing.assert_allclose(np.hypot(normal[:, 0], normal[:, 1]), 1.0, atol=1e-12)
    tangent = np.gradient(r, axis=0)
    np.testing.assert_allclose(np.sum(normal * tangent, axis=1), 0.0, atol=1e-12)
    # the semicircle runs clockwise about (10, 0): its left normal points away from the centre
    outward = r - np.array([10.0, 0.0])
    np.testing.assert_allclose(np.sum(normal * outward, axis=1), 10.0, rtol=1e-3)


def test_coupling_gains_where_the_reference_rests_and_a_static_path():
    r = np.zeros((50, 2))
    r[10:, 0] = np.linspace(0, 5, 40)  # at rest for 10 samples, then along +x
    normal = coupling_gains(r)
    np.testing.assert_allclose(normal, np.tile([0.0, 1.0], (50, 1)), atol=1e-12)
    np.testing.assert_array_equal(coupling_gains(np.ones((5, 2))), 0.0)


def test_contour_error_estimate_of_an_offset_line():
    r = np.column_stack([np.linspace(0, 1, 30), np.zeros(30)])
    actual = r + np.array([0.2, -0.05])  # along-track error does not count
    eps, vector = contour_error_estimate(r, actual)
    np.testing.assert_allclose(eps, 0.05, atol=1e-12)
    np.testing.assert_allclose(vector, np.tile([0.0, 0.05], (30, 1)), atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.floats(-np.pi, np.pi), st.integers(0, 2**31 - 1))
def test_contour_error_is_invariant_to_a_rotation(angle, seed):
    rng = np.random.default_rng(seed)
    r = spiral(80)
    actual = r + 0.1 * rng.standard_normal(r.shape)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    eps, _ = contour_error_estimate(r, actual)
    eps_rot, _ = contour_error_estimate(r @ rot.T, actual @ rot.T)
    np.testing.assert_allclose(eps_rot, eps, atol=1e-9)


def test_contour_error_estimate_rejects_mismatched_shapes():
    with pytest.raises(InputError, match=r"actual: expected the shape of reference \(30, 2\)"):
        contour_error_estimate(np.zeros((30, 2)), np.zeros((29, 2)))


# ----------------------------------------------------------------- the laws (eqs. 9-19)
def test_coupled_law_matches_eq_5_with_the_paper_gains_as_p_type():
    # P-type gains only: eq. (5) reads du_x = kp e_x - C_x kp_eps eps, du_y = kp e_y + C_y ...
    r = semicircle(101)
    gains = MasterSlaveGains(ilc=(0.3, 0.0, 0.0), ccc=(1.0, 0.0, 0.0))
    law = master_slave_law(r, DT, "tdccilc", gains=gains, lead=0)
    e = np.random.default_rng(0).standard_normal(r.shape)
    tangent = np.gradient(r, axis=0)
    tangent /= np.hypot(tangent[:, 0], tangent[:, 1])[:, None]
    cx, cy = tangent[:, 1], tangent[:, 0]
    eps = -cx * e[:, 0] + cy * e[:, 1]  # eq. (1)
    expect = np.column_stack([0.3 * e[:, 0] - cx * eps, 0.3 * e[:, 1] + cy * eps])
    np.testing.assert_allclose(law.correction(e), expect, atol=1e-12)


def test_uncoupled_laws_keep_the_axes_apart():
    r = semicircle(101)
    e = np.zeros(r.shape)
    e[:, 1] = np.random.default_rng(1).standard_normal(101)
    for name in ("tdilc", "pdilc"):
        corr = master_slave_law(r, DT, name).correction(e)
        np.testing.assert_array_equal(corr[:, 0], 0.0)
        assert np.any(corr[:, 1] != 0)


def test_lead_shifts_the_error_the_input_learns_from():
    r = semicircle(60)
    e = np.random.default_rng(2).standard_normal(r.shape)
    c0 = master_slave_law(r, DT, "tdccilc", lead=0).correction(e)
    c2 = master_slave_law(r, DT, "tdccilc", lead=2).correction(e)
    np.testing.assert_allclose(c2[:-2], c0[2:], atol=1e-15)
    np.testing.assert_array_equal(c2[-2:], 0.0)


def test_time_domain_increments_are_dt_and_derivative_gain_is_kd_over_dt():
    law = master_slave_law(semicircle(100), DT, "tdilc")
    np.testing.assert_array_equal(law.dw, DT)
    kp, ki, kd = 0.3, 0.1, 0.1
    np.testing.assert_allclose(law.a[:, 0], kp + ki * DT / 2 + kd / DT)  # eq. (17)
    np.testing.assert_allclose(law.b[:, 0], ki * DT / 2 - kd / DT)


@pytest.mark.parametrize("path", [semicircle(2401), spiral(2401)])
def test_position_domain_survives_a_resting_or_reversing_master(path):
    # dx = 0 at the start and at the semicircle's ends; the spiral's master reverses 4 times
    dx = np.diff(path[:, 0], prepend=path[0, 0])
    assert np.min(np.abs(dx)) == 0.0
    law = master_slave_law(path, DT, "pdccilc", floor=0.25)
    delta = 0.25 * np.sum(np.abs(dx)) / (len(path) - 1)
    ds = law.dw[:, 1]
    assert np.all(np.isfinite(law.a)) and np.all(np.isfinite(law.b))
    assert np.min(ds) == pytest.approx(delta, rel=1e-12)  # the floor where the master rests
    np.testing.assert_allclose(ds, np.hypot(dx, delta), rtol=1e-12)
    # the derivative gain never changes sign and is capped at kd / delta
    kd = 0.1
    assert np.all(law.a[:, 1] > 0) and np.max(law.a[:, 1]) <= 0.3 + 0.05 * delta + kd / delta
    np.testing.assert_array_equal(law.dw[:, 0], DT)  # the master learns in time


def test_regularised_position_domain_learns_where_the_raw_one_blows_up(paper_machine):
    # floor -> 0 is the paper's 1 / dx: gains of ~kd / 1e-5 at the semicircle's ends make the
    # unfiltered PDILC blow up within 20 trials; the regularised domain keeps learning
    r = semicircle(801)
    raw_law = MasterSlave("pdilc", q_cutoff=None, floor=1e-9)
    raw = learn_master_slave(paper_machine, r, law=raw_law, iterations=20, check=False)
    reg_law = MasterSlave("pdilc", q_cutoff=None, floor=0.25)
    reg = learn_master_slave(paper_machine, r, law=reg_law, iterations=20, check=False)
    assert raw.rms_contour[-1] > 5 * raw.rms_contour[0]
    assert reg.rms_contour[-1] < 0.6 * reg.rms_contour[0]
    assert np.all(np.diff(reg.rms_contour) < 0)


def test_position_domain_falls_back_to_time_when_the_master_never_moves():
    r = np.column_stack([np.zeros(80), np.linspace(0, 3, 80)])
    pd = master_slave_law(r, DT, "pdccilc")
    td = master_slave_law(r, DT, "tdccilc")
    np.testing.assert_array_equal(pd.a, td.a)
    np.testing.assert_array_equal(pd.b, td.b)


def test_master_one_swaps_the_roles():
    r = semicircle(120)
    law = master_slave_law(r[:, ::-1], DT, "pdilc", master=1)
    ref = master_slave_law(r, DT, "pdilc", master=0)
    np.testing.assert_allclose(law.dw[:, [1, 0, 2]], ref.dw, rtol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"law": "foo"}, r"law: expected one of tdilc, tdccilc, pdilc, pdccilc, got 'foo'"),
        ({"master": 2}, r"master: expected axis 0 or 1, got 2"),
        ({"lead": -1}, r"lead: expected an integer in \[0, 49\], got -1"),
        ({"floor": 0.0}, r"floor: expected a fraction > 0 of the mean master step, got 0.0"),
        ({"q_cutoff": 100.0}, r"q_cutoff: expected a frequency in \(0, 26.5\] Hz"),
        ({"gains": MasterSlaveGains(ilc=(1, 2))}, r"gains.ilc: expected finite \(kp, ki, kd\)"),
        ({"gains": MasterSlaveGains(ccc=(1, np.nan, 0))}, r"gains.ccc: expected finite"),
    ],
)
def test_law_options_are_checked(kwargs, message):
    with pytest.raises(InputError, match=message):
        master_slave_law(semicircle(50), DT, **kwargs)


@pytest.mark.parametrize(
    ("reference", "message"),
    [
        (np.zeros((10, 3)), r"reference: expected an array of shape \(n, 2\) .* got shape"),
        (np.zeros((2, 2)), r"reference: expected at least 3 samples, got 2"),
        (np.full((10, 2), np.nan), r"reference: expected finite values, got NaN or inf"),
    ],
)
def test_reference_is_checked(reference, message):
    with pytest.raises(InputError, match=message):
        master_slave_law(reference, DT)


# ----------------------------------------------------------------- Q-filter
def test_q_filter_is_symmetric_with_norm_one_and_passes_constants_inside():
    law = master_slave_law(semicircle(400), DT, "tdilc", q_cutoff=2.0)
    q = law.q(np.eye(400))
    np.testing.assert_allclose(q, q.T, atol=1e-14)
    assert np.linalg.norm(q, 2) == pytest.approx(1.0, abs=1e-12)  # Perron vector D^1/2 1
    half = law.q_kernel.size // 2
    ones = law.q(np.ones((400, 2)))
    np.testing.assert_allclose(ones[2 * half : -2 * half], 1.0, atol=1e-12)  # two half-widths in
    assert np.all(ones > 0.7)  # no collapse towards zero at the ends


def test_gaussian_q_kernel_has_its_half_power_point_at_the_cutoff():
    kern = gaussian_q_kernel(1.0, DT)
    assert kern.sum() == pytest.approx(1.0)
    k = np.arange(kern.size) - kern.size // 2
    response = np.sum(kern * np.cos(2 * np.pi * 1.0 * DT * k))
    assert response == pytest.approx(1 / np.sqrt(2), abs=1e-6)


# ----------------------------------------------------------------- lifted analysis
@pytest.mark.parametrize("name", LAWS)
@pytest.mark.parametrize("q_cutoff", [None, 4.0])
def test_lifted_operator_matches_dense_matrix_and_the_learning_loop(paper_machine, name, q_cutoff):
    n = 150
    r = semicircle(n)
    law = master_slave_law(r, DT, name, q_cutoff=q_cutoff)
    lifted = lifted_master_slave(law, paper_machine, r)
    dense = lifted.dense()
    rng = np.random.default_rng(3)
    v = rng.standard_normal(2 * lifted.n_learn)
    w = rng.standard_normal(2 * lifted.n_learn)
    scale = np.linalg.norm(dense, 2)
    np.testing.assert_allclose(lifted.operator.matvec(v), dense @ v, atol=1e-12 * scale * 50)
    np.testing.assert_allclose(lifted.operator.rmatvec(w), dense.T @ w, atol=1e-12 * scale * 50)
    # one real trial: u_{j+1} = M u_j + N (eq. 26) on the learnable samples
    u = np.zeros((n, 2))
    u[: lifted.n_learn] = v.reshape(2, -1).T
    e = r - paper_machine.simulate(u, reference=r)
    nxt = law.update(u, e)[: lifted.n_learn].T.ravel()
    np.testing.assert_allclose(nxt, dense @ v + lifted.offset, atol=1e-10 * np.abs(nxt).max())
    mx, my = lifted.blocks()
    assert mx.shape == my.shape == (lifted.n_learn, 2 * lifted.n_learn)
    if name in ("tdilc", "pdilc"):  # uncoupled: block diagonal
        np.testing.assert_array_equal(mx[:, lifted.n_learn :], 0.0)


@pytest.mark.parametrize("name", ["tdilc", "pdccilc"])
@pytest.mark.parametrize("q_cutoff", [None, 3.0])
def test_fast_max_singular_value_agrees_with_dense_svd(paper_machine, name, q_cutoff):
    r = spiral(200)
    lifted = lifted_master_slave(master_slave_law(r, DT, name, q_cutoff=q_cutoff), paper_machine, r)
    dense = np.linalg.norm(lifted.dense(), 2)
    assert lifted.max_singular_value() == pytest.approx(dense, rel=1e-9)
    assert lifted.max_singular_value("svds") == pytest.approx(dense, rel=1e-9)
    assert lifted.max_singular_value("power", tol=1e-13) == pytest.approx(dense, rel=1e-4)


@pytest.mark.parametrize("name", LAWS)
def test_spectral_radius_is_exact_on_a_triangular_lifted_matrix(proper_machine, name):
    r = semicircle(120)
    lifted = lifted_master_slave(master_slave_law(r, DT, name), proper_machine, r)
    assert lifted.triangular
    rho, exact = lifted.spectral_radius()
    assert exact
    dense = lifted.dense()
    nl = lifted.n_learn
    order = np.arange(2 * nl).reshape(2, nl).T.ravel()  # sample-major: (x0, y0, x1, y1, ...)
    permuted = dense[np.ix_(order, order)]
    # block lower-triangular: nothing above the 2 x 2 diagonal blocks ...
    upper = np.triu(permuted, 1)
    for k in range(nl):
        upper[2 * k, 2 * k + 1] = 0.0
    np.testing.assert_array_equal(upper, 0.0)
    # ... and the diagonal blocks are the ones rho is taken from, so rho is their eigenvalues'
    blocks = np.stack([permuted[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] for k in range(nl)])
    np.testing.assert_allclose(blocks, lifted.diagonal_blocks(), atol=1e-13)
    assert rho == pytest.approx(np.max(np.abs(np.linalg.eigvals(blocks))), rel=1e-12)
    # a dense eigen-solver on the whole (defective-looking) matrix is already off in the
    # fifth digit at N = 119, which is why primlib never uses one
    assert abs(np.max(np.abs(np.linalg.eigvals(dense))) - rho) < 1e-3


def test_spectral_radius_with_q_is_a_certified_bound(paper_machine):
    r = semicircle(160)
    lifted = lifted_master_slave(master_slave_law(r, DT, "pdccilc", q_cutoff=3.0), paper_machine, r)
    assert not lifted.triangular
    rho, exact = lifted.spectral_radius(powers=(1, 2, 4, 8))
    assert not exact
    dense = lifted.dense()
    eig = np.max(np.abs(np.linalg.eigvals(dense)))
    assert eig <= rho * (1 + 1e-9)
    assert rho <= lifted.max_singular_value() * (1 + 1e-9)
    with pytest.raises(InputError, match=r"powers: expected integers >= 1"):
        lifted.spectral_radius(powers=(0,))


def test_asymptotic_input_is_the_fixed_point_of_the_iteration(paper_machine):
    r = semicircle(300)
    law = master_slave_law(r, DT, "pdccilc", q_cutoff=2.0)
    lifted = lifted_master_slave(law, paper_machine, r)
    u_inf, e_inf = lifted.asymptotic()
    x = u_inf[: lifted.n_learn].T.ravel()
    fixed = lifted.operator.matvec(x) + lifted.offset  # eq. (31): u = M u + N
    np.testing.assert_allclose(fixed, x, atol=1e-8 * np.abs(x).max())
    np.testing.assert_allclose(
        e_inf, r - paper_machine.simulate(u_inf, reference=r), atol=1e-10 * np.abs(r).max()
    )  # eq. (32)


def test_lifted_rejects_a_mismatched_reference(paper_machine):
    law = master_slave_law(semicircle(50), DT)
    with pytest.raises(InputError, match=r"reference: expected shape \(50, 2\) like the law's"):
        lifted_master_slave(law, paper_machine, semicircle(40))


# ----------------------------------------------------------------- learning loop
def test_pdccilc_learns_the_semicircle_on_the_paper_machine(paper_machine):
    r = semicircle(801) + np.array([3.0, -2.0])  # absolute points: taken from the start
    res = learn_master_slave(
        paper_machine, r, law=MasterSlave("pdccilc", q_cutoff=1.0), iterations=40
    )
    assert res.stopped == "iterations"
    assert len(res.errors) == 41 and res.rms.shape == (41, 2)
    assert res.rms_contour[-1] < 0.2 * res.rms_contour[0]
    assert res.check is not None and res.check.max_singular_value > 0
    y = paper_machine.simulate(res.u, reference=r - r[0])
    np.testing.assert_allclose(res.errors[-1], r - r[0] - y, atol=1e-12)
    eps, _ = contour_error_estimate(r - r[0], y)
    assert res.rms_contour[-1] == pytest.approx(np.sqrt(np.mean(eps**2)), rel=1e-12)


def test_a_trajectory_is_sampled_on_the_machine_grid(paper_machine):
    from primlib.nurbs import Trajectory

    points = semicircle(401)
    path = Trajectory.from_samples(points, DT)
    res = learn_master_slave(paper_machine, path, law="tdccilc", iterations=2, check=False)
    ref = learn_master_slave(paper_machine, points, law="tdccilc", iterations=2, check=False)
    np.testing.assert_allclose(res.rms_contour, ref.rms_contour, rtol=1e-3)


def test_cross_coupling_beats_independent_learning_on_contour_error(paper_machine):
    r = semicircle(801)
    out = {
        name: learn_master_slave(
            paper_machine, r, law=name, iterations=30, check=False
        ).rms_contour[-1]
        for name in LAWS
    }
    assert out["tdccilc"] < 0.5 * out["tdilc"]
    assert out["pdccilc"] < 0.5 * out["pdilc"]


def test_tol_stops_early_and_warm_start_is_used(paper_machine):
    r = semicircle(401)
    first = learn_master_slave(paper_machine, r, law="tdccilc", iterations=20, check=False)
    tol = float(first.rms_contour[-1]) * 1.01
    again = learn_master_slave(
        paper_machine, r, first.u, law="tdccilc", iterations=20, tol=tol, check=False
    )
    assert again.stopped == "tol" and len(again.errors) == 1


def test_not_monotonic_gives_a_warning(paper_machine):
    r = semicircle(200)
    with pytest.warns(ConvergenceWarning, match=r"pdccilc: monotonic convergence is not certified"):
        learn_master_slave(
            paper_machine, r, law=MasterSlave("pdccilc", q_cutoff=None), iterations=1
        )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"iterations": -1}, r"iterations: expected an integer >= 0, got -1"),
        ({"tol": 0.0}, r"tol: expected an RMS contour error > 0, got 0.0"),
        (
            {"u0": np.zeros((5, 2))},
            r"u0: expected a finite array of shape \(100, 2\), got \(5, 2\)",
        ),
    ],
)
def test_learn_options_are_checked(paper_machine, kwargs, message):
    with pytest.raises(InputError, match=message):
        learn_master_slave(paper_machine, semicircle(100), check=False, **kwargs)


def test_learn_needs_a_two_axis_machine():
    m = Machine.from_json(DATA / "xyz.json")
    with pytest.raises(InputError, match=r"plant: expected a two-axis machine .* got 3 axes"):
        learn_master_slave(m, semicircle(100))


@settings(max_examples=15, deadline=None)
@given(
    st.sampled_from(LAWS),
    st.integers(0, 2**31 - 1),
    st.floats(0.0, 2.0),
    st.floats(0.0, 1.0),
    st.floats(0.0, 0.5),
    st.sampled_from([None, 6.0]),
)
def test_lifted_operator_is_the_law_for_random_paths_and_gains(name, seed, kp, ki, kd, q):
    # a random walk (master rests, reverses, jumps) and random gains: the FFT operator and its
    # adjoint equal the dense lifted matrix, and the law is linear in the error
    rng = np.random.default_rng(seed)
    r = np.cumsum(rng.standard_normal((60, 2)) * (rng.random((60, 1)) > 0.3), axis=0)
    r -= r[0]
    gains = MasterSlaveGains(ilc=(kp, ki, kd), ccc=(kp, ki, kd))
    law = master_slave_law(r, DT, name, gains=gains, q_cutoff=q)
    machine = Machine.from_json(DATA / "xy-pdccilc.json")
    lifted = lifted_master_slave(law, machine, r)
    dense = lifted.dense()
    v = rng.standard_normal(2 * lifted.n_learn)
    scale = max(1.0, np.abs(dense).max()) * 1e-11
    np.testing.assert_allclose(lifted.operator.matvec(v), dense @ v, atol=scale * np.abs(v).sum())
    np.testing.assert_allclose(
        lifted.operator.rmatvec(v), dense.T @ v, atol=scale * np.abs(v).sum()
    )
    e1, e2 = rng.standard_normal((2, 60, 2))
    np.testing.assert_allclose(
        law.correction(2 * e1 - 3 * e2),
        2 * law.correction(e1) - 3 * law.correction(e2),
        atol=1e-9 * (1 + np.abs(law.a).max()),
    )
