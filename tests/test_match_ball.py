"""The ball query of rotation none (primlib.match._ball): its bound on random windows, the
windows it finds against every window scored, and the seeds with and without it."""

import math

import numpy as np
import pytest
from _reference_search import ScanSearch

from primlib.match import BankIndex, SearchOptions, _ball
from primlib.match._index_search import IndexSearch, _Gates
from primlib.match._options import PathPiece
from primlib.store import Bank

DT = 0.01


def _rmsd_translation(w: np.ndarray, q: np.ndarray) -> float:
    """RMSD of w against q under the best translation alone (R = I)."""
    e = (w - w.mean(axis=0)) - (q - q.mean(axis=0))
    return math.sqrt(float((e * e).sum()) / len(w))


def _bound(pts, dil, m, k, q) -> float:
    """√(16/K)·max over the first and last 16 arc samples of |f(w) − f(q)|."""
    f = _ball.descriptors(pts, dil)
    f1, f2 = _ball.query_descriptors(q - q.mean(axis=0))
    d1 = np.linalg.norm(f[m] - f1)
    d2 = np.linalg.norm(f[m + (k - _ball.SUB) * dil] - f2)
    return math.sqrt(_ball.SUB / k) * max(d1, d2)


@pytest.mark.parametrize("d", [2, 3])
def test_the_bound_is_below_the_rmsd_and_close_to_it_on_some_windows(d):
    rng = np.random.default_rng(5)
    ratios = []
    for _ in range(400):
        k, dil, m = int(rng.integers(16, 32)), int(rng.integers(1, 3)), int(rng.integers(0, 6))
        pts = np.cumsum(rng.normal(size=(m + (k - 1) * dil + 8, d)), axis=0)
        w = pts[m : m + (k - 1) * dil + 1 : dil]
        # a query: the window bent smoothly (or not at all), moved anywhere
        bend = np.cumsum(rng.normal(size=w.shape), axis=0) * rng.choice([0.0, 0.05, 0.5, 2.0])
        q = w + bend + rng.normal(size=d) * 100.0
        rho = _rmsd_translation(w, q)
        lb = _bound(pts, dil, m, k, q)
        assert lb <= rho * (1 + 1e-9) + 1e-9
        if rho > 1e-6:
            ratios.append(lb / rho)
    # not vacuous: a sizeable part of the RMSD on most windows
    assert np.median(ratios) > 0.3 and max(ratios) > 0.8
    # and the RMSD itself where the query is the window of 16 points with each half moved
    # by its own offset: a bound even slightly too large fails here
    pts = np.cumsum(rng.normal(size=(40, d)), axis=0)
    w = pts[3:19]
    q = w + np.repeat(rng.normal(size=(2, d)), 8, axis=0)
    np.testing.assert_allclose(_bound(pts, 1, 3, 16, q), _rmsd_translation(w, q), rtol=1e-12)


def test_the_radius_is_the_gate_scaled_with_a_small_margin():
    r = _ball.radius(0.1, 25, 3, 50.0)
    assert 0.1 * math.sqrt(25 / 16) < r < 0.1 * math.sqrt(25 / 16) * (1 + 1e-3)


def _harmonics(rng, k: int, n: int, d: int = 3) -> list[np.ndarray]:
    t = np.linspace(0, 1, n)[:, None, None]
    f = np.arange(1, 7)[None, :, None]
    out = []
    for _ in range(k):
        amp = rng.normal(size=(1, 6, d)) * 50 / f**1.5
        ph = rng.uniform(0, 2 * np.pi, size=(1, 6, d))
        out.append((amp * np.sin(2 * np.pi * f * t + ph)).sum(axis=1))
    return out


@pytest.fixture(scope="module")
def novel():
    rng = np.random.default_rng(11)
    bank = BankIndex(Bank.from_samples(_harmonics(rng, 40, 400), DT))
    path = _harmonics(rng, 1, 600)[0]
    return bank, PathPiece(path, (len(path) - 1) * DT)


PIECES = [(0.0, 0.05), (0.2, 0.24), (0.5, 0.58), (0.3, 0.5), (0.7, 0.73)]


@pytest.mark.parametrize("eps", [0.05, 0.5])
def test_the_balls_hold_every_window_below_the_gate_and_few_others(novel, eps):
    bank, path = novel
    found = 0
    for a, b in PIECES:
        search = IndexSearch(bank, SearchOptions(rotation="none"), chunk=256, first_batch=64)
        aq = search.arc_query(path, a, b, eps)
        assert aq.k >= _ball.SUB and aq.n_windows > search.chunk
        gates = _Gates.of(aq, eps)
        _ball.candidates(aq.index, aq, gates.top, aq.n_windows)  # a tree from the 2nd query on
        got = _ball.candidates(aq.index, aq, gates.top, aq.n_windows)
        assert got is not None
        _, shape = search.score(aq, np.arange(aq.n_windows))
        below = np.flatnonzero(shape < gates.top)
        found += below.size
        assert np.isin(below, got).all()
        assert got.size < 0.2 * aq.n_windows  # the balls leave most windows out
        assert np.all(np.diff(got) > 0)
    assert found > 10  # windows below the gate were there to find


@pytest.mark.parametrize(("a", "b"), PIECES)
def test_seeds_with_the_balls_are_those_of_every_window_scored(novel, a, b, monkeypatch):
    bank, path = novel
    opts = SearchOptions(rotation="none")
    calls = []
    real = _ball.candidates
    monkeypatch.setattr(_ball, "candidates", lambda *x: calls.append(real(*x)) or calls[-1])
    for _ in range(2):  # a level's tree is built on its second query
        seeds = IndexSearch(bank, opts, chunk=256, first_batch=64).seeds(path, a, b, 0.05)
    assert any(c is not None for c in calls)  # the balls were searched
    scan = ScanSearch(bank, opts, chunk=256, first_batch=64)
    assert seeds == scan.seeds(path, a, b, 0.05)
    monkeypatch.setattr(IndexSearch, "ball", False)
    assert seeds == IndexSearch(bank, opts, chunk=256, first_batch=64).seeds(path, a, b, 0.05)
