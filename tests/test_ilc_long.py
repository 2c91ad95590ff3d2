"""Norm-optimal ILC on long trials: the CG path against the dense Cholesky path, a 20,000
sample run, the structured solver, the long-trial check, ILCResult.plot."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import linalg

from primlib import InputError
from primlib.ilc import ConvergenceWarning, NormOptimal, check_learning, learn
from primlib.plant import Machine
from primlib.plant._normal import CG_RTOL, NormalSolver

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"
XYZ = Machine.from_json(DATA / "xyz.json")
XY = Machine.from_json(DATA / "xy-pdccilc.json")


def _path(machine, n):
    s = np.linspace(0.0, 1.0, n)
    bump = 10 * s**3 - 15 * s**4 + 6 * s**5
    cols = [
        10 * np.sin(np.pi * s) ** 2 * np.cos(2 * np.pi * s),
        10 * bump,
        5 * np.sin(2 * np.pi * s) ** 3 * bump,
    ]
    return np.column_stack(cols[: machine.dim])


def _step_error_bound(machine, res, i):
    """Sum over the updates of rtol ||G^T e_s|| / w (primlib.plant._normal: the CG step
    error d = A^-1 r has ||d|| <= ||r|| / w, and the iteration map w A^-1 does not amplify
    earlier errors), plus the dense Cholesky's own rounding, eps cond(A) ||step||."""
    n = res.u.shape[0]
    r = int(machine.relative_degree[i])
    g = machine.impulse_response(n)[r:, i]
    G = linalg.toeplitz(g, np.r_[g[0], np.zeros(n - r - 1)])
    w = res.gains["w"][i]
    cond = (np.linalg.norm(G, 2) ** 2 + w) / w
    total = 0.0
    for j in range(res.iterations):
        b = G.T @ res.errors[j][r:, i]
        step = np.linalg.norm(res.inputs[j + 1][: n - r, i] - res.inputs[j][: n - r, i])
        total += CG_RTOL * np.linalg.norm(b) / w + np.finfo(float).eps * cond * step
    return total


@pytest.mark.slow
@pytest.mark.parametrize(("machine", "q_cutoff"), [(XYZ, None), (XY, None), (XYZ, 8.0)])
def test_cg_path_matches_the_dense_path(machine, q_cutoff):
    n = 801
    ref = _path(machine, n)
    ref -= ref[0]
    kw = dict(iterations=4, contour=False)
    dense = learn(machine, ref, law=NormOptimal(solver="dense", q_cutoff=q_cutoff), **kw)
    cg = learn(machine, ref, law=NormOptimal(solver="cg", q_cutoff=q_cutoff), **kw)
    assert dense.solver == "dense Cholesky" and dense.cg == ()
    assert "banded-Cholesky preconditioner" in cg.solver
    assert len(cg.cg) == 4 and all(info.converged for upd in cg.cg for info in upd)
    for i in range(machine.dim):
        bound = _step_error_bound(machine, dense, i)
        diff = np.linalg.norm(cg.u[:, i] - dense.u[:, i])
        assert diff <= bound, (i, diff, bound)
    np.testing.assert_allclose(cg.rms_total, dense.rms_total, rtol=1e-6)


def test_auto_uses_cg_above_a_thousand_samples():
    ref = _path(XYZ, 1500)
    res = learn(XYZ, ref - ref[0], law="norm-optimal", iterations=1, contour=False)
    assert res.solver.startswith("CG")
    small = learn(XYZ, _path(XYZ, 300) - _path(XYZ, 300)[0], law="norm-optimal", iterations=1)
    assert small.solver == "dense Cholesky"


@pytest.mark.slow
def test_twenty_thousand_samples_converge_without_dense_matrices():
    # The time it takes is a benchmark figure (benchmarks/bench_plant.py), not a test: this
    # checks the long-trial route (no n x n matrix, Lanczos check, a few CG steps) works.
    n = 20_000  # 100 s at 5 ms
    ref = _path(XYZ, n)
    ref -= ref[0]
    res = learn(XYZ, ref, law="norm-optimal", iterations=5, contour=False)
    assert res.check.monotonic and res.check.n == n
    assert "estimate" not in res.check.method and "Lanczos" in res.check.method
    assert res.stopped == "iterations"
    assert np.all(np.diff(res.rms_total) < 0), res.rms_total
    assert res.rms_total[-1] < 1e-8 * np.max(np.abs(ref))
    # every solve reached the tolerance in a handful of preconditioned steps
    assert all(info.converged and info.iterations <= 5 for upd in res.cg for info in upd)


def test_long_trial_check_is_monotonic_without_arpack_on_the_nmp_stage():
    chk = check_learning(XY, 12_000, "norm-optimal")
    assert chk.monotonic and chk.max_singular_value <= 1.0
    q = check_learning(XYZ, 8000, NormOptimal(q_cutoff=8.0))
    assert q.monotonic and q.method.startswith("upper bound ||Q||")
    assert q.spectral_radius <= q.max_singular_value < 1.0


