"""The model-only input polished on the grey-box model run as a machine: on a machine that is
the model it removes what the analytic inverse leaves at stick and reversals, it is never worse
on the model, and it leaves alone what it does not simulate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_greybox import _coulomb_machine, _smooth_path
from test_greybox_refit import _lagged

from primlib.greybox import TERMS, GreyBox, forward_model, polish
from primlib.greybox._features import speed_scale
from primlib.plant import RealisticMachine, invert

FC = 0.3


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def _own_model(lin, path: np.ndarray, fc: float = FC, hard: bool = True) -> GreyBox:
    """A grey-box model whose terms are the Coulomb machine's own: level ``fc`` per axis."""
    d = lin.dim
    coef = np.zeros((d, len(TERMS)))
    coef[:, TERMS.index("coulomb")] = fc
    v = np.diff(path, axis=0) / lin.dt
    speed = np.array([speed_scale(v[:, i]) for i in range(d)])
    z = np.zeros(d)
    return GreyBox(lin, coef, z, speed, z, z, z, path.shape[0], hard=np.full(d, hard))


@pytest.mark.parametrize("seed", range(3))
def test_on_the_models_own_machine_the_polish_removes_what_the_inverse_leaves(seed):
    rm, lin = _coulomb_machine(FC)
    path = _smooth_path(600, np.random.default_rng(seed), None)
    gb = _own_model(lin, path)
    u0 = gb.inverse(path)
    u1, (before, after) = polish(gb, path, u0)
    e0 = _rms(rm.simulate(u0) - path)
    e1 = _rms(rm.simulate(u1) - path)
    # the model is the machine: what polish reports on the model is what the machine does
    assert before == pytest.approx(e0, rel=1e-9) and after == pytest.approx(e1, rel=1e-9)
    # the analytic inverse leaves the reversals' and stops' error (um here); the polished
    # input is the machine's exact inverse up to rounding (the corrections go on until the
    # error is 1e-9 of the path's size) and what the linear inverse itself leaves of the path
    # (its sampling-zero band, :meth:`GreyBox.inverse_gap`; ~1e-11 mm on these paths)
    gap = _rms(lin.simulate(invert(lin, path)) - path)
    assert e0 > 1e-3
    assert e1 <= 1e-9 * np.max(np.abs(path)) + 10 * gap


@pytest.mark.parametrize("seed", range(3))
def test_the_polish_is_never_worse_on_the_model(seed):
    # a model whose level is 10 % off the machine's: on the model the polished input is never
    # worse than the analytic one (the best input on the model is kept)
    rng = np.random.default_rng(10 + seed)
    _, lin = _coulomb_machine(FC)
    path = _smooth_path(500, rng, None)
    gb = _own_model(lin, path, fc=FC * rng.uniform(0.9, 1.1))
    u0 = gb.inverse(path)
    u1, (before, after) = polish(gb, path, u0)
    assert after <= before
    model = forward_model(gb)
    assert _rms(model.simulate(u1) - path) == pytest.approx(after, rel=1e-9)


def test_what_is_not_simulated_is_left_alone():
    rm, lin = _coulomb_machine(FC)
    path = _smooth_path(400, np.random.default_rng(3), None)
    # a smooth-sign model (friction rising smoothly through zero velocity) and a model
    # without friction keep their analytic input, and say so by NaN errors
    for gb in (_own_model(lin, path, hard=False), _own_model(lin, path, fc=0.0)):
        u0 = gb.inverse(path)
        u1, errors = polish(gb, path, u0)
        np.testing.assert_array_equal(u1, u0)
        assert all(math.isnan(x) for x in errors)
        assert forward_model(gb) is None
    # a model with linear terms (fitted without a refined model) likewise
    gb = _own_model(lin, path)
    coef = gb.coef.copy()
    coef[:, TERMS.index("velocity")] = 0.01
    assert forward_model(dataclasses.replace(gb, coef=coef)) is None


def test_the_forward_model_carries_the_fitted_forces():
    _, lin = _coulomb_machine(FC)
    path = _smooth_path(300, np.random.default_rng(4), None)
    gb = _own_model(lin, path)
    coef = gb.coef.copy()
    c1, c2, w = 0.04, -0.03, 2 * np.pi / 5.0
    coef[0, TERMS.index("ripple_sin")], coef[0, TERMS.index("ripple_cos")] = c1, c2
    coef[0, TERMS.index("stribeck")] = 0.06
    coef[1, TERMS.index("stribeck")] = -0.02  # lowers the static level: stays analytic
    gb = dataclasses.replace(gb, coef=coef, w=np.array([w, 0.0, 0.0]))
    dep = forward_model(gb).departures
    x = np.linspace(-7.0, 13.0, 9)
    a, p, phi = dep["x"]["ripple"], dep["x"]["ripple_pitch"], dep["x"]["ripple_phase"]
    np.testing.assert_allclose(
        a * np.sin(2 * np.pi * x / p + phi), c1 * np.sin(w * x) + c2 * np.cos(w * x), atol=1e-12
    )
    # the static level: Coulomb plus the Stribeck term at rest; the Gaussian decay of the
    # same area as the fitted exponential (v_s = 0.1 of the axis's speed)
    assert dep["x"]["coulomb"] * dep["x"]["static_ratio"] == pytest.approx(FC + 0.06)
    v_s = 0.1 * gb.speed[0]
    assert dep["x"]["stribeck_velocity"] * math.sqrt(math.pi) / 2 == pytest.approx(v_s)
    assert dep["y"]["static_ratio"] == 1.0 and dep["y"]["coulomb"] == FC
    assert dep["y"]["ripple"] == 0.0
    # without an absolute start the ripple is not simulated (nor evaluated by the inverse)
    assert forward_model(gb, ripple=False).departures["x"]["ripple"] == 0.0


def _lagged_coulomb_machine(fc: float):
    """The xyz machine with a 12 ms lag per axis (test_greybox_refit's) and Coulomb friction
    ``fc``: its sampled model has a zero outside the unit circle, so its inverse is the
    stable (non-causal) one."""
    lin = _lagged()
    return RealisticMachine.from_machine(lin, coulomb=fc), lin


@pytest.mark.parametrize("seed", range(3))
def test_on_a_lagged_models_own_machine_the_polish_reaches_rounding(seed):
    # with the lag the linear inverse is the stable one, whose pre-actuation cut at t = 0
    # leaves an offset on an integrating axis for the rest of the path (0.12-0.15 mm on these
    # paths, which start moving). A correction u += g G^-1 e built on it put that offset back
    # every step, so no step was kept: the polish returned the analytic input (1.1e-3 to
    # 2.0e-3 mm on the model that is the machine). With the start corrected the corrections
    # converge to what the corrected linear inverse itself leaves of the path (its sampling
    # zeros' band, 2.0e-5 to 2.4e-5 mm here; measured equal to 1e-8), plus rounding
    rm, lin = _lagged_coulomb_machine(FC)
    path = _smooth_path(600, np.random.default_rng(seed), None)
    gb = _own_model(lin, path)
    u1, (before, after) = polish(gb, path, gb.inverse(path))
    e1 = _rms(rm.simulate(u1) - path)
    assert after == pytest.approx(e1, rel=1e-9)
    gap = _rms(lin.simulate(invert(lin, path, correct_start=True)) - path)
    assert e1 <= 1e-9 * np.max(np.abs(path)) + 1.01 * gap
