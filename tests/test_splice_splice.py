"""Splice: pieces from rest, windows, transition bands, unmatched segments, exact length."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from primlib import InputError
from primlib.match import Segment
from primlib.plant import Machine, invert
from primlib.splice import (
    StoredSignal,
    band_limit,
    band_limited_inverse,
    continuous_output,
    splice,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "machines"


@pytest.fixture(scope="module")
def xyz():
    return Machine.from_json(DATA / "xyz.json")


def _minjerk(s):
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _arc(T, dt):
    t = np.arange(round(T / dt) + 1) * dt
    s = _minjerk(t / T)
    return np.stack([5 - 5 * np.cos(np.pi * s), 5 * np.sin(np.pi * s), 2 * s], 1)


def _wave(T, dt):
    t = np.arange(round(T / dt) + 1) * dt
    s = _minjerk(t / T)
    return np.stack([8 * s, 2 * np.sin(2 * np.pi * s), -s], 1)


def _rot_z(th):
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


@pytest.fixture(scope="module")
def stored(xyz):
    pa = _arc(2.0, xyz.dt) + np.array([1.0, 2.0, 3.0])
    pb = _wave(1.5, xyz.dt)
    return {
        7: StoredSignal(invert(xyz, pa - pa[0]), pa, 2.0, "arc"),
        9: StoredSignal(invert(xyz, pb - pb[0]), pb, 1.5, "wave"),
    }


def _seg(start, end, pid, ps, pe, rot, c, k):
    return Segment(start, end, pid, None, ps, pe, rot, np.asarray(c, float), k, 0.0)


def test_single_piece_rotated_time_scaled_is_exact(xyz, stored):
    # the new path is the arc run in 1.6 s instead of 2 s, rotated and moved: the spliced
    # input makes the nominal model produce the stored output at 1.25x speed, rotated
    R, c = _rot_z(0.6), np.array([0.5, -1.0, 2.0])
    pa = stored[7].points
    new = (_arc(1.6, xyz.dt) + np.array([1.0, 2.0, 3.0])) @ R.T + c
    seg = _seg(0, 1, 7, 0, 1, R, c, 2.0 / 1.6)
    res = splice(xyz, new, 1.6, [seg], stored)
    assert res.u.shape == new.shape
    assert res.methods == ("model",)
    assert res.correction == "error"
    # the transformed piece before the correction
    t = np.arange(new.shape[0]) * xyz.dt
    target = continuous_output(xyz, stored[7].signal, 1.25 * t) @ R.T
    np.testing.assert_allclose(xyz.simulate(res.spliced), target, atol=1e-9 * np.abs(pa).max())
    # with the residual correction (default) the model follows the new path itself at the
    # samples, not the stored ZOH output between the stored samples — up to the path's own
    # content in the sampling zeros' near-Nyquist band, which the correction leaves out
    y_d = new - new[0]
    own = np.abs(band_limit(xyz, y_d) - y_d).max()
    # (a smooth path: next to nothing, 2.5e-7 from the minimum-jerk law's jerk steps at its
    # ends, ~ jerk dt^3 / 100)
    assert own < 1e-7 * np.abs(pa).max()
    y = xyz.simulate(res.u)
    np.testing.assert_allclose(y, y_d, atol=2 * own + 1e-9 * np.abs(pa).max())


def test_path_that_is_a_stored_primitive_returns_its_signal(xyz, stored):
    pa = stored[7].points
    res = splice(xyz, pa, 2.0, [_seg(0, 1, 7, 0, 1, np.eye(3), [0, 0, 0], 1.0)], stored)
    np.testing.assert_array_equal(res.u, stored[7].signal)
    assert res.methods == ("identity",)


def test_window_of_a_primitive_keeps_its_state(xyz, stored):
    # a new path that is the middle 40 %..100 % of the arc: the piece is transformed from the
    # primitive's rest and cut, so the machine, started at the window's state, follows it
    pa, u = stored[7].points, stored[7].signal
    i0 = 160  # 0.8 s = v 0.4
    new = pa[i0:]
    seg = _seg(0, 1, 7, 0.4, 1.0, np.eye(3), [0, 0, 0], 1.0)
    # (the new path starts moving: from rest the machine cannot follow it, so the residual
    # correction adds a start impulse; the cut alone, before it, is tested)
    res = splice(xyz, new, 1.2, [seg], stored)
    np.testing.assert_array_equal(res.spliced, u[i0:])


def test_two_pieces_with_a_rest_junction(xyz, stored):
    R, c1 = _rot_z(-0.4), np.array([0.5, -1.0, 2.0])
    p1 = (_arc(1.6, xyz.dt) + np.array([1.0, 2.0, 3.0])) @ R.T + c1
    wave = _wave(2.5, xyz.dt)
    c2 = p1[-1] - wave[0]
    p2 = wave + c2
    path = np.vstack([p1, p2[1:]])
    T = (path.shape[0] - 1) * xyz.dt
    j = 1.6 / T
    segs = [_seg(0, j, 7, 0, 1, R, c1, 2.0 / 1.6), _seg(j, 1, 9, 0, 1, np.eye(3), c2, 0.6)]
    res = splice(xyz, path, T, segs, stored, band=0.04)
    assert res.u.shape == path.shape
    assert len(res.bands) == 1 and res.bands[0].kind == "continuous"
    # rest-to-rest primitives: nothing to blend, the band has no width
    assert res.bands[0].end - res.bands[0].start == 0.0
    assert np.all(res.sample_segment[: round(1.6 / xyz.dt)] == 0)
    assert np.all(res.sample_segment[round(1.6 / xyz.dt) :] == 1)
    err = np.abs(xyz.simulate(res.u) - (path - path[0])).max()
    # exact up to the stored outputs' deviation from the analytic paths between samples
    # and the residual velocity they leave at the junction (the ZOH input's last samples
    # are not exactly 0): measured 1.5e-4, ~1e-5 of the path's 15-unit extent
    assert err < 3e-4


def _two_windows(xyz, stored, shift):
    """Arc 0..0.5 then arc 0.5..1 as separate pieces; ``shift`` moves the second piece."""
    pa = stored[7].points
    new = pa.copy()
    segs = [
        _seg(0, 0.5, 7, 0, 0.5, np.eye(3), [0, 0, 0], 1.0),
        _seg(0.5, 1, 7, 0.5, 1.0, np.eye(3), shift, 1.0),
    ]
    return new, segs


@pytest.mark.parametrize(("sign", "kind"), [(0.0, "continuous"), (-1.0, "overlap"), (1.0, "gap")])
def test_junction_cases(xyz, stored, sign, kind):
    pa = stored[7].points
    v = (pa[201] - pa[199]) / (2 * xyz.dt)  # velocity at the junction (t = 1 s)
    shift = sign * 0.05 * v  # the second piece starts 50 ms later (gap) or earlier (overlap)
    if kind == "continuous":
        # a tenth of a sample along the path: continuous, but not the same window (which
        # the splice would join into one piece)
        shift = 0.1 * xyz.dt * v
    new, segs = _two_windows(xyz, stored, shift)
    res = splice(xyz, new, 2.0, segs, stored, band=0.04)
    b = res.bands[0]
    assert b.kind == kind
    if kind == "continuous":
        assert b.end - b.start == pytest.approx(0.04)
        # the band blends two exact continuations of the same motion: still the signal
        np.testing.assert_allclose(res.spliced, stored[7].signal, atol=1e-9)
    else:
        assert abs(b.delta) == pytest.approx(0.05, rel=0.02)
        assert b.end - b.start >= 2 * 0.05


def test_consecutive_windows_of_one_primitive_are_one_piece(xyz, stored):
    new, segs = _two_windows(xyz, stored, np.zeros(3))
    res = splice(xyz, new, 2.0, segs, stored, band=0.04)
    assert res.bands == () and res.methods == ("identity",)
    np.testing.assert_array_equal(res.u, stored[7].signal)


def test_unmatched_segment_gets_the_nominal_inverse(xyz, stored):
    pa = stored[7].points
    segs = [
        _seg(0, 0.5, 7, 0, 0.5, np.eye(3), [0, 0, 0], 1.0),
        Segment(0.5, 1.0, None, None, np.nan, np.nan, np.eye(3), np.zeros(3), np.nan, np.nan),
    ]
    res = splice(xyz, pa, 2.0, segs, stored, band=0.04)
    assert res.methods == ("identity", "inverse")
    assert "unmatched" in res.sources[1] and "nominal-model inverse" in res.sources[1]
    assert any("unmatched" in note for note in res.notes)
    inv = band_limited_inverse(xyz, pa - pa[0])
    tail = res.sample_segment == 1
    after = np.arange(pa.shape[0]) * xyz.dt > 1.0 + 0.02 + 1e-9
    # (with the default correction: the model inverse of the whole path there, to rounding,
    # without the sampling zeros' near-Nyquist band)
    sel = tail & after
    np.testing.assert_allclose(res.u[sel], inv[sel], atol=1e-9 * np.abs(inv).max())


def test_exact_length_for_a_duration_off_the_grid(xyz, stored):
    T = 2.0 + 0.0031  # not a multiple of dt
    n = round(T / xyz.dt) + 1
    pts = np.zeros((n, 3))
    pts[:, 0] = np.linspace(0, 1, n)
    seg = Segment(0, 1, None, None, np.nan, np.nan, np.eye(3), np.zeros(3), np.nan, np.nan)
    assert splice(xyz, pts, T, [seg], stored).u.shape == (n, 3)


def test_splice_errors(xyz, stored):
    pa = stored[7].points
    seg = _seg(0, 1, 7, 0, 1, np.eye(3), [0, 0, 0], 1.0)
    with pytest.raises(InputError, match=r"points: expected shape \(401, 3\)"):
        splice(xyz, pa[:-1], 2.0, [seg], stored)
    with pytest.raises(InputError, match="segments: expected contiguous segments from 0 to 1"):
        splice(xyz, pa, 2.0, [_seg(0, 0.5, 7, 0, 0.5, np.eye(3), [0, 0, 0], 1.0)], stored)
    with pytest.raises(InputError, match="band: expected a width >= 0 s, got -1"):
        splice(xyz, pa, 2.0, [seg], stored, band=-1)
    with pytest.raises(InputError, match="method: expected one of auto, model, direct"):
        splice(xyz, pa, 2.0, [seg], stored, method="fast")
    with pytest.raises(InputError, match="segments: expected at least one segment"):
        splice(xyz, pa, 2.0, [], stored)
