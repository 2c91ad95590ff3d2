"""WarmStarter: warm start and learn through a real (in-memory) Library and the real matcher."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from path_helpers import DT
from path_helpers import arc as _arc
from path_helpers import wave as _wave

from primlib import NoMatchError
from primlib.nurbs import Trajectory
from primlib.pipeline import Library, WarmStart, find_versions
from primlib.plant import Machine, invert
from primlib.splice import refine_machine

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def xyz():
    return Machine.from_json(ROOT / "data" / "machines" / "xyz.json")


def _library(machine, shapes):
    lib = Library()
    lib.add_machine(machine)
    items = []
    for name, pts in shapes:
        traj = Trajectory.from_samples(pts, DT)
        ref = traj.sample(DT) - pts[0]
        fb = ref if machine.feedback else None
        items.append((traj, invert(machine, ref, reference=fb), name, "test"))
    lib.add_many(items, machine.name)
    return lib


@pytest.fixture(scope="module")
def lib(xyz):
    return _library(xyz, [("arc", _arc(1.0)), ("wave", _wave(1.2))])


def test_warm_start_of_a_stored_primitive_returns_its_signal(lib):
    pid = lib.primitives("xyz")[0].id
    prim = lib.get(pid)
    ws = lib.warm_start(prim.trajectory, machine="xyz", eps=0.01)
    assert isinstance(ws, WarmStart)
    assert ws.match.segments[0].primitive == pid
    # (a last unmatched sliver of the matcher's final search step, if any, is absorbed)
    assert ws.methods == ("identity",)
    # the matcher's rotation is the identity to rounding: the stored signal comes back
    np.testing.assert_allclose(ws.u, prim.signal, atol=1e-9 * np.abs(prim.signal).max())
    np.testing.assert_allclose(ws.t, prim.times())


def test_warm_start_of_new_path_from_two_pieces(lib, xyz):
    # the arc 1.25x slower and rotated about z, then the wave, at rest at the junction
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    a = _arc(1.25) @ rz.T
    b = _wave(1.2)
    path = np.vstack([a, (b + a[-1] - b[0])[1:]])
    traj = Trajectory.from_samples(path, DT)
    ws = lib.warm_start(traj, "xyz", 0.005)
    n = round(traj.duration / DT) + 1
    assert ws.u.shape == (n, 3) and ws.t.shape == (n,)
    assert len(ws.bands) == len(ws.match.segments) - 1
    assert len(ws.sources) == len(ws.match.segments)
    ref = traj.sample(DT)
    ref = ref - ref[0]
    warm = np.sqrt(np.mean((xyz.simulate(ws.u) - ref) ** 2))
    cold = np.sqrt(np.mean(ref**2))
    # on the nominal machine only the match (eps) and NURBS fits limit the warm start
    assert warm < cold / 100


def test_refine_recovers_a_machine_in_the_family(xyz):
    true = Machine(
        "xyz",
        DT,
        xyz.axes,
        {
            a: (1.1 * num, np.convolve(den * [1.2**2, 1.2, 1.0], [0.01, 1.0]))
            for a, (num, den) in xyz.plants.items()
        },
    )
    pairs = []
    for pts in (_arc(1.0), _wave(1.2)):
        y = pts - pts[0]
        pairs.append((invert(true, y), y))
    got = refine_machine(xyz, pairs)
    # G_θ = g num / den(c s) / (τ s + 1); den(c s) = c s (T c s + 1): g / c = 1.1 / 1.2
    np.testing.assert_allclose(got.theta[:, 1], 1.2, rtol=1e-4)
    np.testing.assert_allclose(got.theta[:, 0], 1.1 * 1.2 / 1.2, rtol=1e-3)
    np.testing.assert_allclose(got.theta[:, 2], 0.01, rtol=1e-3)
    assert np.all(got.rms_refined < 1e-3 * got.rms_nominal)
    # nominal pairs: the nominal model comes back
    nominal = refine_machine(xyz, [(invert(xyz, p - p[0]), p - p[0]) for p in (_arc(1.0),)])
    np.testing.assert_allclose(nominal.theta[:2], [[1, 1, 0], [1, 1, 0]], atol=1e-4)


def test_versions_and_eq20_are_used(xyz):
    lib = _library(xyz, [("arc", _arc(1.0)), ("arc-slow", _arc(2.0)), ("wave", _wave(1.2))])
    bank = lib.bank("xyz")
    assert find_versions(bank, 0) == [1]
    assert find_versions(bank, 2) == []
    traj = Trajectory.from_samples(_arc(1.4), DT)
    ws = lib.warm_start(traj, "xyz", 0.01, refine=False)
    assert ws.methods == ("direct",)
    ref = traj.sample(DT)
    err = np.sqrt(np.mean((xyz.simulate(ws.u) - (ref - ref[0])) ** 2))
    # eq. (20) is exact in continuous time; on the 5 ms ZOH grid it leaves O(dt^2)
    assert err < 1e-3 * np.sqrt(np.mean((ref - ref[0]) ** 2))


def test_learn_warm_and_cold(lib, xyz):
    traj = Trajectory.from_samples(_arc(1.1), DT)
    ref = traj.sample(DT)
    ref = ref - ref[0]
    for cold in (False, True):
        u = lib.learn(traj, "xyz", iterations=3, cold=cold, contour=False).u
        assert u.shape == ref.shape
        assert np.sqrt(np.mean((xyz.simulate(u) - ref) ** 2)) < 1e-3


def test_warm_start_needs_primitives(xyz):
    lib = Library()
    lib.add_machine(xyz)
    traj = Trajectory.from_samples(_arc(1.0), DT)
    with pytest.raises(NoMatchError):
        lib.warm_start(traj, "xyz", 0.01)


def test_warm_start_on_the_pid_stage_holds_the_offset():
    # two-axis non-minimum-phase stage in a PID loop (PDCCILC paper, eq. (33)): the second
    # piece starts 10 mm away, which a stable plant only holds with a DC feedforward
    m = Machine.from_json(ROOT / "data" / "machines" / "xy-pdccilc.json")
    arc = _arc(3.0)[:, :2]
    line = _wave(3.0)[:, :2] * [1.0, 0.0]
    lib = _library(m, [("arc", arc), ("line", line)])
    rz = np.array([[0, -1], [1, 0.0]])
    a = _arc(3.6)[:, :2]
    b = (_wave(2.5)[:, :2] * [1.0, 0.0]) @ rz.T
    path = np.vstack([a, (b + a[-1] - b[0])[1:]])
    traj = Trajectory.from_samples(path, DT)
    ws = lib.warm_start(traj, "xy-pdccilc", 0.01)
    ref = traj.sample(DT)
    ref = ref - ref[0]
    warm = np.sqrt(np.mean((m.simulate(ws.u, ref) - ref) ** 2))
    cold = np.sqrt(np.mean((m.simulate(np.zeros_like(ws.u), ref) - ref) ** 2))
    assert np.all(np.isfinite(ws.u))
    assert warm < cold / 100


def _hf(u):
    """RMS of the second difference / 4 per axis: the input's content near Nyquist."""
    return np.sqrt(np.mean((np.diff(u, 2, axis=0) / 4) ** 2, axis=0))


