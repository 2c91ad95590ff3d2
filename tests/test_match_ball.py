"""The ball query of rotation none (primlib.match._ball): its bound on random windows, the
windows it finds against every window scored, and the seeds with and without it."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import test_match_index_search as index_tests
from _reference_search import ScanSearch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from primlib.match import BankIndex, SearchOptions, _ball
from primlib.match._index_search import IndexSearch, _Gates
from primlib.match._options import PathPiece
from primlib.store import Bank

DT = 0.01
_harmonics = index_tests._harmonics
novel = index_tests.novel  # the same novel library (a module-scoped fixture)


def _rmsd_translation(w: np.ndarray, q: np.ndarray) -> float:
    """RMSD of w against q under the best translation alone (R = I)."""
    e = (w - w.mean(axis=0)) - (q - q.mean(axis=0))
    return math.sqrt(float((e * e).sum()) / len(w))


def _bound(pts, dil, m, k, q, sub) -> float:
    """√(sub/K)·max over the first and last ``sub`` arc samples of |f(w) − f(q)|."""
    f = _ball.descriptors(pts, dil, sub)
    f1, f2 = _ball.query_descriptors(q - q.mean(axis=0), sub)
    d1 = np.linalg.norm(f[m] - f1)
    d2 = np.linalg.norm(f[m + (k - sub) * dil] - f2)
    return math.sqrt(sub / k) * max(d1, d2)


@pytest.mark.parametrize("stride", [1, 2, 4])
@pytest.mark.parametrize("chunk", [1, 7, 64, 1 << 16])
@pytest.mark.parametrize(("dil", "sub"), [(1, 16), (2, 16), (3, 8)])
def test_the_descriptors_by_chunks_are_those_of_the_whole_level(dil, sub, chunk, stride):
    # the half sums of every sub-window at once, in the same order: the same numbers, at
    # the starts p with floor(p / dil) a multiple of the stride
    pts = np.random.default_rng(dil * sub).normal(size=(300, 3)) * 100.0
    half = sub // 2
    n = pts.shape[0] - (sub - 1) * dil
    sums = pts[: n + half * dil].copy()
    for i in range(1, half):
        sums += pts[i * dil : i * dil + n + half * dil]
    want = (sums[:n] - sums[half * dil : half * dil + n]) * (1.0 / sub)
    want = want[(np.arange(n) // dil) % stride == 0]
    got = _ball.descriptors(pts, dil, sub, stride, chunk)
    assert got.shape == want.shape and got.tobytes() == want.tobytes()
    assert _ball.descriptors(pts[: (sub - 1) * dil], dil, sub, stride, chunk).shape == (0, 3)


@pytest.mark.parametrize("sub", _ball.SUBS)
@pytest.mark.parametrize("d", [2, 3])
def test_the_bound_is_below_the_rmsd_and_close_to_it_on_some_windows(d, sub):
    rng = np.random.default_rng(5)
    ratios = []
    for _ in range(400):
        k, dil, m = int(rng.integers(sub, 32)), int(rng.integers(1, 3)), int(rng.integers(0, 6))
        pts = np.cumsum(rng.normal(size=(m + (k - 1) * dil + 8, d)), axis=0)
        w = pts[m : m + (k - 1) * dil + 1 : dil]
        # a query: the window bent smoothly (or not at all), moved anywhere
        bend = np.cumsum(rng.normal(size=w.shape), axis=0) * rng.choice([0.0, 0.05, 0.5, 2.0])
        q = w + bend + rng.normal(size=d) * 100.0
        rho = _rmsd_translation(w, q)
        lb = _bound(pts, dil, m, k, q, sub)
        assert lb <= rho * (1 + 1e-9) + 1e-9
        if rho > 1e-6:
            ratios.append(lb / rho)
    # not vacuous: a sizeable part of the RMSD on most windows
    assert np.median(ratios) > 0.3 and max(ratios) > 0.8
    # and the RMSD itself where the query is the window of ``sub`` points with each half
    # moved by its own offset: a bound even slightly too large fails here
    pts = np.cumsum(rng.normal(size=(40, d)), axis=0)
    w = pts[3 : 3 + sub]
    q = w + np.repeat(rng.normal(size=(2, d)), sub // 2, axis=0)
    np.testing.assert_allclose(_bound(pts, 1, 3, sub, q, sub), _rmsd_translation(w, q), rtol=1e-12)


def test_the_radius_is_the_gate_scaled_with_a_small_margin():
    r = _ball.radius(0.1, 25, 16, 3, 50.0)
    assert 0.1 * math.sqrt(25 / 16) < r < 0.1 * math.sqrt(25 / 16) * (1 + 1e-3)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), stride=st.sampled_from([1, 2, 3, 4]),
       sub=st.sampled_from(_ball.SUBS), d=st.sampled_from([2, 3]))  # fmt: skip
def test_the_strided_balls_hold_every_window_below_the_radius_of_a_small_level(seed, stride,
                                                                              sub, d):  # fmt: skip
    # brute force: the translation RMSD of every window of a random level against a query
    # (one of its windows bent and moved); the balls hold each one below the radius
    rng = np.random.default_rng(seed)
    dil = int(rng.integers(1, 4))
    k = int(rng.integers(sub + stride - 1, 33))
    # at least 2 windows (of one, the quantile is its own RMSD: none below it)
    pts = np.cumsum(rng.normal(size=(int(rng.integers((k - 1) * dil + 2, 400)), d)), axis=0)
    span = (k - 1) * dil + 1
    n = pts.shape[0] - span + 1
    wins = np.stack([pts[m : m + span : dil] for m in range(n)])
    q = wins[rng.integers(n)] + np.cumsum(rng.normal(size=(k, d)), axis=0) * 0.1
    q += rng.normal(size=d) * 10.0
    rho = np.array([_rmsd_translation(w, q) for w in wins])
    r = float(np.quantile(rho, rng.uniform(0.01, 0.3))) * (1 + 1e-6) + 1e-12  # some below
    tree = cKDTree(_ball.descriptors(pts, dil, sub, stride))
    coord = float(np.abs(pts).max())
    aq = SimpleNamespace(n_windows=n, k=k, qc=q - q.mean(axis=0), dil=dil)
    ws = _ball.candidates(aq, (tree, coord, stride), sub, r, n)
    below = np.flatnonzero(rho < r)
    assert below.size > 0 and np.isin(below, ws).all()
    assert np.all(np.diff(ws) > 0)  # sorted, distinct
    # and exactly the windows whose sub-windows at the stored starts are in the balls
    f, fq = _ball.descriptors(pts, dil, sub), _ball.descriptors(aq.qc, 1, sub)
    m = np.arange(n)
    j = -(m // dil) % stride  # the first ball's offset; the last's: k - sub - j', j' < stride
    j2 = k - sub - (m // dil + k - sub) % stride
    far = np.maximum(np.linalg.norm(f[m + j * dil] - fq[j], axis=1),
                     np.linalg.norm(f[m + j2 * dil] - fq[j2], axis=1))  # fmt: skip
    rad = _ball.radius(r, k, sub, d, max(coord, float(np.abs(aq.qc).max())))
    assert np.isin(np.flatnonzero(far < rad * (1 - 1e-9)), ws).all()
    assert np.all(far[ws] <= rad * (1 + 1e-9))


PIECES = [(0.0, 0.05), (0.2, 0.24), (0.5, 0.58), (0.3, 0.5), (0.7, 0.73)]


@pytest.mark.parametrize("eps", [0.05, 0.5])
@pytest.mark.parametrize("stride", [1, 2, 4])
def test_the_balls_hold_every_window_below_their_radius_and_few_others(novel, eps, stride,
                                                                      monkeypatch):  # fmt: skip
    monkeypatch.setattr(_ball, "_BUILD", 0)  # a tree at a level's first query
    monkeypatch.setattr(_ball, "STRIDE", stride)
    bank, path = novel
    found = 0
    for a, b in PIECES:
        search = IndexSearch(bank, SearchOptions(rotation="none"), chunk=256, first_batch=64)
        aq = search.arc_query(path, a, b, eps)
        sub = next(s for s in _ball.SUBS if s + stride - 1 <= aq.k)
        assert aq.n_windows > search.chunk
        gates = _Gates.of(aq, eps)
        got = _ball._tree(aq.index, aq.jb, aq.dil, sub, aq.n_windows)
        _, shape = search.score(aq, np.arange(aq.n_windows))
        for rho in (0.5 * gates.top, gates.top):
            ws = _ball.candidates(aq, got, sub, rho, aq.n_windows)
            below = np.flatnonzero(shape < rho)
            found += below.size
            assert np.isin(below, ws).all()
            assert ws.size < 0.2 * aq.n_windows  # the balls leave most windows out
            assert np.all(np.diff(ws) > 0)
    assert found > 10  # windows below the radius were there to find


@pytest.fixture(scope="module")
def copies():
    """60 near copies of one curve (each bent by its own small harmonics) and a path that
    is the curve moved: the pool fills up with close windows (one round of balls)."""
    rng = np.random.default_rng(12)
    base = _harmonics(rng, 1, 400)[0]
    bank = BankIndex(Bank.from_samples([base + 0.02 * c for c in _harmonics(rng, 60, 400)], DT))
    return bank, PathPiece(base + np.array([5.0, -3.0, 2.0]), 399 * DT)


@pytest.mark.parametrize("stride", [1, 2])
@pytest.mark.parametrize("target", [16, 8])
def test_seeds_with_the_balls_are_those_of_every_window_scored(novel, copies, target, stride,
                                                               monkeypatch):  # fmt: skip
    # pieces of 16-31 arc samples (target 16) and 8-15 (target 8: the 8-point trees; with
    # stride 2, 16 takes those too, and 8 none); on near copies the pool fills up below
    # half the gate (one round), on the novel library not
    monkeypatch.setattr(_ball, "_BUILD", 0)  # a tree at a level's first query
    monkeypatch.setattr(_ball, "STRIDE", stride)
    opts = SearchOptions(rotation="none")
    calls = []
    real = _ball.candidates
    monkeypatch.setattr(
        _ball, "candidates", lambda *x: calls.append((x[2], real(*x))) or calls[-1][1]
    )
    rounds, subs = set(), set()
    for (bank, path), eps in ((novel, 0.05), (novel, 0.5), (copies, 0.05)):
        for a, b in PIECES:
            calls.clear()
            search = IndexSearch(bank, opts, chunk=256, first_batch=64, target_points=target)
            seeds = search.seeds(path, a, b, eps)
            rounds.add(sum(ws is not None for _, ws in calls))
            subs.update(sub for sub, _ in calls)
            scan = ScanSearch(bank, opts, chunk=256, first_batch=64, target_points=target)
            assert seeds == scan.seeds(path, a, b, eps)
            with monkeypatch.context() as m:
                m.setattr(IndexSearch, "ball", False)
                plain = IndexSearch(bank, opts, chunk=256, first_batch=64, target_points=target)
                assert seeds == plain.seeds(path, a, b, eps)
    assert rounds - {0} == {1, 2} and target in subs
    assert (0 in rounds, subs) == ((False, {target}) if stride == 1 else (target == 8, {8, target}))


def test_a_level_asked_for_few_windows_in_all_is_searched_without_a_tree(monkeypatch):
    # the tree is built once the level's queries have asked for _BUILD windows in all
    rng = np.random.default_rng(13)
    bank = BankIndex(Bank.from_samples(_harmonics(rng, 20, 400), DT))
    path = PathPiece(_harmonics(rng, 1, 600)[0], 599 * DT)
    opts = SearchOptions(rotation="none")
    search = IndexSearch(bank, opts, chunk=256, first_batch=64)
    aq = search.arc_query(path, 0.2, 0.24, 0.05)
    monkeypatch.setattr(_ball, "_BUILD", 3 * aq.n_windows)
    built = []
    for _ in range(4):
        search = IndexSearch(bank, opts, chunk=256, first_batch=64)
        search.seeds(path, 0.2, 0.24, 0.05)
        key = ("ball", aq.jb, aq.dil, _ball.SUBS[0], _ball.STRIDE)
        built.append(aq.index.cache[key][1] is not None)
    assert built == [False, False, True, True]
