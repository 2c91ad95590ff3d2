"""``min_segment``: matches shorter than it join the unmatched stretch beside them; the
fraction of the path matched is reported (API, ``Match.to_dict``, ``primlib match``)."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from match_helpers import random_primitive
from scipy.spatial.transform import Rotation

import primlib as pl
from primlib.cli import main
from primlib.defaults import BAND_SAMPLES, MIN_SEGMENT_BANDS
from primlib.io import write_path_csv
from primlib.match import BankIndex, Segment, match_path, matched_pieces, segment_path
from primlib.match._segment import drop_short
from primlib.nurbs import Trajectory
from primlib.plant import Machine, invert

ROOT = Path(__file__).resolve().parents[1]
EPS = 0.05
SHORT = 31  # samples of the middle piece: 0.15 s at dt 5 ms


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """4 primitives; a path of a long piece, a short one (SHORT samples), a long one."""
    tmp = tmp_path_factory.mktemp("minseg")
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    rng = np.random.default_rng(3)
    trajs = [random_primitive(rng, machine.dt) for _ in range(4)]
    db = tmp / "lib.duckdb"
    with pl.Library(db) as lib:
        lib.add_machine(machine)
        items = []
        for i, tr in enumerate(trajs):
            pts = tr.sample(machine.dt)
            items.append((tr, invert(machine, pts - pts[0]), f"prim-{i}", None))
        lib.add_many(items, machine.name)
    lib = pl.Library(db, read_only=True)  # as the CLI opens it for match
    parts, last = [], np.zeros(3)
    for row, v0, v1, n in ((1, 0.1, 0.5, 161), (2, 0.4, 0.5, SHORT), (3, 0.3, 0.8, 251)):
        pts = trajs[row].at(np.linspace(v0, v1, n))
        pts = pts @ Rotation.from_euler("zyx", [40 * row, 10, -20], degrees=True).as_matrix().T
        pts += last - pts[0]
        last = pts[-1]
        parts.append(pts if not parts else pts[1:])
    pts = np.concatenate(parts)
    csv = tmp / "new.csv"
    write_path_csv(csv, np.arange(len(pts)) * machine.dt, pts)
    path = Trajectory.from_samples(pts, machine.dt)
    return {"lib": lib, "db": db, "csv": csv, "path": path, "dt": machine.dt}


def _matched(mt) -> list[tuple[float, float, int]]:
    return [(s.start, s.end, s.primitive) for s in mt.segments if s.primitive is not None]


def _check_cover(segments) -> None:
    assert segments[0].start == 0.0 and segments[-1].end == 1.0
    for s, t in zip(segments, segments[1:], strict=False):
        assert s.end == t.start
        assert s.primitive is not None or t.primitive is not None  # no two unmatched in a row


def test_a_short_match_becomes_part_of_the_unmatched_stretch(setup):
    lib, path = setup["lib"], setup["path"]
    bank = lib.bank("xyz")
    every = match_path(bank, path, EPS, min_segment=0.0)
    durations = [(s.end - s.start) * path.duration for s in every.segments if s.matched]
    short = min(durations)
    assert short < 0.3, durations  # the middle piece (or part of it) matched on its own
    cut = short + setup["dt"]
    mt = match_path(bank, path, EPS, min_segment=cut)
    _check_cover(mt.segments)
    kept = [m for m in _matched(every) if (m[1] - m[0]) * path.duration >= cut]
    assert _matched(mt) == kept  # the long matches and their cuts are unchanged
    dropped = sum(d for d in durations if d < cut) / path.duration
    assert mt.matched_fraction == pytest.approx(every.matched_fraction - dropped, abs=1e-12)
    assert 0.0 < mt.matched_fraction < every.matched_fraction <= 1.0
    assert mt.info["min_segment"] == cut


def test_default_is_one_transition_band_and_the_fraction_is_reported(setup):
    lib, path = setup["lib"], setup["path"]
    mt = lib.match(path, "xyz", eps=EPS)
    band = MIN_SEGMENT_BANDS * BAND_SAMPLES * setup["dt"]
    assert mt.info["min_segment"] == pytest.approx(band)
    assert all(
        (s.end - s.start) * path.duration >= band * (1 - 1e-9) for s in mt.segments if s.matched
    )
    d = mt.to_dict()
    assert d["matched_fraction"] == pytest.approx(
        sum(s["end"] - s["start"] for s in d["segments"] if s["primitive"] is not None)
    )


def test_warm_start_passes_min_segment_through(setup):
    lib, path = setup["lib"], setup["path"]
    ws = lib.warm_start(path, "xyz", eps=EPS, min_segment=path.duration)  # nothing is that long
    assert ws.match.matched_fraction == 0.0
    assert [s.primitive for s in ws.match.segments] == [None]
    assert np.all(np.isfinite(ws.u))  # filled from the model


def test_negative_min_segment_is_refused(setup):
    with pytest.raises(pl.InputError, match=r"min_segment: expected a duration >= 0 s, got -1"):
        match_path(setup["lib"].bank("xyz"), setup["path"], EPS, min_segment=-1.0)


def test_cli_min_segment_and_matched_fraction(setup):
    base = ["--db", str(setup["db"]), "match", str(setup["csv"]), "-m", "xyz", "--eps", str(EPS)]
    res = CliRunner().invoke(main, [*base, "--min-segment", "0", "--json"])
    assert res.exit_code == 0, res.output
    every = json.loads(res.stdout)
    res = CliRunner().invoke(main, [*base, "--min-segment", "100", "--json"])
    assert res.exit_code == 0, res.output
    none = json.loads(res.stdout)
    assert 0.5 < every["matched_fraction"] <= 1.0
    assert none["matched_fraction"] == 0.0 and none["n_segments"] == 1
    res = CliRunner().invoke(main, [*base, "--min-segment", "0"])
    assert f"{100 * every['matched_fraction']:.1f} % of the path matched" in res.output
    res = CliRunner().invoke(main, [*base, "--min-segment", "-0.5"])
    assert res.exit_code == 2
    assert "--min-segment: expected a duration >= 0 s, got -0.5" in res.output


@pytest.mark.parametrize("low, high", [("2", "1"), ("0", "1"), ("1", "inf"), ("nan", "1")])
def test_cli_refuses_a_bad_time_scale_range_under_its_option_name(setup, low, high):
    base = ["--db", str(setup["db"]), "match", str(setup["csv"]), "-m", "xyz"]
    before = setup["db"].read_bytes()
    res = CliRunner().invoke(main, [*base, "--time-scale", low, high])
    assert res.exit_code == 2
    assert f"--time-scale: expected finite bounds 0 < low <= high, got {low} {high}" in res.output
    assert setup["db"].read_bytes() == before


def _segments(cuts: list[float], matched: list[bool]) -> list[Segment]:
    out = []
    for a, b, m in zip([0.0, *cuts], [*cuts, 1.0], matched, strict=True):
        nan = float("nan")
        pid = 1 if m else None
        out.append(Segment(a, b, pid, None, nan, nan, np.eye(2), np.zeros(2), 1.0, 0.0))
    return out


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.001, 0.999), min_size=0, max_size=12, unique=True),
    st.lists(st.booleans(), min_size=13, max_size=13),
    st.floats(0.0, 0.3),
)
def test_drop_short_keeps_the_long_matches_and_merges_the_rest(cuts, flags, shortest):
    cuts = sorted(cuts)
    segs = _segments(cuts, flags[: len(cuts) + 1])
    out = drop_short(segs, shortest, 2)
    _check_cover(out)
    long = [(s.start, s.end) for s in segs if s.matched and s.end - s.start >= shortest]
    assert [(s.start, s.end) for s in out if s.matched] == long


def _key(segments) -> list[tuple]:
    """Every number of every segment (exact equality, float by float)."""
    return [(s.start, s.end, s.primitive, s.primitive_start, s.primitive_end, s.time_scale,
             s.rmsd, s.rotation.tobytes(), s.translation.tobytes()) for s in segments]  # fmt: skip


@pytest.fixture(scope="module")
def sampled(setup):
    """The setup's path on the bank's grid, as match_path samples it, and its default cuts."""
    path, bank = setup["path"], setup["lib"].bank("xyz")
    n = int(round(path.duration / setup["dt"])) + 1
    pts = path.at(np.linspace(0.0, 1.0, n))
    dt = path.duration / (n - 1)
    index = BankIndex(bank)
    return {"index": index, "pts": pts, "dt": dt, "default": segment_path(index, pts, dt, EPS)[0]}


@pytest.mark.parametrize("min_samples", [0, 1, 8])
def test_the_shortest_probe_as_minimum_is_the_default_segmentation(sampled, min_samples):
    s = sampled
    segs, _ = segment_path(s["index"], s["pts"], s["dt"], EPS, min_samples=min_samples)
    assert _key(segs) == _key(s["default"])


def test_match_path_at_the_default_drops_after_the_default_segmentation(setup, sampled):
    # one band of 8 steps is 8 samples: no probe is left out, and the matches of 7 steps
    # are dropped after, as before the segmentation knew of a minimum
    mt = match_path(sampled["index"], setup["path"], EPS)
    band = MIN_SEGMENT_BANDS * BAND_SAMPLES * setup["dt"]
    before = drop_short(sampled["default"], band / setup["path"].duration, 3)
    assert _key(mt.segments) == _key(before)


@settings(max_examples=6, deadline=None)
@given(st.integers(9, 80))
def test_no_match_is_shorter_than_the_minimum_and_each_is_within_eps(sampled, min_samples):
    s = sampled
    segs, _ = segment_path(s["index"], s["pts"], s["dt"], EPS, min_samples=min_samples)
    _check_cover(segs)
    last = s["pts"].shape[0] - 1
    assert all(abs(t.end * last - round(t.end * last)) < 1e-6 for t in segs)  # on samples
    for t in segs:
        if t.matched:
            assert round((t.end - t.start) * last) + 1 >= min_samples
            assert t.rmsd < EPS
            p = matched_pieces([t], s["index"], n=round((t.end - t.start) * last) + 1)[0]
            q = s["pts"][round(t.start * last) : round(t.end * last) + 1]
            assert np.sqrt(np.mean(np.sum((p - q) ** 2, axis=1))) < EPS * (1 + 1e-6)


def test_a_bad_min_samples_is_refused(sampled):
    s = sampled
    for bad, what in ((2.5, "a whole"), (-1, "a number of samples >= 0"), (True, "a whole")):
        with pytest.raises(pl.InputError, match=f"min_samples: expected {what}"):
            segment_path(s["index"], s["pts"], s["dt"], EPS, min_samples=bad)
