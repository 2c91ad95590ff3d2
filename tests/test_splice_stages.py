"""The splice's stages one at a time: plan the junctions, place a piece, blend, correct."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.match import Segment
from primlib.plant import Machine, invert
from primlib.splice import (
    Band,
    CorrectionJob,
    ErrorCorrection,
    JunctionPlan,
    StoredSignal,
    band_limited_inverse,
    blend,
    derivative_orders,
    place_piece,
    plan_junctions,
    splice,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"


@pytest.fixture(scope="module")
def xyz():
    return Machine.from_json(DATA / "xyz.json")


def _arc(T, dt):
    r = np.arange(round(T / dt) + 1) * dt / T
    s = 10 * r**3 - 15 * r**4 + 6 * r**5
    return np.stack([5 - 5 * np.cos(np.pi * s), 5 * np.sin(np.pi * s), 2 * s], 1)


def _seg(start, end, pid, ps, pe, k=1.0, c=(0, 0, 0)):
    return Segment(start, end, pid, None, ps, pe, np.eye(3), np.asarray(c, float), k, 0.0)


@pytest.fixture(scope="module")
def arc(xyz):
    pa = _arc(2.0, xyz.dt) + np.array([1.0, 2.0, 3.0])
    return {7: StoredSignal(invert(xyz, pa - pa[0]), pa, 2.0, "arc")}


def _true(xyz):
    """+8 % gain, +15 % time constant, a 12 ms lag: a machine that is not its model."""
    plants = {
        a: (1.08 * num, np.convolve(den * [1.15, 1.0, 1.0], [0.012, 1.0]))
        for a, (num, den) in xyz.plants.items()
    }
    return Machine("xyz", xyz.dt, xyz.axes, plants)


# ---- plan -------------------------------------------------------------------------------


def test_plan_joins_one_primitives_consecutive_windows(xyz, arc):
    pa = arc[7].points
    segs = [_seg(0, 0.5, 7, 0, 0.5), _seg(0.5, 1, 7, 0.5, 1)]
    plan = plan_junctions(xyz, pa, 2.0, segs, arc)
    assert len(plan.segments) == 1 and plan.bands == ()
    assert plan.segments[0].primitive_end == 1 and plan.segments[0].end == 1


def test_plan_absorbs_an_unmatched_sliver(xyz, arc):
    pa = arc[7].points
    cut = 1 - 3 * xyz.dt / 2.0  # the last 3 samples unmatched
    none = Segment(cut, 1, None, None, np.nan, np.nan, np.eye(3), np.zeros(3), np.nan, np.nan)
    plan = plan_junctions(xyz, pa, 2.0, [_seg(0, cut, 7, 0, cut), none], arc)
    assert len(plan.segments) == 1
    assert plan.segments[0].primitive_end == pytest.approx(1.0)
    assert any("absorbed" in note for note in plan.notes)


def test_plan_band_is_confined_to_where_both_pieces_are_defined(xyz, arc):
    pa = arc[7].points
    v = (pa[201] - pa[199]) / (2 * xyz.dt)
    # the second window a tenth of a sample along the path: continuous, not the same window
    segs = [_seg(0, 0.5, 7, 0, 0.5), _seg(0.5, 1, 7, 0.5, 1, c=0.1 * xyz.dt * v)]
    plan = plan_junctions(xyz, pa, 2.0, segs, arc, band=0.04)
    (b,) = plan.bands
    assert b.kind == "continuous" and b.junction == pytest.approx(1.0)
    assert (b.start, b.end) == pytest.approx((0.98, 1.02))
    np.testing.assert_allclose(plan.reach, [[0, 0.02], [0.02, 0]], atol=1e-12)
    assert plan.extent_samples(0) == (0, 204) and plan.extent_samples(1) == (196, 400)
    # a window that starts at its primitive's start cannot reach back: no band before it
    segs = [_seg(0, 0.5, 7, 0, 0.5), _seg(0.5, 1, 7, 0, 0.5, k=1.0, c=pa[200] - pa[0])]
    (b,) = plan_junctions(xyz, pa, 2.0, segs, arc, band=0.04).bands
    assert b.start == pytest.approx(1.0)


# ---- place ------------------------------------------------------------------------------


def test_place_a_window_on_the_grid_is_the_stored_slice(xyz, arc):
    pa, u = arc[7].points, arc[7].signal
    new = pa[100:301]  # v 0.25..0.75 of the arc, 1 s
    seg = _seg(0, 1, 7, 0.25, 0.75)
    plan = plan_junctions(xyz, new, 1.0, [seg], arc)
    piece = place_piece(xyz, plan, 0, arc[7], "auto", derivative_orders(xyz))
    assert piece.method == "identity" and piece.placement.first == -100
    np.testing.assert_array_equal(piece.u, u[100:301])
    # what it was built to track: the stored path from the new path's first point
    np.testing.assert_allclose(piece.path, new - new[0], atol=1e-12)
    assert "primitive 7 (arc)" in piece.source


def test_place_a_time_scaled_piece_runs_the_primitive_faster(xyz, arc):
    new = _arc(1.6, xyz.dt) + np.array([1.0, 2.0, 3.0])
    plan = plan_junctions(xyz, new, 1.6, [_seg(0, 1, 7, 0, 1, k=1.25)], arc)
    piece = place_piece(xyz, plan, 0, arc[7], "auto", derivative_orders(xyz))
    assert piece.method == "model" and piece.placement.k == 1.25
    # the nominal model's output of the placed input is the stored output at 1.25 t, which
    # is the new path up to the stored samples' ZOH behaviour between samples (< 1e-4)
    err = np.abs(xyz.simulate(piece.u) - (new - new[0])).max()
    assert err < 1e-4


# ---- blend ------------------------------------------------------------------------------


def _plan_1d(band_start, band_end):
    n, dt = 11, 0.1
    segs = (_seg(0, 0.5, 1, 0, 1), _seg(0.5, 1, 2, 0, 1))
    bands = (Band(0.5, band_start, band_end, "continuous", 0.0, 0.0),)
    reach = np.array([[0, band_end - 0.5], [0.5 - band_start, 0]])
    bounds = np.array([[0, 0.5], [0.5, 1.0]])
    return JunctionPlan(np.zeros((n, 1)), segs, bounds, 1.0, dt, 0.4, bands, reach, 1.0)


def test_blend_is_linear_across_a_band_and_each_piece_elsewhere():
    plan = _plan_1d(0.3, 0.7)
    t = plan.t
    out = blend([np.ones((11, 1)), 3 * np.ones((11, 1))], plan)
    expect = np.where(t < 0.3, 1.0, np.where(t > 0.7, 3.0, 1 + 2 * (t - 0.3) / 0.4))
    np.testing.assert_allclose(out[:, 0], expect, atol=1e-12)
    # a band without width switches at the junction (t = 0.5 belongs to the later segment)
    out = blend([np.ones((11, 1)), 3 * np.ones((11, 1))], _plan_1d(0.5, 0.5))
    np.testing.assert_array_equal(out[:, 0], np.where(t < 0.5 - 1e-9, 1.0, 3.0))


# ---- correct ----------------------------------------------------------------------------


def _job(machine, plan, pieces, correction):
    terms = tuple(correction.piece_term(machine, p, plan.n) for p in pieces)
    u_s = blend([p.u for p in pieces], plan)
    return CorrectionJob(machine, plan, tuple(pieces), terms, u_s)


def test_error_correction_term_is_the_measured_error_from_the_window_on(xyz):
    true = _true(xyz)
    pa = _arc(2.0, xyz.dt)
    u = invert(true, pa - pa[0], method="lifted")  # the library learned on the true machine
    stored = {7: StoredSignal(u, pa, 2.0, "arc")}
    new = pa[100:]
    plan = plan_junctions(xyz, new, 1.5, [_seg(0, 1, 7, 0.25, 1)], stored)
    piece = place_piece(xyz, plan, 0, stored[7], "auto", derivative_orders(xyz))
    term = ErrorCorrection().piece_term(xyz, piece, plan.n)
    e_l = (pa - pa[0]) - xyz.simulate(u)  # the model's error on the stored pair
    # increments summed along the window: the error's change since the window's start
    np.testing.assert_allclose(np.cumsum(term, axis=0), e_l[100:] - e_l[100], atol=1e-12)
    assert np.abs(e_l).max() > 1e-2  # (a real error, not a vacuous zero)


def test_error_correction_on_the_nominal_machine_is_the_model_inverse(xyz, arc):
    new = _arc(1.6, xyz.dt) + np.array([1.0, 2.0, 3.0])
    plan = plan_junctions(xyz, new, 1.6, [_seg(0, 1, 7, 0, 1, k=1.25)], arc)
    piece = place_piece(xyz, plan, 0, arc[7], "auto", derivative_orders(xyz))
    corr = ErrorCorrection()
    job = _job(xyz, plan, [piece], corr)
    # the library's pairs are the model's own: E = 0 to rounding
    assert np.abs(corr.error_path(job)).max() < 1e-9
    u, note = corr(job)
    # the model inverse without the sampling zeros' band (E is 1e-12: rounding)
    np.testing.assert_allclose(u, band_limited_inverse(xyz, new - new[0]), atol=1e-6)
    assert "model-error correction" in note


class _Halve:
    """A correction that halves the spliced input: checks the protocol's plumbing."""

    name = "halve"
    keeps_stored = False

    def __init__(self):
        self.calls = 0

    def piece_term(self, machine, piece, n):
        self.calls += 1
        return None

    def __call__(self, job):
        assert job.terms == (None,) and job.y_d.shape == job.spliced.shape
        return job.spliced / 2, "halved"


def test_splice_runs_any_correction_that_follows_the_protocol(xyz, arc):
    pa = arc[7].points
    corr = _Halve()
    res = splice(xyz, pa, 2.0, [_seg(0, 1, 7, 0, 1)], arc, correction=corr)
    assert corr.calls == 1 and res.correction == "halve" and "halved" in res.notes
    np.testing.assert_array_equal(res.u, arc[7].signal / 2)
    np.testing.assert_array_equal(res.spliced, arc[7].signal)


def test_splice_refuses_what_is_not_a_correction(xyz, arc):
    pa = arc[7].points
    with pytest.raises(InputError, match="correction: expected a Correction .* got str"):
        splice(xyz, pa, 2.0, [_seg(0, 1, 7, 0, 1)], arc, correction="input")