@pytest.mark.xfail(
    reason="known limit, not the junction chatter of issue 12 (fixed: test_splice_inverse): "
    "the library records no stored signal's worth here, so both segments take the model-only "
    "input, the grey-box model's exact inverse, which rings near Nyquist after the path's "
    "curvature jumps (the join at sample 250, the wave's turn near 390): 0.224 where the "
    "stored inputs have 0.173. Band-limited as the splice's inverses are (band_limit) it is "
    "0.108 at the same error on the machine (1.2038e-3 mm), but the model-only input then "
    "loses its sample-exact tracking on the model (bench_realism's linear library, rotated "
    "paths 2.5e-8 -> 6.2e-7 mm, their near-Nyquist content 30 % lower; stop 51), so it is "
    "not done. Strict, so a fix shows up as a failure to remove this mark.",
    strict=True,
)
def test_warm_start_adds_no_chatter_beyond_the_stored_inputs(xyz):
    # the correction adds no chatter: near-Nyquist input content no more than the stored
    # inputs' own (the machine's exact inverses start with a kick its lag needs)
    lib, traj, _, items = _different_machine_case(xyz)
    warm = lib.warm_start(traj, "xyz", 0.005, refine=False)
    stored = max(float(_hf(u).max()) for _, u, _, _ in items)
    assert float(_hf(warm.u).max()) <= stored


def _different_machine_case(xyz):
    """The machine is not its model (+8 % gain, +15 % time constant, a 12 ms lag); the
    library holds that machine's exact inputs. Returns (library, new path, true machine,
    stored items)."""
    true = Machine(
        "xyz",
        DT,
        xyz.axes,
        {
            a: (1.08 * num, np.convolve(den * [1.15, 1.0, 1.0], [0.012, 1.0]))
            for a, (num, den) in xyz.plants.items()
        },
    )
    lib = Library()
    lib.add_machine(xyz)
    items = []
    for name, pts in (("arc", _arc(1.0)), ("wave", _wave(1.2))):
        traj = Trajectory.from_samples(pts, DT)
        ref = traj.sample(DT) - pts[0]
        items.append((traj, invert(true, ref, method="lifted"), name, "test"))
    lib.add_many(items, "xyz")
    rz = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    a = _arc(1.25) @ rz.T
    b = _wave(1.2)
    path = np.vstack([a, (b + a[-1] - b[0])[1:]])
    return lib, Trajectory.from_samples(path, DT), true, items


def test_residual_correction_beats_the_model_inverse_on_a_different_machine(xyz):
    # on the nominal model (no refinement) the warm start only carries the model's error
    # through the change of the pieces' measured error under the time scale, the nominal
    # inverse carries all of it
    lib, traj, true, _ = _different_machine_case(xyz)
    ref = traj.sample(DT)
    ref = ref - ref[0]

    def rms(u):
        return np.sqrt(np.mean((true.simulate(u) - ref) ** 2))

    inverse = invert(xyz, ref)
    warm = lib.warm_start(traj, "xyz", 0.005, refine=False)
    assert rms(warm.u) < rms(inverse) / 1.5
    # refined on the library's pairs the model is the machine's family: far better still
    refined = lib.warm_start(traj, "xyz", 0.005)
    assert rms(refined.u) < rms(warm.u) / 20


def test_without_records_a_transformed_piece_takes_the_model_and_says_why(lib):
    # the library records no stored signal's worth (added without error_rms): a rotated
    # stored piece cannot earn its place over the model-only input, and the warm start says so
    prim = lib.get(lib.primitives("xyz")[0].id)
    c, s = np.cos(0.6), np.sin(0.6)
    pts = prim.trajectory.sample(DT) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T
    ws = lib.warm_start(Trajectory.from_samples(pts, DT), machine="xyz", eps=0.01)
    assert ws.match.segments[0].primitive == prim.id
    assert ws.choices[0] == "model"
    assert "records no stored signal's worth" in ws.sources[0]
    np.testing.assert_array_equal(ws.u, ws.model_u)
