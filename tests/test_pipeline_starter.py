"""WarmStarter: one learn path for every caller, caches on the object, the store only stores."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import primlib as pl
from primlib import InputError
from primlib.nurbs import Trajectory
from primlib.pipeline import LAWS, LearnRun, Library, WarmStarter, store_learned
from primlib.plant import Machine, invert
from primlib.store import Store

ROOT = Path(__file__).resolve().parents[1]
DT = 0.005


def _minjerk(r):
    return 10 * r**3 - 15 * r**4 + 6 * r**5


def _arc(T, d=3):
    s = _minjerk(np.arange(round(T / DT) + 1) * DT / T)
    return np.stack([10 * np.sin(np.pi / 2 * s), 10 * (1 - np.cos(np.pi / 2 * s)), 3 * s], 1)[:, :d]


@pytest.fixture(scope="module")
def lib():
    m = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    lib = Library()
    lib.add_machine(m)
    traj = Trajectory.from_samples(_arc(1.0), DT)
    ref = traj.sample(DT)
    lib.add(traj, invert(m, ref - ref[0]), machine="xyz", name="arc")
    return lib


def test_pl_library_is_the_store_plus_the_pipeline():
    assert pl.Library is Library and issubclass(Library, Store)
    assert pl.Store is Store
    for verb in ("match", "warm_start", "learn"):
        assert hasattr(Library, verb) and not hasattr(Store, verb)


def test_the_store_imports_none_of_match_splice_ilc_pipeline():
    banned = ("primlib.match", "primlib.splice", "primlib.ilc", "primlib.pipeline")
    for f in (ROOT / "primlib" / "store").glob("*.py"):
        for node in ast.walk(ast.parse(f.read_text())):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            assert not any(n.startswith(banned) for n in names), (f.name, names)


def test_the_refined_model_is_cached_on_the_starter_not_in_a_module(lib):
    traj = Trajectory.from_samples(_arc(1.2), DT)
    ws1 = lib.warm_start(traj, "xyz", 0.01)
    assert len(lib.starter.refined) == 1
    ws2 = lib.warm_start(traj, "xyz", 0.01)
    assert ws2.model is ws1.model
    other = WarmStarter(lib)  # a second starter over the same store starts empty
    assert len(other.refined) == 0
    assert other.warm_start(traj, "xyz", 0.01).model is not ws1.model


def test_learn_starts_from_the_warm_start_with_its_band(lib):
    # the drift issue 10 names: learn_signal never passed the band
    traj = Trajectory.from_samples(np.vstack([_arc(1.0), _arc(1.0)[1:] + _arc(1.0)[-1]]), DT)
    run = lib.learn(traj, "xyz", iterations=1, band=0.2, contour=False)
    ws = lib.warm_start(traj, "xyz", band=0.2)
    assert [b.to_dict() for b in run.warm.bands] == [b.to_dict() for b in ws.bands]
    assert run.warm.sources == ws.sources
    np.testing.assert_array_equal(run.warm.u, ws.u)
    assert run.result.rms_total[0] == pytest.approx(
        np.sqrt(np.mean(np.sum((run.machine.simulate(ws.u) - run.reference) ** 2, axis=1))),
        rel=1e-6,
    )


def test_learn_runs_the_master_slave_laws_on_a_two_axis_machine():
    # the other drift: learn_signal (ingest --learn) knew only the single-axis laws
    lib = Library()
    lib.add_machine(Machine.from_json(ROOT / "data" / "machines" / "xy-pdccilc.json"))
    traj = Trajectory.from_samples(_arc(2.0, d=2), DT)
    run = lib.learn(traj, "xy-pdccilc", law="pdccilc", iterations=2, cold=True)
    assert isinstance(run, LearnRun) and run.start == "cold"
    assert run.contour is not None and len(run.contour) == 3


def test_a_master_slave_law_on_three_axes_is_refused(lib):
    traj = Trajectory.from_samples(_arc(1.0), DT)
    with pytest.raises(InputError, match="law: expected a two-axis machine .* 3 axes"):
        lib.learn(traj, "xyz", law="pdccilc")


def test_an_unknown_law_is_refused_with_the_fixed_set(lib):
    traj = Trajectory.from_samples(_arc(1.0), DT)
    with pytest.raises(InputError, match=r"law: expected one of p, pd, pid, norm-optimal, tdilc"):
        lib.learn(traj, "xyz", law="pdx")
    assert set(LAWS) == {"p", "pd", "pid", "norm-optimal", "tdilc", "tdccilc", "pdilc", "pdccilc"}


def test_learn_store_true_stores_back_once(tmp_path):
    m = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    with Library(tmp_path / "l.duckdb") as lib:
        lib.add_machine(m)
        traj = Trajectory.from_samples(_arc(1.0), DT)
        run = lib.learn(traj, "xyz", iterations=2, store=True, name="learned", contour=False)
        assert run.stored_id is not None
        np.testing.assert_array_equal(lib.signal(run.stored_id), run.u)
        # the same result stored again is the same primitive
        assert store_learned(lib, run, traj, "xyz", name="again") == run.stored_id
        assert [p.name for p in lib.primitives("xyz")] == ["learned"]
