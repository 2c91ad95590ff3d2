"""Index windows at a primitive's end (``_ends``, ``Gates.over``, ``ArcQuery.at_starts``):
a window may run past its primitive's last point by as much as the gates allow, and is then
scored ending there, not on the next primitive's points."""

from pathlib import Path

import numpy as np
import pytest
from _reference_search import reference_segment_path
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation
from test_match_gates import _query

from primlib.match import BankIndex, segment_path
from primlib.match._gates import Gates
from primlib.nurbs import Trajectory
from primlib.store import Bank

ROOT = Path(__file__).resolve().parents[1]
DT = 0.005


def test_gates_split_the_windows_with_arc_left_into_inside_and_over():
    aq = _query()
    gates = Gates.of(aq, 0.05)
    n, lv = aq.n_windows, aq.level
    m = np.arange(n)
    left_ok = np.asarray(lv.left)[:n] >= gates.need
    inside = lv.prim[m + aq.span - 1] == lv.prim[m]
    np.testing.assert_array_equal(gates.valid((0, n)), left_ok & inside)
    over = np.zeros(lv.prim.size, dtype=bool)
    over[gates.over] = True
    np.testing.assert_array_equal(over[:n], left_ok & ~inside)
    assert gates.over.size > 0  # the helix's last windows run past its last point
    # past the last whole window: the line's (the bank's last primitive) that have the arc
    tail = np.arange(n, lv.prim.size)
    np.testing.assert_array_equal(over[n:], np.asarray(lv.left)[tail] >= gates.need)
    assert over[n:].any()


def test_at_starts_takes_the_level_points_inside_and_ends_at_the_last_point_past_it():
    aq = _query()
    lv, k, dil = aq.level, aq.k, aq.dil
    need = Gates.of(aq, 0.05).need
    inside = np.array([0, 5, 17])
    pts, x, ok = aq.at_starts(inside.astype(float), need)
    idx = inside[:, None] + dil * np.arange(k)
    np.testing.assert_array_equal(pts, lv.pts[idx])
    np.testing.assert_array_equal(x, lv.x[idx])
    assert ok.all()
    over = Gates.of(aq, 0.05).over
    over = over[lv.prim[over] == 0]  # the helix's
    pts, x, ok = aq.at_starts(over.astype(float), need)
    last = int(lv.start[1]) - 1  # the helix's last level point
    assert ok.all()
    np.testing.assert_allclose(pts[:, -1], np.broadcast_to(lv.pts[last], pts[:, -1].shape))
    np.testing.assert_allclose(x[:, -1], lv.x[last])
    gap = np.diff(x, axis=1)
    assert np.all(gap > 0)  # inside the helix: its sample indices only grow
    # evenly spaced level positions: k points from the start to the last point
    pos = over[:, None] + (last - over)[:, None] * np.linspace(0, 1, k)
    i0 = np.minimum(np.floor(pos).astype(int), last - 1)
    want = lv.x[i0] + (pos - i0) * (lv.x[i0 + 1] - lv.x[i0])
    np.testing.assert_allclose(x, want, rtol=0, atol=1e-9)
    # too little arc left, or a start before the bank's first point: not a window
    _, _, ok = aq.at_starts(np.array([last - 2.0, -0.25]), need)
    assert not ok.any()


def _bundled(last: str | None = None) -> BankIndex:
    """The bundled library, with primitive ``last`` moved to the end of the bank."""
    files = sorted(f for f in (ROOT / "data" / "library").glob("*.csv")
                   if not f.name.endswith(".signal.csv"))  # fmt: skip
    files.sort(key=lambda f: f.stem == last)
    pieces = [Trajectory.from_csv(f).sample(DT) for f in files]
    return BankIndex(Bank.from_samples(pieces, DT, names=[f.stem for f in files]))


@pytest.mark.parametrize("last", [None, "line-diagonal"])
@pytest.mark.parametrize("seed", [0, 2, 5])
def test_a_whole_noisy_line_is_one_segment_as_the_grid_finds_it(seed, last):
    # a whole stored line, rotated, time-scaled, with white noise of 1 % of its extent:
    # smoothed, its arc is 1-2 % longer than the stored line's, so its windows run past the
    # line's last point. Scored on the next primitive's points they matched nothing, and
    # the path came out in two pieces of other primitives where the exhaustive grid
    # (benchmarks/_reference_search.py) matches the line whole. Last in the bank, its
    # windows past the last whole window were not windows at all.
    bank = _bundled(last)
    row = list(bank.names).index("line-diagonal")
    rng = np.random.default_rng(seed)
    p = bank.points[bank.offsets[row] : bank.offsets[row + 1]]
    k = np.exp(rng.uniform(np.log(0.5), np.log(2)))
    n = int(round((p.shape[0] - 1) / k)) + 1
    q = CubicSpline(np.arange(p.shape[0]), p)(np.linspace(0, p.shape[0] - 1, n))
    q = q @ Rotation.random(random_state=seed).as_matrix().T + rng.normal(size=3) * 10
    sigma = 0.01 * float(np.ptp(q, axis=0).max())
    q = q + rng.normal(scale=sigma, size=q.shape)
    eps = 2 * sigma * np.sqrt(3)
    segs, _ = segment_path(bank, q, DT, eps)
    ref, _ = reference_segment_path(bank, q, DT, eps, "grid")
    assert len(ref) == 1 and ref[0].rmsd < eps
    assert [(s.end, s.primitive) for s in segs] == [(1.0, ref[0].primitive)]
    assert segs[0].rmsd == pytest.approx(ref[0].rmsd, rel=1e-6)