@pytest.mark.slow
def test_long_check_bounds_the_dense_value():
    # n_r above dense_limit: Lanczos on G^-1, the value rounded up with its error bound
    n = 600
    w = np.array([1e-6, 2e-6, 3e-6])
    fast = check_learning(XYZ, n, NormOptimal(w=w, solver="cg"), dense_limit=0)
    exact = check_learning(XYZ, n, NormOptimal(w=w), dense_limit=10_000)
    T = XYZ.lifted(n)
    for i, (f, e) in enumerate(
        zip(fast.max_singular_value_axes, exact.max_singular_value_axes, strict=True)
    ):
        # the "exact" one: eigvalsh finds lam_min to ~eps ||G^T G|| absolute, which moves
        # w / (lam + w) by up to that / w; the fast one is rounded up, by at most the 1e-6
        # Lanczos tolerance / 2 (the value's sensitivity to sigma_min)
        slack = 10 * np.finfo(float).eps * np.linalg.norm(T[i], 2) ** 2 / w[i]
        assert e - slack <= f <= e + 1e-6


@pytest.mark.parametrize("with_polys", [True, False])
def test_normal_solver_against_dense(with_polys):
    n = 800
    r = 1
    g = XYZ.impulse_response(n + r)[r:, 1]
    num, _, den = XYZ.closed_loop()[1]
    w = 3e-6
    s = NormalSolver(g, w, num[r:] if with_polys else None, den if with_polys else None)
    assert s.preconditioned == with_polys
    rng = np.random.default_rng(0)
    e = np.cumsum(rng.standard_normal(n))
    G = linalg.toeplitz(g, np.r_[g[0], np.zeros(n - 1)])
    A = G.T @ G + w * np.eye(n)
    b = s.rhs(e)
    np.testing.assert_allclose(b, G.T @ e, atol=1e-12 * np.linalg.norm(b))
    # rtol: the step's effect on the next error <= 1e-6 of it (primlib.plant._normal)
    assert s.rtol == pytest.approx(min(CG_RTOL, 2e-6 * np.sqrt(w) / np.sum(np.abs(g))))
    x, info = s.solve(b)
    assert info.converged and info.residual <= s.rtol
    # ... which that effect obeys: ||G (x - x*)|| <= 1e-6 ||e||
    assert np.linalg.norm(G @ (x - linalg.solve(A, b, assume_a="pos"))) <= 1e-6 * np.linalg.norm(e)
    if with_polys:
        assert info.iterations <= 3
    exact = linalg.solve(A, b, assume_a="pos")
    # ||x - x*|| <= ||r|| / w, plus the dense solve's own eps * cond rounding
    cond = np.linalg.cond(A)
    tol = s.rtol * np.linalg.norm(b) / w + 10 * np.finfo(float).eps * cond * np.linalg.norm(exact)
    assert np.linalg.norm(x - exact) <= tol
    # warm start from the answer: done at once; from a stale, scaled-up step: never worse
    # than a cold start in iterations
    x2, info2 = s.solve(b, x0=exact)
    assert info2.iterations <= 1
    _, info3 = s.solve(b, x0=100 * exact + rng.standard_normal(n))
    assert info3.converged
    zero, info0 = s.solve(np.zeros(n))
    assert info0.iterations == 0 and not np.any(zero)


def test_polynomials_that_do_not_describe_g_are_ignored():
    g = XYZ.impulse_response(200)[1:, 0]
    s = NormalSolver(g, 1e-6, [1.0, 0.5], [1.0, -0.9])
    assert not s.preconditioned and "preconditioner" not in s.method


def test_solver_errors():
    ref = _path(XYZ, 50)
    with pytest.raises(InputError, match="solver: expected one of auto, dense, cg, got 'lu'"):
        learn(XYZ, ref - ref[0], law=NormOptimal(solver="lu"))
    with pytest.raises(
        InputError,
        match=r"reference: solver 'dense' factors an n x n matrix per axis, expected "
        r"n <= 5000, got 5002; use solver 'cg' or 'auto'",
    ):
        check_learning(XYZ, 5002, NormOptimal(solver="dense"))


def test_result_plot_delegates():
    import matplotlib.pyplot as plt

    ref = _path(XYZ, 300)
    res = learn(XYZ, ref - ref[0], law="norm-optimal", iterations=3)
    ax = res.plot()
    assert ax.get_yscale() == "log"
    labels = [line.get_label() for line in ax.get_lines()]
    assert labels[:4] == ["axis 0 RMS", "axis 1 RMS", "axis 2 RMS", "total RMS"]
    np.testing.assert_array_equal(ax.get_lines()[1].get_ydata(), res.rms[:, 1])
    if res.rms_contour is not None:
        assert "contour RMS" in labels
    fig, own = plt.subplots()
    assert res.plot(ax=own) is own
    plt.close("all")


