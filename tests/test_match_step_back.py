"""The step back from a failing first probe (primlib.match._step_back): the halving's
shortest probe made first on a noisy path's first start, the answer the halving's."""

import numpy as np
import pytest

from primlib.match import BankIndex, segment_path
from primlib.match import _step_back as step_back
from primlib.match._rough import block_roughness, query_roughness
from primlib.match._segment import _Segmenter
from primlib.store import Bank

DT = 0.01


def _library(k: int = 6, n: int = 300, seed: int = 3) -> BankIndex:
    """k smooth random curves (sums of 6 harmonics), n samples each, ~50 units wide."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, n)[:, None, None]
    f = np.arange(1, 7)[None, :, None]
    pieces = []
    for _ in range(k):
        amp = rng.normal(size=(1, 6, 3)) * 50 / f**1.5
        ph = rng.uniform(0, 2 * np.pi, size=(1, 6, 3))
        pieces.append((amp * np.sin(2 * np.pi * f * t + ph)).sum(axis=1))
    return BankIndex(Bank.from_samples(pieces, DT, ids=np.arange(100, 100 + k)))


def _noisy(bank: BankIndex, sigma: float, seed: int = 5) -> np.ndarray:
    """Stored primitive 2's samples 40-260 with white noise of ``sigma`` per axis."""
    rng = np.random.default_rng(seed)
    clean = bank.points_of(2)[40:261]
    return clean + rng.normal(scale=sigma, size=clean.shape)


def _searched(monkeypatch) -> list[tuple[int, int]]:
    """(start, steps) of every whole search made from here on (probes not rejected)."""
    out: list[tuple[int, int]] = []
    probe = _Segmenter.probe

    def logged(self, a, b):
        before = self.seeder.stats.queries
        found = probe(self, a, b)
        if self.seeder.stats.queries > before:
            n = self.path.n - 1
            out.append((round(a * n), round((b - a) * n)))
        return found

    monkeypatch.setattr(_Segmenter, "probe", logged)
    return out


def _as_tuples(segs) -> list[str]:
    """Each segment's cuts and primitive piece, as text (an unmatched one's nan compares)."""
    return [repr((s.start, s.end, s.primitive, s.primitive_start, s.primitive_end)) for s in segs]


@pytest.mark.parametrize(
    ("length", "sig", "least", "floor"),
    [(312, 1, 7, 9), (836, 1, 7, 13), (459, 1, 7, 7), (14, 1, 7, 7), (7, 1, 7, 7),
     (6, 1, 7, None), (100, 30, 7, 30), (100, 1, 20, 25)],
)  # fmt: skip
def test_the_halving_floor_is_the_last_length_it_searches(length, sig, least, floor):
    assert step_back.halving_floor(length, sig, least) == floor


def test_a_noisy_path_nothing_matches_leaves_its_first_start_after_two_searches(monkeypatch):
    bank = _library()
    sigma = 0.05
    pts = _noisy(bank, sigma)
    eps = sigma * np.sqrt(3) / 2  # half the noise's own RMSD: nothing is within it
    # every piece searched, however noisy (the skip of noisy starts: the test below)
    monkeypatch.setattr(step_back, "noisy_start", lambda *args: False)
    searched = _searched(monkeypatch)
    segs, info = segment_path(bank, pts, DT, eps)
    first = [s for s in searched if s[0] == 0]
    assert [s[1] for s in first] == [len(pts) - 1, step_back.halving_floor(len(pts) - 1, 1, 7)]
    # the same segmentation as the halving in its own order, with fewer searches
    monkeypatch.setattr(step_back, "_rough", lambda *args: False)
    searched.clear()
    old, old_info = segment_path(bank, pts, DT, eps)
    assert _as_tuples(segs) == _as_tuples(old)
    assert len([s for s in searched if s[0] == 0]) >= len(first) + 3
    assert info["queries"] <= old_info["queries"] - 3


def test_a_shortest_probe_out_of_turn_that_matches_changes_nothing(monkeypatch):
    # forced on a path that matches: the halving goes on, and reaching the shortest probe
    # takes its result (one search more at most, the same segments)
    bank = _library()
    pts = _noisy(bank, 0.05)
    eps = 0.05 * np.sqrt(3) * 2
    searched = _searched(monkeypatch)
    ref, ref_info = segment_path(bank, pts[::-1].copy(), DT, eps)
    n_ref = len(searched)
    monkeypatch.setattr(step_back, "_rough", lambda *args: True)
    searched.clear()
    segs, info = segment_path(bank, pts[::-1].copy(), DT, eps)
    assert _as_tuples(segs) == _as_tuples(ref)
    assert n_ref <= len(searched) <= n_ref + 1
    floor = step_back.halving_floor(len(pts) - 1, 1, 7)
    assert searched.count((0, floor)) <= 1  # never searched twice


