"""The refinement's structural mode (primlib.splice.refine_machine, modes=True): found where
the machine has one, not invented where it has none, and carried into the warm start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from path_helpers import DT
from path_helpers import arc as _arc
from path_helpers import wave as _wave

from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.plant import Machine, RealisticMachine, invert
from primlib.splice import refine_machine

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def xyz():
    return Machine.from_json(ROOT / "data" / "machines" / "xyz.json")


def _true(xyz, hz=None, zeta=0.05):
    """+10 % gain, time constants x1.2, a 10 ms lag and, with ``hz``, a mode in series."""
    plants = {}
    for a, (num, den) in xyz.plants.items():
        n_, d_ = 1.1 * np.asarray(num), np.convolve(den * [1.2**2, 1.2, 1.0], [0.01, 1.0])
        if hz:
            w = 2 * np.pi * hz
            n_, d_ = n_ * w * w, np.convolve(d_, [1.0, 2 * zeta * w, w * w])
        plants[a] = (n_, d_)
    return Machine("xyz", DT, xyz.axes, plants)


def _pairs(machine, shapes):
    """(input, the motion it gave): a stored pair is what the machine did with its input
    (the inverse of a mode's non-minimum-phase sampling zeros is truncated at t = 0, so
    the motion is not exactly the shape there)."""
    out = []
    for pts in shapes:
        u = invert(machine, pts - pts[0])
        out.append((u, machine.simulate(u)))
    return out


@pytest.mark.parametrize("hz,zeta", [(20.0, 0.05), (35.0, 0.15)])
def test_a_mode_in_series_is_found_with_the_rest(xyz, hz, zeta):
    got = refine_machine(xyz, _pairs(_true(xyz, hz, zeta), [_arc(1.0), _wave(1.2)]))
    # noise-free pairs of a machine inside the family: the least squares' answer is the
    # machine itself, to the solver's tolerance
    np.testing.assert_allclose(got.mode[:, 0], hz, rtol=1e-4)
    np.testing.assert_allclose(got.mode[:, 1], zeta, rtol=1e-3)
    np.testing.assert_allclose(got.theta[:, 1], 1.2, rtol=1e-4)
    np.testing.assert_allclose(got.theta[:, 2], 0.01, rtol=1e-3)
    assert np.all(got.rms_refined < 1e-4 * got.rms_nominal)
    # without the mode the three parameters are biased and leave far more
    plain = refine_machine(xyz, _pairs(_true(xyz, hz, zeta), [_arc(1.0), _wave(1.2)]), modes=False)
    assert plain.mode is None
    assert np.all(plain.rms_refined > 100 * got.rms_refined)


@pytest.mark.parametrize("noise", [0.0, 1e-4])
def test_no_mode_is_invented_for_a_machine_without_one(xyz, noise):
    # noise-free, the fit without a mode leaves nothing to explain and none is searched;
    # with white noise of 1e-4 of the motion on the measured paths the search runs, and no
    # mode halves an error that is noise
    rng = np.random.default_rng(1)
    pairs = [
        (u, y + noise * np.max(np.abs(y)) * rng.standard_normal(y.shape))
        for u, y in _pairs(_true(xyz), [_arc(1.0), _wave(1.2)])
    ]
    got = refine_machine(xyz, pairs)
    np.testing.assert_array_equal(got.mode, 0.0)
    if noise == 0.0:
        np.testing.assert_allclose(got.theta[:, 2], 0.01, rtol=1e-3)


def test_no_mode_stands_in_for_friction(xyz):
    # Coulomb friction at 5 % of the input: a nonlinearity no mode explains; the gate
    # (a mode must halve the error) keeps it out
    true = RealisticMachine.from_machine(_true(xyz), coulomb=0.05, typical_input=1.0, seed=0)
    pairs = []
    for pts in (_arc(1.0), _wave(1.2)):
        y = pts - pts[0]
        u = invert(_true(xyz), y)
        pairs.append((u, true.simulate(u)))
    got = refine_machine(xyz, pairs)
    np.testing.assert_array_equal(got.mode, 0.0)


def test_the_warm_start_carries_the_mode_through_rotation_and_time_scale(xyz):
    true = _true(xyz, 20.0, 0.05)
    lib = Library()
    lib.add_machine(xyz)
    items = []
    for name, pts in (("arc", _arc(1.0)), ("wave", _wave(1.2))):
        # as ILC leaves it: the input that makes the machine follow the stored path to
        # 1e-5 mm (the regularised lifted inverse; the stable one is truncated at t = 0)
        traj = Trajectory.from_samples(pts, DT)
        u = invert(true, traj.sample(DT) - traj.sample(DT)[0], method="lifted")
        items.append((traj, u, name, "test"))
    lib.add_many(items, "xyz")
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    a = _arc(1.25) @ rz.T
    b = _wave(1.2)
    traj = Trajectory.from_samples(np.vstack([a, (b + a[-1] - b[0])[1:]]), DT)
    ref = traj.sample(DT) - traj.sample(DT)[0]
    err = {}
    for modes in (True, False):
        ws = lib.warm_start(traj, "xyz", 0.005, greybox=False, modes=modes)
        err[modes] = np.sqrt(np.mean((true.simulate(ws.u) - ref) ** 2))
        assert ("mode 20 Hz" in " ".join(ws.notes)) == modes
    assert err[True] < 0.2 * err[False]


def test_an_axis_whose_fit_ends_at_a_bound_is_said_to(xyz):
    # y's stored inputs do not make their paths: a third of what its machine needs (a young
    # library's unconverged inputs, or pairs from elsewhere). The least squares take the gain
    # to its upper bound (2): kept (under friction a bound stands in for it), but said
    true = _true(xyz)
    pairs = [(u * np.array([1.0, 1 / 3, 1.0]), y) for u, y in _pairs(true, [_arc(1.0), _wave(1.2)])]
    got = refine_machine(xyz, pairs, modes=False)
    assert got.at_bound[0] == got.at_bound[2] == ""
    assert got.at_bound[1].startswith("gain 2")
    assert got.theta[1][0] == pytest.approx(2.0, rel=1e-6)  # the bound, to the solver
    # the other axes are refined as ever: the machine itself, to the solver's tolerance
    np.testing.assert_allclose(got.theta[[0, 2]], [[1.1, 1.2, 0.01]] * 2, rtol=1e-3)
    # the warm start's note says so
    from primlib.pipeline._starter import _refined_note

    note = _refined_note(xyz, got)
    assert "y: gain 2, " in note and "(at its bound: gain 2; the pairs do not determine" in note
    assert "x: gain 1.1" in note and note.count("at its bound") == 1