def test_near_cancelling_zero_and_pole_still_precondition():
    # a PID loop's zero at z = 1 beside a slow pole just inside it: N^T N + w D^T D is
    # numerically singular unless the pair is dropped from the preconditioner
    from scipy import signal

    from primlib.plant._normal import _cancel_common_roots

    num = 1e-3 * np.convolve([1.0, -1.0], [1.0, 0.5])
    den = np.convolve([1.0, -0.9999997], [1.0, -0.9])
    kept_num, kept_den = _cancel_common_roots(num, den)
    np.testing.assert_allclose(kept_num, [1e-3, 0.5e-3], rtol=1e-9)
    np.testing.assert_allclose(kept_den, [1.0, -0.9], rtol=1e-9)
    n = 4000
    imp = np.zeros(n)
    imp[0] = 1.0
    g = signal.lfilter(num, den, imp)
    s = NormalSolver(g, 1e-8, num, den)
    assert s.preconditioned
    b = s.rhs(np.cumsum(np.random.default_rng(2).standard_normal(n)))
    x, info = s.solve(b)
    assert info.converged and info.iterations <= 20
    assert np.linalg.norm(b - s.matvec(x)) <= s.rtol * np.linalg.norm(b)


def test_cg_stopping_short_warns(monkeypatch):
    import primlib.ilc._learn as learn_module
    from primlib.ilc import ConvergenceWarning

    class Starved(NormalSolver):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.maxiter = self.fallback_maxiter = 0

    monkeypatch.setattr(learn_module, "NormalSolver", Starved)
    ref = _path(XYZ, 300)
    with pytest.warns(ConvergenceWarning, match=r"3 CG solve\(s\) stopped short of the tol"):
        res = learn(XYZ, ref - ref[0], law=NormOptimal(solver="cg"), iterations=1)
    assert not any(info.converged for info in res.cg[0])


@st.composite
def _stable_tf(draw):
    """A random proper plant with poles in the closed left half plane (as in test_plant)."""
    poles = [-draw(st.floats(0.5, 50.0)) for _ in range(draw(st.integers(0, 2)))]
    for _ in range(draw(st.integers(0, 1))):
        sigma, omega = draw(st.floats(0.5, 20.0)), draw(st.floats(0.5, 30.0))
        poles += [complex(-sigma, omega), complex(-sigma, -omega)]
    if draw(st.booleans()) or not poles:
        poles.append(0.0)
    den = np.real(np.poly(poles))
    num = [draw(st.floats(-3.0, 3.0)) for _ in range(draw(st.integers(1, len(den))))]
    if abs(num[0]) < 1e-3:
        num[0] = 1.0
    return num, den.tolist()


@pytest.mark.xfail(
    strict=True,
    reason="known limit, found by the property test below on a fresh CI run: CG stops short of "
    "its tolerance on this slow, lightly damped loop under PI feedback (learn warns with "
    "ConvergenceWarning); the property test now draws a fixed set of examples",
)
def test_cg_converges_on_a_slow_loop_under_pi():
    m = Machine("rand", 0.005, ["x"], {"x": ([1.0, 0.5], [1.0, 4.0, 6.25, 4.5, 1.25, 0.0])},
                {"x": {"kp": 0.5, "ki": 0.1}})  # fmt: skip
    ref = np.sin(np.linspace(0.0, np.pi, 400))[:, None] ** 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        cg = learn(m, ref, law=NormOptimal(solver="cg"), iterations=2, contour=False)
    assert all(info.converged for upd in cg.cg for info in upd)


@pytest.mark.slow
@given(_stable_tf(), st.sampled_from([None, {"kp": 0.5, "ki": 0.1}]))
@settings(max_examples=15, deadline=None, derandomize=True)
def test_cg_path_matches_dense_on_random_machines(tf, pid):
    try:
        m = Machine("rand", 0.005, ["x"], {"x": tf}, None if pid is None else {"x": pid})
    except InputError:
        return  # a random PID may not stabilise a random plant
    n = 400
    ref = np.sin(np.linspace(0.0, np.pi, n))[:, None] ** 2
    kw = dict(iterations=2, contour=False)
    with warnings.catch_warnings():
        # the check may find sigma_max ~ 1 on odd plants; the solves are what is tested
        warnings.simplefilter("ignore", ConvergenceWarning)
        dense = learn(m, ref, law=NormOptimal(solver="dense"), **kw)
        cg = learn(m, ref, law=NormOptimal(solver="cg"), **kw)
    assert all(info.converged for upd in cg.cg for info in upd)
    bound = _step_error_bound(m, dense, 0)
    assert np.linalg.norm(cg.u[:, 0] - dense.u[:, 0]) <= max(bound, 1e-12), bound