def test_the_shortest_probe_made_out_of_turn_is_not_searched_again(monkeypatch):
    # every probe between the whole path and the shortest made to fail: the halving reaches
    # the shortest, which matched out of turn, and takes that result
    bank = _library()
    pts = _noisy(bank, 0.05)[::-1].copy()
    eps = 0.05 * np.sqrt(3) * 2
    last = len(pts) - 1
    floor = step_back.halving_floor(last, 1, 7)
    calls: list[int] = []
    probe = _Segmenter.probe

    def failing_between(self, a, b):
        steps = round((b - a) * last)
        if a == 0 and floor < steps < last:
            self.probes += 1
            return None, np.inf
        if a == 0:
            calls.append(steps)
        return probe(self, a, b)

    monkeypatch.setattr(_Segmenter, "probe", failing_between)
    monkeypatch.setattr(step_back, "_rough", lambda *args: False)
    ref, _ = segment_path(bank, pts, DT, eps)
    assert calls.count(floor) == 1
    calls.clear()
    monkeypatch.setattr(step_back, "_rough", lambda *args: True)
    segs, _ = segment_path(bank, pts, DT, eps)
    assert calls[:2] == [last, floor] and calls.count(floor) == 1
    assert _as_tuples(segs) == _as_tuples(ref)


def test_a_noisy_paths_unmatched_stretch_skips_its_noisy_starts(monkeypatch):
    # the first start's shortest probe and the doubling's starts whose pieces are noisier
    # than eps: unmatched, unsearched, and the same segmentation as searching them
    bank = _library()
    sigma = 0.05
    pts = _noisy(bank, sigma)
    eps = sigma * np.sqrt(3) / 4
    searched = _searched(monkeypatch)
    segs, info = segment_path(bank, pts, DT, eps)
    assert info["noisy_starts"] >= 3
    assert all(s.primitive is None for s in segs)
    starts = {s[0] for s in searched}
    assert [s[1] for s in searched if s[0] == 0] == [len(pts) - 1]  # not the shortest
    monkeypatch.setattr(step_back, "noisy_start", lambda *args: False)
    searched.clear()
    ref, ref_info = segment_path(bank, pts, DT, eps)
    assert _as_tuples(segs) == _as_tuples(ref)
    assert ref_info["noisy_starts"] == 0
    # every start but the first skipped whole (the first searched the whole path)
    assert len({s[0] for s in searched} - starts) == info["noisy_starts"] - 1
    assert info["queries"] <= ref_info["queries"] - info["noisy_starts"]


@pytest.mark.parametrize("sigma", [0.0, 0.05])
def test_a_path_within_eps_of_cubics_at_its_shortest_pieces_never_skips_a_start(sigma):
    # clean, or noisy at an eps the noise's cubic residual stays below (~0.7x its RMS): the
    # rule never fires, whatever matches
    bank = _library()
    pts = _noisy(bank, sigma) if sigma else bank.points_of(2)[40:261] + 0.0
    t = np.linspace(0.0, 1.0, pts.shape[0])[:, None]
    pts = pts + 5.0 * np.sin(2 * np.pi * t * np.array([1.0, 2.0, 3.0]))  # not a stored piece
    eps = max(sigma, 0.01) * np.sqrt(3) * 2
    segs, info = segment_path(bank, pts, DT, eps)
    assert info["noisy_starts"] == 0
    if sigma == 0.0:
        assert any(s.primitive is None for s in segs)  # an unmatched stretch was searched
    else:  # the noise's cubic residual over 8 samples: σ·√(d·(8 − 4)), half of eps·√8
        blocks = pts[: 27 * 8].reshape(27, 8, 3)
        rough = np.median(block_roughness(blocks))
        assert rough == pytest.approx(sigma * np.sqrt(3 * 4), rel=0.3)
        assert rough < 0.6 * eps * np.sqrt(8)


def test_block_roughness_is_each_pieces_distance_from_its_least_squares_cubic():
    rng = np.random.default_rng(4)
    blocks = rng.normal(size=(7, 8, 3)) * 10.0 + rng.normal(size=(7, 1, 3)) * 100.0
    got = block_roughness(blocks)
    cubic = np.vander(np.arange(8.0), 4)
    want = [np.linalg.norm(b - cubic @ np.linalg.lstsq(cubic, b, rcond=None)[0]) for b in blocks]
    # below by the round-off margin, 1e-9 of the largest coordinate per √(K·d) samples
    margin = 1e-9 * np.abs(blocks).max(axis=(1, 2)) * np.sqrt(8 * 3)
    np.testing.assert_allclose(got + margin, want, rtol=1e-12)
    assert [query_roughness(b) for b in blocks] == got.tolist()
    assert block_roughness(blocks[:, :4]).tolist() == [0.0] * 7


def test_a_start_is_noisy_only_when_every_prefix_it_could_end_at_is():
    # a probe of 12 steps whose own piece is rough, with an 8-step prefix on a line: the
    # failed search's seeds shrunk there could still match, so the start is searched
    from types import SimpleNamespace

    from primlib.match._options import PathPiece

    rng = np.random.default_rng(8)
    noise = rng.normal(scale=1.0, size=(400, 3))
    line = np.linspace(0.0, 1.0, 9)[:, None] * np.array([3.0, 1.0, 2.0])

    def seg(points):
        return SimpleNamespace(path=PathPiece(points, 4.0), eps=0.2, least=7, noisy={})

    assert step_back.noisy_start(seg(noise), 0, 12)
    assert step_back.noisy_start(seg(noise), 5, 7)
    bent = noise.copy()
    bent[:9] = line
    assert not step_back.noisy_start(seg(bent), 0, 12)
    assert step_back.noisy_start(seg(bent), 20, 12)
    # a path whose pieces are within eps of their cubics by the median: never
    calm = noise * 0.01
    calm[:13] = noise[:13]
    assert not step_back.noisy_start(seg(calm), 0, 12)
    assert not step_back.noisy_start(seg(noise), 395, 7)  # runs past the path's end
