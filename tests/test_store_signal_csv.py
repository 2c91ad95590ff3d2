"""Signal CSV files (primlib.io._signal): bit-exact round trips, header and grid errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from primlib import InputError
from primlib.defaults import MAX_ABS_VALUE
from primlib.io import read_signal_csv, write_signal_csv


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(8, 60),
    d=st.sampled_from([2, 3]),
    dt=st.sampled_from([0.001, 0.005, 0.01, 1 / 3]),
    data=st.data(),
)
def test_round_trip_is_bit_exact(tmp_path_factory, n, d, dt, data):
    big = MAX_ABS_VALUE
    floats = st.floats(-big, big, allow_nan=False, allow_infinity=False, width=64)
    u = data.draw(hnp.arrays(np.float64, (n, d), elements=floats))
    t = np.arange(n) * dt
    f = tmp_path_factory.mktemp("sig") / "u.csv"
    write_signal_csv(f, t, u)
    t2, u2 = read_signal_csv(f, t=t)
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(u2, u)
    assert f.read_text().splitlines()[0] == ("t,ux,uy" if d == 2 else "t,ux,uy,uz")


def test_header_and_grid_errors_name_the_file(tmp_path):
    t = np.arange(20) * 0.005
    f = tmp_path / "u.csv"
    f.write_text("t,x,y\n" + "\n".join(f"{x!r},0,0" for x in t))
    with pytest.raises(InputError, match=r"u.csv: expected signal header t,ux,uy or t,ux,uy,uz"):
        read_signal_csv(f)
    write_signal_csv(f, t, np.zeros((20, 2)))
    with pytest.raises(InputError, match=r"u.csv: expected the path's time grid \(21 samples"):
        read_signal_csv(f, t=np.arange(21) * 0.005)
    with pytest.raises(InputError, match=r"dt = 0.01 s, T = 0.19 s\), got 20 samples, dt = 0.005"):
        read_signal_csv(f, t=np.arange(20) * 0.01)
    with pytest.raises(InputError, match=r"u.csv: expected a signal of shape \(n, 2\) or \(n, 3\)"):
        write_signal_csv(f, t, np.zeros((20, 4)))
