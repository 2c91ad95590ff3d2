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
