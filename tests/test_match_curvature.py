"""The grid's curvature bound (``_curvature``): a piece that stops dead or sets off at once
cannot be followed by a smooth primitive played slowly, so the grid leaves those windows out;
every window left out is farther than eps at the path's samples, and the grid's seeds are
those of every window it keeps scored."""

import math

import numpy as np
import pytest
from _reference_search import every_window_seeds
from match_helpers import every_window_score, smooth_walk

from primlib.match import BankIndex, kabsch
from primlib.match._curvature import Curvature, critical, lag_turns, minus
from primlib.match._grid import GridSearch
from primlib.match._grid_blocks import Scale
from primlib.match._interp import cubic_at
from primlib.match._options import PathPiece, SearchOptions
from primlib.store import Bank

DT = 0.01


def _bank(rng) -> BankIndex:
    """Smooth primitives of several speeds; some start and end moving (their clamped ends'
    ghosts are kinks a whole sample step wide), one is a polyline with sharp corners."""
    prims = [smooth_walk(rng, int(rng.integers(150, 400)), rng.uniform(0.02, 0.3))
             for _ in range(6)]  # fmt: skip
    corners = np.repeat(np.cumsum(rng.normal(size=(6, 3)), axis=0), 20, axis=0)
    prims.append(corners + np.linspace(0, 1, corners.shape[0])[:, None])  # a kink each 20
    return BankIndex(Bank.from_samples(prims, DT))


def _stop(rng, speed: float, moving: int, still: int, start: bool = False) -> np.ndarray:
    """``moving`` samples of straight motion at ``speed`` a sample, then ``still`` at rest
    (or the reverse, with ``start``): a machine that stops dead (or sets off at once)."""
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    go = np.arange(moving)[:, None] * speed * d
    pts = np.concatenate([go, np.repeat(go[-1:], still, axis=0)])
    return (pts[::-1] if start else pts) + rng.normal(size=3)


