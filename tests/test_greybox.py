"""The grey-box model: what it finds on a machine with friction and ripple, what it does not
invent on a linear one, and its refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.greybox import TERMS, Pair, fit_greybox
from primlib.plant import Machine, invert

ROOT = Path(__file__).resolve().parents[1]
STAGE = Machine.from_json(ROOT / "examples" / "stage" / "stage.json")


def _nominal(stage=STAGE) -> Machine:
    plants = {
        a: ([p["K"] / stage.length_unit], [p["M"], p["B"], 0.0]) for a, p in stage.motors.items()
    }
    return Machine(stage.name, stage.dt, stage.axes, plants)


def _loop(n: int, size: float, turns: float, phase: float) -> np.ndarray:
    """A smooth rest-to-rest 2-D path relative to its start (mm)."""
    s = np.linspace(0.0, 1.0, n)
    s = s**3 * (10 - 15 * s + 6 * s**2)
    a = 2 * np.pi * turns * s + phase
    return np.c_[size * (np.cos(a) - np.cos(phase)) + 20 * s, size * (np.sin(a) - np.sin(phase))]


def _stage_pair(path: np.ndarray, origin, iterations: int = 12) -> Pair:
    """The stage's converged pair for ``path`` at ``origin``: ILC (P-type on the nominal
    inverse, as the library's inputs are learned) until the stage follows it."""
    nom = _nominal()
    u = invert(nom, path)
    for _ in range(iterations):
        e = path - STAGE.simulate(u, start=origin)
        u = u + invert(nom, e)
    return Pair(u, path, np.asarray(origin, float))


@pytest.fixture(scope="module")
def stage_fit():
    pairs = [
        _stage_pair(_loop(1001, 12.0, 1.0, 0.3), (40.0, 25.0)),
        _stage_pair(_loop(1001, 8.0, 1.5, 1.7), (75.0, 10.0)),
        _stage_pair(_loop(801, 15.0, 0.75, 2.9), (10.0, 60.0)),
    ]
    return fit_greybox(_nominal(), pairs), pairs


def test_the_stage_is_followed_by_its_pairs(stage_fit):
    # the ILC above converged: the pairs are what the stage really needs (else the fit below
    # would be judged on pairs that are not the machine's)
    _, pairs = stage_fit
    for p in pairs:
        assert np.max(np.abs(STAGE.simulate(p.u, start=p.origin) - p.y)) < 1e-2  # 10 um


def test_ripple_pitch_and_amplitude_are_found(stage_fit):
    gb, _ = stage_fit
    pitch_mm = STAGE.motors["x"]["ripple_pitch"] / STAGE.length_unit
    c = dict(zip(TERMS, gb.coef[0], strict=True))
    assert 2 * np.pi / gb.w[0] == pytest.approx(pitch_mm, rel=0.02)
    # ripple force C_c sin(w0 x) opposes the input: K u = ... + C_c sin(w0 x)
    amp = STAGE.motors["x"]["Cc"] / STAGE.motors["x"]["K"]
    assert np.hypot(c["ripple_sin"], c["ripple_cos"]) == pytest.approx(amp, rel=0.1)
    assert c["coulomb"] + c["stribeck"] > 0  # friction opposes the motion: more input


def test_the_inverse_follows_a_new_path_at_a_new_place(stage_fit):
    gb, _ = stage_fit
    path = _loop(1201, 10.0, 1.25, 0.9)
    origin = np.array([130.0, 45.0])

    def err(u):
        return float(np.sqrt(np.mean((STAGE.simulate(u, start=origin) - path) ** 2)))

    linear = err(invert(_nominal(), path))
    grey = err(gb.inverse(path, origin))
    no_place = err(gb.inverse(path))  # without where it runs the ripple is left out
    assert grey < linear / 10
    assert grey < no_place
    # the three parts add up to the inverse
    u_lin, lin, non = gb.terms(path, origin)
    assert np.allclose(u_lin + lin + non, gb.inverse(path, origin))


def test_nothing_is_invented_on_a_linear_machine():
    # the machine is its nominal model with 10 % more mass; stored inputs carry noise that
    # ILC learned: the fit may correct the linear terms but adds no friction and no ripple
    nom = _nominal()
    heavy = Machine(
        "heavy",
        nom.dt,
        nom.axes,
        {a: (num, [den[0] * 1.1, *den[1:]]) for a, (num, den) in nom.plants.items()},
    )
    rng = np.random.default_rng(3)
    pairs = []
    for k, origin in enumerate([(0.0, 0.0), (50.0, 20.0), (90.0, 70.0)]):
        path = _loop(1001, 10.0 + 2 * k, 1.0 + 0.25 * k, 0.5 * k)
        u = invert(heavy, path)
        pairs.append(Pair(u + 1e-3 * np.std(u) * rng.standard_normal(u.shape), path, origin))
    gb = fit_greybox(nom, pairs)
    assert np.all(gb.w == 0)
    nonlinear = [TERMS.index(t) for t in ("coulomb", "stribeck", "bias")]
    assert np.all(gb.coef[:, nonlinear] == 0)
    path = _loop(901, 9.0, 1.1, 2.0)
    assert np.max(np.abs(gb.inverse(path) - invert(heavy, path))) < 0.05 * np.max(
        np.abs(invert(heavy, path))
    )
    assert np.all(gb.cv_rms <= gb.rms_nominal)


def test_an_axis_that_did_not_move_gets_no_terms():
    nom = _nominal()
    path = _loop(501, 10.0, 1.0, 0.0)
    path[:, 1] = 0.0
    gb = fit_greybox(nom, [Pair(invert(nom, path), path, (0.0, 0.0))])
    assert np.all(gb.coef[1] == 0)
    assert any("did not move" in n for n in gb.notes)


@pytest.mark.parametrize(
    "pairs, needle",
    [
        ([], "at least one stored pair"),
        ([Pair(np.zeros((10, 2)), np.zeros((10, 3)))], "same shape"),
        ([Pair(np.full((10, 2), np.nan), np.zeros((10, 2)))], "finite"),
    ],
)
def test_refusals(pairs, needle):
    with pytest.raises(InputError, match=needle):
        fit_greybox(_nominal(), pairs)
