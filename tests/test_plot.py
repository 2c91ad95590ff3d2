"""The figures a user reads (primlib.plot), asserted through the matplotlib objects.

Regression tests of issue 12: units on every axis, the CLI's words in the legends, visible
transition bands, integer iteration ticks, segments named by primitive, equal 3-D scales.
"""

import numpy as np
import pytest

from primlib.match import Match, Segment
from primlib.pipeline import WarmStart
from primlib.plot._match import match_figure
from primlib.plot._warm import warm_start_figure
from primlib.splice import Band

DT = 0.001


def _segment(start, end, primitive, name, rmsd, d=3):
    return Segment(start, end, primitive, name, 0.0, 1.0, np.eye(d), np.zeros(d), 1.0, rmsd)


def _warm_start():
    t = np.arange(3001) * DT
    s = t / t[-1]
    points = np.c_[40 * np.sin(3 * s), 20 * (1 - np.cos(3 * s)), 5 * s]
    match = Match(
        (
            _segment(0.0, 0.4, 3, "arc-quarter", 1e-3),
            _segment(0.4, 0.8, 7, "line-x-fast", 2e-3),
            _segment(0.8, 1.0, None, None, float("nan")),
        ),
        "xyz",
        0.01,
    )
    seg = np.digitize(s, [0.4, 0.8])
    bands = (Band(1.2, 1.196, 1.204, "continuous", 0.0, 0.0), Band(2.4, 2.4, 2.4, "gap", 0, 0))
    u = np.c_[np.sin(7 * t), np.cos(5 * t), 0 * t]
    warm = WarmStart(u, t, match, bands, seg, ("a", "b", "c"), ("direct", "model", "inverse"))
    return points, t, warm


def _legend_texts(ax):
    return [x.get_text() for x in ax.get_legend().get_texts()]


def test_warm_start_figure_has_units_cli_words_visible_bands_integer_iterations():
    points, t, warm = _warm_start()
    rms = np.array([3e-3, 2e-4, 5e-5, 3e-5, 2e-5])
    fig = warm_start_figure(points, t, warm, rms, rms * 30, input_unit="V")
    path_ax, u_ax, rms_ax = fig.axes
    assert (path_ax.get_xlabel(), path_ax.get_ylabel()) == ("x (mm)", "y (mm)")
    assert (u_ax.get_xlabel(), u_ax.get_ylabel()) == ("t (s)", "u0 (V)")
    assert rms_ax.get_ylabel() == "RMS tracking error (mm)"
    words = _legend_texts(path_ax)
    assert words[:3] == [
        "1: arc-quarter (model-free eq. (20))",
        "2: line-x-fast (model-based)",
        "3 (unmatched: model inverse)",
    ]
    assert not any("direct" in w or "(model)" in w for w in words)
    # each band is drawn at least 1.2 % of the time axis wide, and the legend says so
    assert len(u_ax.patches) == 2
    for patch in u_ax.patches:  # axvspan: a rectangle in data x, axes y
        assert patch.get_width() >= 0.012 * t[-1] * (1 - 1e-9)
    assert any("transition band" in w for w in _legend_texts(u_ax))
    ticks = [v for v in rms_ax.get_xticks() if rms_ax.get_xlim()[0] <= v <= rms_ax.get_xlim()[1]]
    assert ticks and all(float(v).is_integer() for v in ticks)


def test_warm_start_figure_default_input_unit_is_input():
    points, t, warm = _warm_start()
    fig = warm_start_figure(points, t, warm, np.array([1e-3, 1e-4]))
    assert fig.axes[1].get_ylabel() == "u0 (input)"


@pytest.mark.parametrize("d", [2, 3])
def test_match_figure_names_segments_keeps_aspect_and_gives_rmsd_a_unit(d):
    t = np.linspace(0.0, 1.0, 801)
    points = np.c_[60 * t, 10 * np.sin(6 * t), 2 * t][:, :d]
    match = Match(
        (_segment(0.0, 0.5, 4, "s-wave", 2e-3, d), _segment(0.5, 1.0, None, None, np.nan, d)),
        "xyz",
        5e-3,
    )
    fig = match_figure(points, match, [points[:401], None])
    path_ax, bar = fig.axes
    assert _legend_texts(path_ax) == ["1: s-wave", "2: unmatched"]
    assert [x.get_text() for x in bar.get_xticklabels()] == ["1: s-wave", "2: unmatched"]
    assert bar.get_ylabel() == "Kabsch RMSD (mm)"
    assert _legend_texts(bar) == ["eps = 0.005 mm"]
    assert path_ax.get_xlabel() == "x (mm)"
    if d == 3:
        aspect = path_ax.get_box_aspect()
        np.testing.assert_allclose(aspect / aspect[0], np.ptp(points, 0) / np.ptp(points[:, 0]))
    else:
        assert path_ax.get_aspect() == 1.0


def test_sweep_figure_axes_and_units(tmp_path):
    from primlib.plot import plot_cee
    from primlib.reproduce import CEESweep

    feed = np.array([20.0, 40.0])
    val = {n: np.array([1.0, 2.0]) for n in ("linear", "circular", "exact")}
    sweep = CEESweep(feed / 10, feed, val, val, val, val, {"ccc_gain_V_per_mm": 1.0})
    (path,) = plot_cee(sweep, tmp_path)
    assert path.name == "cee-sweep.png" and path.stat().st_size > 1000