def test_the_interpolants_second_difference_is_below_three_curvatures_times_its_step():
    # |c(x − δ) − 2c(x) + c(x + δ)| <= 3·D2·δ² with D2 the largest row curvature it reads
    # (the ghosts' at a primitive's ends included): the stored side of the bound
    rng = np.random.default_rng(3)
    bank = _bank(rng)
    curv = Curvature(bank.points, bank.offsets, float(np.abs(bank.points).max()))
    for p in range(bank.k):
        n, o = int(bank.counts[p]), int(bank.offsets[p])
        delta = rng.uniform(0.05, 4.0, 400)
        x = rng.uniform(delta, n - 1 - delta)
        pts = cubic_at(bank.points, o, n, np.concatenate([x - delta, x, x + delta]))
        dd = np.linalg.norm(pts[:400] - 2 * pts[400:800] + pts[800:], axis=1)
        lo = np.floor(x - delta).astype(int) + o  # the rows (centres) the three points read
        hi = np.minimum(np.ceil(x + delta).astype(int), n - 1) + o
        d2 = np.array(
            [curv.block[r0 // 16 : r1 // 16 + 1].max() for r0, r1 in zip(lo, hi, strict=True)]
        )
        assert np.all(dd <= 3.0 * d2 * delta**2 * (1 + 1e-9) + 1e-12)


def _cells_out(grid: GridSearch, path: PathPiece, a: float, b: float, eps: float):
    """Per scale, the windows its ``out`` holds (primitive, start) and the scale."""
    for sc in grid._scales(path, a, b, eps):
        if sc.out is not None:
            m = np.concatenate(
                [np.arange(f, f + n) for f, n in zip(sc.out.m0, sc.out.n_start, strict=True)]
            )
            yield sc, np.repeat(sc.out.prim, sc.out.n_start), m


@pytest.mark.parametrize("start", [False, True])
@pytest.mark.parametrize("rotation", ["full", "none"])
def test_no_window_left_out_is_within_eps_at_the_paths_samples(start, rotation):
    # any continuous window of a cell left out (start within h of the grid's, lasting up to
    # the cell's longest) has a Kabsch RMSD of eps or more against the piece's own samples:
    # so no match is lost. The piece moves at 6·eps a sample, then stops dead
    rng = np.random.default_rng(11 if start else 12)
    bank = _bank(rng)
    eps = 0.01
    pts = _stop(rng, 6 * eps, 5, 9, start)
    path = PathPiece(pts, (pts.shape[0] - 1) * DT)
    opts = SearchOptions(rotation=rotation)
    grid = GridSearch(bank, opts)
    spread = math.sqrt(opts.scale_ratio)
    k = pts.shape[0]
    checked = 0
    for sc, prim, m in _cells_out(grid, path, 0.0, 1.0, eps):
        pick = rng.choice(m.size, min(m.size, 60), replace=False)
        for p, mm in zip(prim[pick], m[pick], strict=True):
            n = int(bank.counts[p])
            dur = sc.dur * rng.uniform(1.0 / spread, spread)
            x0 = np.clip(mm * sc.h + rng.uniform(-sc.h, sc.h), 0.0, n - 1 - dur)
            w = cubic_at(bank.points, bank.offsets[p], n, np.linspace(x0, x0 + dur, k))
            assert kabsch(w, pts, rotation=rotation).rmsd >= eps
            checked += 1
    assert checked > 300  # the bound leaves windows out here (it is not idle)


def test_windows_near_a_primitives_moving_end_stay():
    # the clamped ends read a ghost sample: a primitive that starts moving has a kink there
    # as sharp as a sudden start, so the windows at its start stay in the search
    rng = np.random.default_rng(5)
    line = np.arange(200)[:, None] * np.array([0.06, 0.0, 0.0])  # moving from its first sample
    bank = BankIndex(Bank.from_samples([line, smooth_walk(rng, 300, 0.05)], DT))
    pts = np.concatenate([np.zeros((9, 3)), line[1:6]])  # at rest, then off at 0.06 a sample
    path = PathPiece(pts, (pts.shape[0] - 1) * DT)
    grid = GridSearch(bank, SearchOptions(rotation="none"))
    outs = list(_cells_out(grid, path, 0.0, 1.0, 0.01))
    assert outs  # most of the bank is out
    for sc, prim, m in outs:
        assert not np.any((prim == 0) & (m * sc.h < 1.0 + sc.h))  # the line's start stays


@pytest.mark.parametrize("few", [0, None])
@pytest.mark.parametrize("rotation", ["full", "none"])
def test_the_grid_returns_the_seeds_of_every_window_it_keeps(rotation, few):
    rng = np.random.default_rng(21)
    bank = _bank(rng)
    pts = _stop(rng, 0.06, 6, 12)
    path = PathPiece(pts, (pts.shape[0] - 1) * DT)
    pruned = GridSearch(bank, SearchOptions(rotation=rotation))
    if few is not None:
        pruned.few = few
    got = pruned.seeds(path, 0.0, 1.0, 0.01)
    every = GridSearch(bank, SearchOptions(rotation=rotation))
    want = every_window_seeds(every, path, 0.0, 1.0, 0.01, every_window_score(rotation, 16))
    assert [(c.prim, c.x0, c.x1) for c in got] == [(c.prim, c.x0, c.x1) for c in want]
    assert pruned.stats.windows == every.stats.windows


def test_critical_curvature_and_turns():
    # a stop from v a sample: H_m = m·v up to the samples it moved; the critical D2 is where
    # 3·D2·m²σ² leaves √(6K)·eps of it
    q = np.concatenate([np.arange(4)[:, None] * [2.0, 0, 0], np.full((8, 3), [6.0, 0, 0])])
    turns = lag_turns(q)
    np.testing.assert_allclose(turns[:3], [2.0, 4.0, 6.0], rtol=1e-9)
    k, eps, sigma = q.shape[0], 0.1, 0.5
    need = math.sqrt(6 * k) * eps
    want = max((turns[m - 1] - need) / (3 * m * m * sigma**2) for m in range(1, turns.size + 1))
    assert critical(turns, sigma, k, eps) == pytest.approx(want, rel=1e-6)
    assert critical(turns, sigma, k, 10.0) < 0  # a tolerance wider than the turn: none out
    assert lag_turns(np.zeros((2, 3))).size == 0


def test_minus_is_the_set_difference_of_runs():
    rng = np.random.default_rng(4)
    for _ in range(50):
        prim = np.sort(rng.choice(20, 6, replace=False))
        n = rng.integers(0, 30, prim.size)
        whole = Scale(prim, n, 5.0, 0.5, 0.3)
        every = {(p, m) for p, c in zip(prim, n, strict=True) for m in range(c)}

        def runs(keep):
            p = np.array([x[0] for x in sorted(keep)], dtype=int)
            m = np.array([x[1] for x in sorted(keep)], dtype=int)
            return Scale(p, np.ones(p.size, dtype=int), 5.0, 0.5, 0.3, m) if p.size else None

        part = runs({x for x in every if rng.random() < 0.7})
        out = runs({x for x in every if rng.random() < 0.4})
        got = minus(part, out, whole)
        have = (
            set()
            if got is None
            else {
                (p, m)
                for p, f, c in zip(got.prim, got.m0, got.n_start, strict=True)
                for m in range(f, f + c)
            }
        )
        want = set() if part is None else set(zip(part.prim, part.m0, strict=True))
        want -= set() if out is None else set(zip(out.prim, out.m0, strict=True))
        assert have == want
    assert minus(whole, None, whole) is whole
