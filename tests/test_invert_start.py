"""The stable inverse's start correction (primlib.plant.invert): what the truncated
pre-actuation leaves on an integrating axis is a lasting offset, taken out over the first
samples."""

from __future__ import annotations

import numpy as np
import pytest

from primlib.plant import Machine, invert

DT = 0.005


def _axis(lag: float, hz: float | None):
    """K / (s (T s + 1)) with a lag and, with ``hz``, a mode of damping 0.05 in series:
    relative degree 3 or 5, so the ZOH model has sampling zeros outside the unit circle."""
    num, den = np.array([1.2]), np.convolve([0.2, 1.0, 0.0], [lag, 1.0])
    if hz:
        w = 2 * np.pi * hz
        num, den = num * w * w, np.convolve(den, [1.0, 0.1 * w, w * w])
    return Machine("m", DT, ("x",), {"x": (num, den)})


def _path(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return (20 * (10 * s**3 - 15 * s**4 + 6 * s**5))[:, None]


@pytest.mark.parametrize("hz", [None, 20.0])
@pytest.mark.parametrize("n", [241, 701])
def test_the_stable_inverse_tracks_as_well_as_the_lifted_one(hz, n):
    m = _axis(0.012, hz)
    yd = _path(n)
    u = invert(m, yd, correct_start=True)
    lifted = invert(m, yd, method="lifted")
    err = np.sqrt(np.mean((m.simulate(u) - yd) ** 2))
    err_lifted = np.sqrt(np.mean((m.simulate(lifted) - yd) ** 2))
    # both are the regularised least-squares answer near the start (the same weight);
    # beyond it the stable inverse is exact, so it is no worse than the lifted one
    assert err <= 2 * err_lifted + 1e-12 * np.max(np.abs(yd))
    # and bounded like it: no start kick
    assert np.max(np.abs(u)) <= 1.1 * np.max(np.abs(lifted))


def test_the_correction_removes_a_lasting_offset():
    m = _axis(0.012, 20.0)
    yd = _path(1201)
    err = m.simulate(invert(m, yd, correct_start=True)) - yd
    # the truncated pre-actuation alone left a lasting offset of 1.4e-5 of the motion
    # on this axis; corrected, the second half of the path is exact to the solver's level
    assert np.max(np.abs(err[600:])) < 1e-8 * np.max(np.abs(yd))
