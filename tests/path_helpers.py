"""Short rest-to-rest test paths on the XYZ machine's 5 ms grid (minimum-jerk timing)."""

from __future__ import annotations

import numpy as np

DT = 0.005


def minjerk(r):
    return 10 * r**3 - 15 * r**4 + 6 * r**5


def _s(T):
    return minjerk(np.arange(round(T / DT) + 1) * DT / T)


def arc(T):
    """A quarter circle of radius 10 in xy, climbing 3 in z, over T seconds."""
    s = _s(T)
    return np.stack([10 * np.sin(np.pi / 2 * s), 10 * (1 - np.cos(np.pi / 2 * s)), 3 * s], 1)


def wave(T):
    """12 along x with one period of a 3-high sine in y, 2 down in z."""
    s = _s(T)
    return np.stack([12 * s, 3 * np.sin(2 * np.pi * s), -2 * s], 1)


def line(T):
    """12 along x, 2 down in z."""
    s = _s(T)
    return np.stack([12 * s, 0 * s, -2 * s], 1)
