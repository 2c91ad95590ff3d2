"""Smoke test of the residual-correction ablations in benchmarks/_ablations.py."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from primlib.match import Segment
from primlib.plant import Machine, invert
from primlib.splice import Correction, StoredSignal, splice

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _ablations import CORRECTIONS  # noqa: E402


@pytest.fixture(scope="module")
def xyz():
    return Machine.from_json(ROOT / "data" / "machines" / "xyz.json")


def _arc(T, dt):
    r = np.arange(round(T / dt) + 1) * dt / T
    s = 10 * r**3 - 15 * r**4 + 6 * r**5
    return np.stack([5 - 5 * np.cos(np.pi * s), 5 * np.sin(np.pi * s), 2 * s], 1)


def _rot_z(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


@pytest.mark.parametrize("name", sorted(CORRECTIONS))
def test_each_ablation_is_a_correction_and_runs(xyz, name):
    corr = CORRECTIONS[name]
    assert isinstance(corr, Correction) and corr.name == name
    pa = _arc(2.0, xyz.dt) + np.array([1.0, 2.0, 3.0])
    stored = {7: StoredSignal(invert(xyz, pa - pa[0]), pa, 2.0, "arc")}
    R, c = _rot_z(0.6), np.array([0.5, -1.0, 2.0])
    new = (_arc(1.6, xyz.dt) + np.array([1.0, 2.0, 3.0])) @ R.T + c
    seg = Segment(0, 1, 7, None, 0, 1, R, c, 2.0 / 1.6, 0.0)
    res = splice(xyz, new, 1.6, [seg], stored, correction=corr)
    assert res.correction == name and res.u.shape == new.shape
    err = np.abs(xyz.simulate(res.u) - (new - new[0])).max()
    if name in ("input", "output"):
        # through the pieces' paths, a cubic spline of the stored samples at k t: error
        # ~ dt^4 max|y^(4)| / 384, below 1e-7 of this 10-unit arc
        assert err < 1e-7 * np.abs(pa).max()
    elif name == "none":
        np.testing.assert_array_equal(res.u, res.spliced)
    # "junction" with one piece has no junction: the spliced input as it is
    if name == "junction":
        np.testing.assert_array_equal(res.u, res.spliced)
