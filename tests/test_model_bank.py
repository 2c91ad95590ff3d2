"""The primitives a machine's models are fitted on: every one up to 24, then the library as
it stood when it last grew by a quarter, so that neither a new path nor a new primitive
makes a warm start fit them again (on 1,000 primitives each did: 5-11 s a warm start)."""

from __future__ import annotations

import json
import math
import threading

import duckdb
import numpy as np
import pytest
from click.testing import CliRunner
from match_helpers import ROOT

from primlib.cli import main
from primlib.nurbs import Trajectory
from primlib.pipeline import FitShare, Library, model_count
from primlib.pipeline._greywarm import pair_mismatch
from primlib.pipeline._starter import refine_ids
from primlib.plant import Machine, invert

DT = 0.005


def test_model_count_is_every_primitive_up_to_24_then_grows_by_quarters():
    ks = np.arange(0, 5000)
    counts = np.array([model_count(int(k)) for k in ks])
    assert np.array_equal(counts[:25], ks[:25])
    assert np.all(np.diff(counts) >= 0) and np.all(counts <= ks)
    # the models always see at least 1/1.25 of the library (less one for the rounding up)
    assert np.all(counts[25:] >= ks[25:] / 1.25 - 1)
    # and a library growing one primitive at a time fits them O(log k) times beyond 24
    fits = np.unique(counts[25:]).size
    assert fits <= math.log(5000 / 24) / math.log(1.25) + 1
    assert model_count(1000) == 888 and model_count(1110) == 1110


def test_refine_ids_are_all_within_the_sample_budget_else_spread_through_the_library():
    assert refine_ids([5, 3, 9]) == [3, 5, 9]
    ids = list(range(100, 400, 3))  # 100 primitives
    for sizes, count in ((None, 24), ([2000] * 100, 24), ([401] * 100, 100), ([800] * 100, 60),
                         ([10_000] * 100, 24)):  # fmt: skip
        picked = refine_ids(ids[::-1], sizes)
        assert len(picked) == count and picked == sorted(set(picked))
        assert picked[0] == ids[0] and picked[-1] == ids[-1]
        assert set(picked) <= set(ids)


def _primitive(rng, n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)[:, None]
    amp, ph = rng.normal(size=(2, 3)) * 5.0, rng.uniform(0, 2 * np.pi, size=(2, 3))
    pts = amp[0] * np.sin(2 * np.pi * t + ph[0]) + amp[1] * np.sin(4 * np.pi * t + ph[1])
    return pts - pts[0]


@pytest.fixture(scope="module")
def grown(tmp_path_factory):
    """A file library of 26 small primitives on the XYZ stage (exact inputs), and the
    generator that makes more."""
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    rng = np.random.default_rng(7)
    db = tmp_path_factory.mktemp("grown") / "lib.duckdb"

    def item(k: int):
        pts = _primitive(rng, 161)
        return Trajectory.from_samples(pts, DT), invert(machine, pts), f"p{k}", None

    with Library(db) as lib:
        lib.add_machine(machine)
        lib.add_many([item(k) for k in range(26)], "xyz")
    return db, item


def _path(lib, rows, seed):
    """A path of pieces of the primitives ``rows`` (bank order), turned at random."""
    bank = lib.bank("xyz")
    rng = np.random.default_rng(seed)
    out, last = [], np.zeros(3)
    for r in rows:
        p = bank.points_of(r)[20:140]
        c, s = np.cos(rng.uniform(0, 6)), np.sin(rng.uniform(0, 6))
        p = (p - p[0]) @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T + last
        last = p[-1]
        out.append(p if not out else p[1:])
    return Trajectory.from_samples(np.concatenate(out), DT)


