"""FFT Toeplitz operators and the largest singular value, against dense matrices."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg

from primlib import InputError
from primlib.plant import Machine, max_singular_value, toeplitz_operator


@pytest.mark.parametrize("n", [1, 2, 7, 128, 1000])
def test_lower_triangular_operator_matches_dense(n):
    rng = np.random.default_rng(0)
    h = rng.standard_normal(n)
    T = linalg.toeplitz(h, np.r_[h[0], np.zeros(n - 1)])
    op = toeplitz_operator(h)
    x = rng.standard_normal(n)
    X = rng.standard_normal((n, 3))
    tol = 1e-12 * np.sqrt(n) * np.max(np.abs(h)) * np.max(np.abs(X))
    np.testing.assert_allclose(op @ x, T @ x, atol=tol)
    np.testing.assert_allclose(op.T @ x, T.T @ x, atol=tol)
    np.testing.assert_allclose(op @ X, T @ X, atol=tol)
    np.testing.assert_allclose(op.T @ X, T.T @ X, atol=tol)


def test_general_toeplitz():
    rng = np.random.default_rng(1)
    h, row = rng.standard_normal((2, 50))
    row[0] = h[0]
    op = toeplitz_operator(h, row)
    x = rng.standard_normal(50)
    np.testing.assert_allclose(op @ x, linalg.toeplitz(h, row) @ x, atol=1e-12)
    with pytest.raises(InputError, match="first_row: expected shape"):
        toeplitz_operator(h, row[:10])


@pytest.mark.parametrize("method", ["svds", "lanczos", "power"])
def test_max_singular_value_of_a_machine(method):
    m = Machine.from_json("data/machines/xy-pdccilc.json")
    n = 600
    h = m.impulse_response(n)[:, 1]
    dense = np.linalg.norm(m.lifted(n)[1], 2)
    est = max_singular_value(toeplitz_operator(h), method=method, tol=1e-10)
    # power iteration stops on a relative change of 1e-10 per step; its error is larger
    np.testing.assert_allclose(est, dense, rtol={"svds": 1e-9, "lanczos": 1e-7}.get(method, 1e-4))


def test_max_singular_value_bad():
    with pytest.raises(InputError, match="method: expected 'svds', 'lanczos' or 'power', got 'qr'"):
        max_singular_value(np.eye(5), method="qr")
    with pytest.raises(InputError, match="h: expected a finite 1-D impulse response"):
        toeplitz_operator(np.array([np.nan, 1.0]))


def test_unconverged_lanczos_says_estimate_and_its_bound_holds():
    # a tight cluster at the top: sigma = 1, 1 - 1e-7, 1 - 2e-7, ... (orthogonally mixed)
    n = 400
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = 1.0 - 1e-7 * np.arange(n)
    s[n // 2 :] = np.linspace(0.5, 0.01, n - n // 2)
    A = (q * s) @ q.T
    for method, steps in (("lanczos", 60), ("lanczos", 3), ("power", 300)):
        est = max_singular_value(A, method=method, tol=1e-14, lanczos_steps=steps, full_output=True)
        assert not est.converged and "estimate" in est.method
        # the Ritz / Rayleigh value is a lower bound, within the stated bound of sigma_max
        assert est.value <= 1.0 + 1e-15
        assert 1.0 - est.value <= est.error_bound
        if method == "lanczos" and steps == 60:
            # k = 59: eps = (ln(1.648 sqrt(400) / 1e-6) / 117)^2 = 0.022 -> ~1.1 % in sigma
            assert est.error_bound < 0.02 and "(p >= 1 - 1e-06)" in est.method
        else:  # too few steps for the gap-free bound; power iteration has none
            assert est.error_bound == np.inf
    good = max_singular_value(A, method="lanczos", tol=1e-8, full_output=True)
    assert good.converged and good.method.endswith("converged")
    assert abs(good.value - 1.0) <= good.error_bound + 1e-15 and good.error_bound <= 1e-8


def test_full_output_float_compatible():
    m = Machine.from_json("data/machines/xyz.json")
    op = toeplitz_operator(m.impulse_response(500)[:, 0])
    est = max_singular_value(op, method="svds", full_output=True)
    assert est.value == max_singular_value(op, method="svds")
    assert isinstance(est.converged, bool) and isinstance(est.error_bound, float)
    np.testing.assert_allclose(est.value, np.linalg.norm(m.lifted(500)[0], 2), rtol=1e-9)
