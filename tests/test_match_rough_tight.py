"""The tighter roughness bound (``_rough_tight``): the kernel's moments, a bound never above
the cubic one and well below it on smooth primitives, and the shortest probes of a noisy
unmatched path rejected by it with the segmentation unchanged. (That no window exceeds it:
``test_match_rough.py``, with ``tight``.)"""

import math

import numpy as np
import pytest
from match_helpers import bundled_bank

from primlib.match import BankIndex, segment_path
from primlib.match import _segment as segment_module
from primlib.match import _step_back as step_back
from primlib.match._rough import Roughness
from primlib.match._rough_tight import moment_max


def test_the_kernel_s_moments_are_those_catmull_rom_has():
    # M_i(f) = Σ_m (f − m)^i φ(f − m): 1, 0, 0 (quadratics held), max |g| = √3/18, and the
    # 4th and 5th sampled on a fine grid never above the maxima taken from the polynomial
    f = np.linspace(0.0, 1.0, 4001)
    m = np.arange(-1, 3)[:, None]
    t = np.abs(f - m)
    phi = np.where(t <= 1, 1.5 * t**3 - 2.5 * t**2 + 1, -0.5 * t**3 + 2.5 * t**2 - 4 * t + 2)
    sampled = [np.abs(((f - m) ** i * phi).sum(axis=0)).max() for i in range(6)]
    assert moment_max(0) == pytest.approx(1.0, abs=1e-9)
    assert moment_max(1) < 1e-9 and moment_max(2) < 1e-9
    assert moment_max(3) == pytest.approx(math.sqrt(3.0) / 18.0, rel=1e-9)
    for i in range(6):
        assert sampled[i] <= moment_max(i)
        assert sampled[i] >= moment_max(i) - 1e-6  # the maximum, not a loose bound


@pytest.mark.parametrize("k", [5, 8, 16])
def test_the_tight_bound_is_never_above_the_cubic_one_and_well_below_on_the_bundled_bank(k):
    index = BankIndex(bundled_bank())
    rough = Roughness(index.points, index.offsets)
    for h0, h1, coarse in rough.bins(k, 0.25, 4.0):
        tight = rough.bound(k, h0 * 1.001, h1 * 0.999, tight=True)
        assert np.all(tight <= coarse)
        # the smooth primitives (all but the rounded corner's, row 10) at least 1.5x below
        smooth = np.arange(index.k) != 10
        assert np.all(tight[smooth] * 1.5 <= coarse[smooth]), (h0, coarse / tight)


@pytest.mark.parametrize("level", [0.001, 0.01])
def test_shortest_probes_rejected_by_the_tight_bound_leave_the_segments_as_they_were(
    level, monkeypatch
):
    # issue 13's unmatched noisy queries: a stored piece with noise at a quarter of the eps
    # it needs; the start's shortest probes fail unsearched more often, the cuts the same
    bank = bundled_bank()
    plain = segment_module.rough_bounds
    runs = []
    for tight in (False, True):
        if not tight:
            monkeypatch.setattr(segment_module, "rough_bounds",
                                lambda *a, tight=False: plain(*a))  # fmt: skip
        else:
            monkeypatch.undo()
        # every start searched, as before the noisy starts were skipped (test_match_step_back)
        monkeypatch.setattr(step_back, "noisy_start", lambda *args: False)
        index = BankIndex(bank)
        noise = np.random.default_rng(11)  # the same noise for both
        out = []
        for row in (5, 10, 12):
            clean = index.points_of(row)[60:300]
            sigma = level * float(np.ptp(clean, axis=0).max())
            pts = clean + noise.normal(size=clean.shape) * sigma
            segs, info = segment_path(index, pts, 0.005, sigma * np.sqrt(3) / 4)
            out.append(([repr((s.start, s.end, s.primitive)) for s in segs], info))
        runs.append(out)
    for (segs0, info0), (segs1, info1) in zip(*runs, strict=True):
        assert segs1 == segs0
        assert info1["queries"] <= info0["queries"]
        assert info1["rejected"] >= info0["rejected"]
    assert sum(i[1]["queries"] for i in runs[1]) < sum(i[1]["queries"] for i in runs[0])


def test_the_tight_bound_is_taken_only_where_the_plain_one_leaves_a_primitive_in():
    index = BankIndex(bundled_bank())
    rough = Roughness(index.points, index.offsets)
    coarse = rough.bound(8, 2.1, 3.9)
    above = float(np.median(coarse))
    part = rough.bound(8, 2.1, 3.9, tight=True, above=above)
    ((h0, _, _),) = rough.bins(8, 2.1, 3.9)  # one bin: its bottom edge names it
    kept = rough._tight[(8, h0)]
    assert np.array_equal(np.isnan(kept), coarse <= above)  # the others never computed
    whole = Roughness(index.points, index.offsets).bound(8, 2.1, 3.9, tight=True)
    assert np.array_equal(part, np.where(coarse > above, whole, coarse))