def test_new_paths_and_new_primitives_do_not_fit_the_models_again(grown):
    db, item = grown
    with Library(db) as lib:
        kept = lib.starter.kept
        lib.warm_start(_path(lib, [0, 5], 1), "xyz", eps=0.05)
        first = kept.fitted
        assert first == 3  # grey-box, refined, grey-box beside it
        lib.warm_start(_path(lib, [11, 17, 25], 2), "xyz", eps=0.05)
        assert kept.fitted == first  # another path: the same models
        lib.add_many([item(k) for k in range(26, 30)], "xyz")  # 30: the library grew by 1/4
        ws = lib.warm_start(_path(lib, [29, 3], 3), "xyz", eps=0.05)
        assert kept.fitted == first + 3 and model_count(30) == 30
        lib.add(*item(30)[:2], "xyz", name="p30")  # 31: not in the models' fit
        ws = lib.warm_start(_path(lib, [30, 3], 4), "xyz", eps=0.05)
        assert kept.fitted == first + 3
        bank = lib.bank("xyz")
        assert int(bank.ids[-1]) in {s.primitive for s in ws.match.segments}
        assert np.all(np.isfinite(ws.u)) and np.all(np.isfinite(ws.model_u))
        # the newest primitive's pair is unknown to the fitted model: NaN, as one left out
        _, gb, _ = lib.starter.fit_models("xyz")
        assert kept.fitted == first + 3
        mismatch = pair_mismatch(gb, bank)
        assert mismatch.shape == (31,) and np.isnan(mismatch[30])
        assert np.all(np.isfinite(mismatch[:30]))


def test_machine_fit_says_which_primitives_the_models_are_fitted_on(grown, tmp_path):
    db, item = grown
    copy = tmp_path / "lib.duckdb"
    copy.write_bytes(db.read_bytes())
    res = CliRunner().invoke(main, ["--db", str(copy), "machine", "fit", "xyz", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.output)
    assert out["fitted_on"] == model_count(out["primitives"]) < out["primitives"]
    res = CliRunner().invoke(main, ["--db", str(copy), "machine", "fit", "xyz"])
    assert res.exit_code == 0, res.output
    assert f"fitted on the oldest {out['fitted_on']} of the {out['primitives']}" in res.output
    k = out["fitted_on"] + 1
    while model_count(k) == out["fitted_on"]:
        k += 1
    assert f"fitted again at {k}" in res.output


def _without_models(db, tmp_path):
    """A copy of the library file ``db`` with no models kept."""
    copy = tmp_path / "lib.duckdb"
    copy.write_bytes(db.read_bytes())
    with duckdb.connect(str(copy)) as con:
        con.execute("DELETE FROM fitted_models")
    return copy


def test_connections_sharing_fits_fit_each_model_once(grown, tmp_path):
    # primlib serve's readers at a size where the models are fitted again: the one that
    # starts fits, the other waits for its model (two fits of 11 s at once on 1,000
    # primitives, on the same cores, before)
    copy = _without_models(grown[0], tmp_path)
    share = FitShare()
    libs = [Library(copy) for _ in range(2)]
    try:
        for lib in libs:
            lib.starter.kept.share = share
        path = _path(libs[0], [2, 7], 5)
        out = [None, None]

        def run(j: int) -> None:
            out[j] = libs[j].warm_start(path, "xyz", eps=0.05).u

        threads = [threading.Thread(target=run, args=(j,)) for j in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert sum(lib.starter.kept.fitted for lib in libs) == 3
        assert sum(lib.starter.kept.read for lib in libs) == 3
        np.testing.assert_array_equal(out[0], out[1])
    finally:
        for lib in libs:
            lib.close()


def test_a_failed_fit_leaves_the_next_thread_to_fit():
    share = FitShare()

    def boom():
        raise RuntimeError("no")

    with pytest.raises(RuntimeError):
        share.fit("k", boom)
    assert share.fit("k", lambda: 42) == (42, True)
    assert share.fit("k", lambda: 43) == (42, False)


def test_learn_ingest_keeps_its_models_for_the_next_command(grown, tmp_path):
    # below the next size the stored primitive leaves the models valid: the next command
    # reads them (it fitted them again, until stop 46)
    copy = _without_models(grown[0], tmp_path)
    with Library(copy, read_only=True) as lib:
        count = len(lib.bank("xyz").ids)
        path = _path(lib, [4, 9], 6)
    assert model_count(count + 1) == model_count(count)
    csv = tmp_path / "new.csv"
    path.to_csv(csv, DT)
    args = ["--db", str(copy), "learn", str(csv), "--machine", "xyz", "--eps", "0.05"]
    res = CliRunner().invoke(main, [*args, "--iterations", "1", "--ingest"])
    assert res.exit_code == 0, res.output
    assert "kept the 3 model(s)" in res.output and "stored primitive" in res.output
    res = CliRunner().invoke(main, ["--db", str(copy), "machine", "fit", "xyz", "--json"])
    out = json.loads(res.output)
    assert out["primitives"] == count + 1
    assert (out["fitted"], out["read"]) == (0, 3)
