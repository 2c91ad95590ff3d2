"""Trial series over HTTP against a real ``primlib serve`` process.

The stage is the xyz machine simulated (its model is exact, so the noise added is all the
learning has to fight); the path is the library's quarter arc moved and rotated. Answers
are compared with :mod:`primlib.trials` run in this process on a copy of the library.
"""

from __future__ import annotations

import json
import shutil
import signal
import threading

import numpy as np
import pytest
from serve_helpers import Server, machine_dict, moved, stored

import primlib as pl
from primlib.client import Client, RemoteInputError, RemoteNotFoundError
from primlib.nurbs import Trajectory
from primlib.trials import StartResult, StepResult, start, status, step

pytestmark = pytest.mark.slow

EPS = 0.01
NOISE = 1e-3  # mm per axis
RW, RO = "rw-token-0123456789abcdef", "ro-token-0123456789abcdef"
MACHINE = pl.Machine.from_dict(machine_dict())


def _csv(header: str, t: np.ndarray, values: np.ndarray) -> str:
    rows = "\n".join(",".join(map(repr, r)) for r in np.column_stack([t, values]).tolist())
    return header + "\n" + rows + "\n"


class Stage:
    """The xyz machine with seeded measurement noise: ``measure(u)`` in absolute positions."""

    def __init__(self, origin: np.ndarray, seed: int = 0) -> None:
        self.origin = np.asarray(origin, dtype=float)
        self.rng = np.random.default_rng(seed)

    def run(self, u: np.ndarray) -> np.ndarray:  # relative, as a Plant
        y = MACHINE.simulate(np.asarray(u, dtype=float))
        return y + NOISE * self.rng.standard_normal(y.shape)

    def measure(self, u: np.ndarray) -> np.ndarray:
        return self.run(u) + self.origin


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    folder = tmp_path_factory.mktemp("serve-trials")
    db = folder / "lib.duckdb"
    t, p, _ = stored("arc-quarter")
    points = moved(p, 20.0, (100.0, 50.0, 10.0))
    with pl.Library(db) as lib:
        lib.add_machine(MACHINE)
        _, ps, us = stored("arc-quarter")
        lib.add(Trajectory.from_samples(ps, 0.005), us, "xyz", name="arc-quarter")
    tokens = folder / "tokens.txt"
    tokens.write_text(f"rw {RW}\nro {RO}\n")
    server = Server(db, "--token-file", str(tokens), "--max-body", "65536")
    yield {"server": server, "db": db, "t": t, "points": points, "folder": folder}
    server.stop()


def _call(world, method, path, body=None, token=RW, **kw):
    return world["server"].call(method, path, body, token=token, **kw)


def _n_series(world) -> int:
    return len(_call(world, "GET", "/trials")[1])


def _start_inverse(world, **extra) -> dict:
    body = {"machine": "xyz", "path": world["points"].tolist(), "first": "inverse", **extra}
    status_, d, _ = _call(world, "POST", "/trials", body)
    assert status_ == 201, d
    return d


# ---------------------------------------------------------------------------- the whole cycle
def test_start_step_status_list_input_finish_equal_the_library(world):
    pts = world["points"]
    # the same start and step in this process, on a copy of the library
    copy = world["folder"] / "copy.duckdb"
    shutil.copy(world["db"], copy)
    stage = Stage(pts[0])
    with pl.Library(copy) as lib:
        local = start(lib, Trajectory.from_samples(pts, 0.005), "xyz", eps=EPS, name="arc")
        y0 = stage.measure(local.u)
        local_step = step(lib, local.series, y0)
    status_, d, _ = _call(
        world,
        "POST",
        "/trials",
        {"machine": "xyz", "path": pts.tolist(), "eps": EPS, "name": "arc"},
    )
    assert status_ == 201 and d["start"] == "warm" == local.start and d["trial"] == 0
    assert any("arc-quarter" in n for n in d["notes"])
    np.testing.assert_array_equal(np.array(d["u"]), local.u)  # the same warm start
    sid = d["series"]
    status_, inp, _ = _call(world, "GET", f"/trials/{sid}/input", token=RO)
    assert status_ == 200 and inp["trial"] == 0 and inp["u"] == d["u"]
    status_, d1, _ = _call(
        world, "POST", f"/trials/{sid}/step", {"trial": 0, "measured": y0.tolist()}
    )
    assert status_ == 200 and (d1["trial"], d1["next_trial"]) == (0, 1)
    assert d1["rms"] == local_step.rms and d1["verdict"] == "learning"
    np.testing.assert_array_equal(np.array(d1["u"]), local_step.u)
    # the next step as the measured CSV file itself, the trial in the query
    y1 = stage.measure(np.array(d1["u"]))
    status_, text, hdrs = _call(
        world,
        "POST",
        f"/trials/{sid}/step?trial=1",
        _csv("t,x,y,z", world["t"], y1),
        content_type="text/csv",
        accept="text/csv",
    )
    assert (
        status_ == 200 and hdrs["x-primlib-trial"] == "2" and hdrs["x-primlib-series"] == str(sid)
    )
    assert text.splitlines()[0] == "t,ux,uy,uz" and len(text.splitlines()) == len(pts) + 1
    status_, st, _ = _call(world, "GET", f"/trials/{sid}", token=RO)
    assert status_ == 200 and st["verdict"] in ("learning", "converged") and st["name"] == "arc"
    assert [t["pending"] for t in st["trials"]] == [False, False, True]
    assert st["trials"][0]["rms"] == local_step.rms
    rows = _call(world, "GET", "/trials?machine=xyz", token=RO)[1]
    assert {"series": sid, "state": "running", "steps": 2} == {
        k: v
        for k, v in next(r for r in rows if r["series"] == sid).items()
        if k in ("series", "state", "steps")
    }
    assert _call(world, "GET", "/trials?machine=nosuch")[0] == 404
    status_, fin, _ = _call(world, "POST", f"/trials/{sid}/finish", {"force": True})
    assert status_ == 201 and fin["info"]["source"].startswith(f"trial series {sid}: 2 trials")
    pid = fin["primitive"]
    assert _call(world, "GET", f"/primitives/{pid}")[1]["name"] == "arc"
    # a finished series: finish, step and input are conflicts with its state
    assert _call(world, "POST", f"/trials/{sid}/finish", {"force": True})[:2] == (
        409,
        {"error": f"trial series {sid} is finished (primitive {pid})"},
    )
    assert _call(world, "POST", f"/trials/{sid}/step", {"trial": 2, "measured": y1.tolist()})[
        :2
    ] == (409, {"error": f"trial series {sid} is finished; it takes no more trials"})
    assert _call(world, "GET", f"/trials/{sid}/input")[:2] == (
        409,
        {"error": f"trial series {sid} is finished; no trial is pending"},
    )
    assert _call(world, "DELETE", f"/primitives/{pid}")[0] == 200


def test_finish_before_a_measurement_and_before_convergence_is_a_conflict(world):
    sid = _start_inverse(world)["series"]
    assert _call(world, "POST", f"/trials/{sid}/finish")[:2] == (
        409,
        {"error": f"trial series {sid} has no measured trial yet; step it first"},
    )
    u = np.array(_call(world, "GET", f"/trials/{sid}/input")[1]["u"])
    y = Stage(world["points"][0]).measure(u)
    assert (
        _call(world, "POST", f"/trials/{sid}/step", {"trial": 0, "measured": y.tolist()})[0] == 200
    )
    status_, body, _ = _call(world, "POST", f"/trials/{sid}/finish", {"name": "x"})
    assert status_ == 409 and body["error"].startswith(f"trial series {sid} has not converged")
    assert _call(world, "POST", f"/trials/{sid}/finish", {"force": "maybe"})[0] == 400
    assert _call(world, "GET", f"/trials/{sid}")[1]["state"] == "running"


# ---------------------------------------------------------------------------- refusals
def test_start_refusals_create_no_series(world):
    pts = world["points"].tolist()
    ok = {"machine": "xyz", "path": pts, "first": "inverse"}
    before = _n_series(world)
    cases = [
        ({**ok, "machine": "q"}, 404, "unknown machine 'q'; the library has: xyz"),
        ({**ok, "first": "hot"}, 422, "first: expected one of warm, inverse, cold, got 'hot'"),
        ({**ok, "law": "pidd"}, 422, "law: expected one of p, pd, pid, norm-optimal, got 'pidd'"),
        ({**ok, "average": 0}, 422, "average: expected an integer >= 1, got 0"),
        ({**ok, "average": 1.5}, 400, "average: expected an integer, got 1.5"),
        ({**ok, "eps": -1}, 422, "eps: expected a match tolerance > 0, got -1"),
        (
            {**ok, "gain": 2},
            400,
            "body: unknown field 'gain'; expected fields machine, path, dt, "
            "first, eps, name, law, plain, noise_aware, average, margin, q_cutoff",
        ),
        (
            {**ok, "plain": True, "noise_aware": True},
            400,
            "plain: contradicts noise_aware (True and True); give one of them",
        ),
        (
            {**ok, "path": [r[:2] for r in pts]},
            422,
            f"path: expected points of shape (n, 3), got ({len(pts)}, 2)",
        ),
        ({"machine": "xyz"}, 400, "body: expected field 'path', got none"),
    ]
    for body, code, message in cases:
        assert _call(world, "POST", "/trials", body)[:2] == (code, {"error": message}), body
    status_, body, _ = _call(world, "POST", "/trials", {**ok, "margin": -1.0})
    assert status_ == 422 and body["error"].startswith("margin: expected a number in (0, 10)")
    status_, body, _ = _call(
        world, "POST", "/trials?machine=xyz", "t,x,y,z\n0,1\n", content_type="text/csv"
    )
    assert (status_, body["error"]) == (422, "path, line 2: expected 4 columns, got 2")
    assert _n_series(world) == before


def test_step_refusals_record_nothing_and_say_what_the_cli_says(world):
    d = _start_inverse(world)
    sid, u0 = d["series"], np.array(d["u"])
    t, stage = world["t"], Stage(world["points"][0], seed=3)
    y = stage.measure(u0)
    n = len(t)

    def refused(body, q: str = "", **kw) -> tuple[int, str]:
        status_, answer, _ = _call(world, "POST", f"/trials/{sid}/step{q}", body, **kw)
        assert _call(world, "GET", f"/trials/{sid}")[1]["trials"][-1]["pending"], "it stepped"
        return status_, answer["error"]

    assert refused(_csv("t,x,y,z", t * 2, y), "?trial=0", content_type="text/csv") == (
        422,
        "measured: expected samples every dt = 0.005 s, got dt = 0.01 s",
    )
    assert refused(_csv("t,x,y", t, y[:, :2]), "?trial=0", content_type="text/csv") == (
        422,
        "measured: expected measured positions on 3 axes, got 2",
    )
    assert refused(_csv("t,x,y,z", t[:-1], y[:-1]), "?trial=0", content_type="text/csv") == (
        422,
        f"measured: expected a trial of {n} samples (T = 2 s), got {n - 1} (T = 1.995 s)",
    )
    assert refused({"trial": 0, "measured": y[:-1].tolist()}) == (
        422,
        f"measured: expected a trial of {n} samples on 3 axes, got shape ({n - 1}, 3)",
    )
    bad = y.copy()
    bad[7, 2] = np.nan
    assert refused(json.dumps({"trial": 0, "measured": bad.tolist()})) == (
        422,
        "measured: expected finite positions, got NaN or inf",
    )
    status_, msg = refused({"trial": 0, "measured": (y + 10.0).tolist()})
    assert status_ == 422 and msg.startswith("measured: expected the stage to start at the path's")
    assert refused({"measured": y.tolist()}) == (400, "body: expected field 'trial', got none")
    assert refused({"trial": "first", "measured": y.tolist()}) == (
        400,
        "trial: expected an integer, got 'first'",
    )
    assert refused({"trial": 3, "measured": y.tolist()}) == (
        409,
        f"trial: expected the pending trial 0 of series {sid}, got 3; nothing recorded",
    )
    assert refused({"trial": 0, "measured": 5}) == (
        400,
        "measured: expected a list of rows or CSV text, got int",
    )
    # the same output again: refused after the first was recorded
    assert (
        _call(world, "POST", f"/trials/{sid}/step", {"trial": 0, "measured": y.tolist()})[0] == 200
    )
    status_, answer, _ = _call(
        world, "POST", f"/trials/{sid}/step", {"trial": 1, "measured": y.tolist()}
    )
    assert (status_, answer["error"]) == (
        422,
        "measured: the same measured output as trial 0; run the new input on the stage first",
    )
    # unknown series, bad id, and a body over the server's limit
    assert _call(world, "POST", "/trials/999/step", {"trial": 0, "measured": y.tolist()})[:2] == (
        404,
        {"error": f"no trial series with id 999 in {world['db']}"},
    )
    assert _call(world, "GET", "/trials/999")[0] == 404
    assert _call(world, "GET", "/trials/999/input")[0] == 404
    assert _call(world, "POST", "/trials/999/finish")[0] == 404
    assert _call(world, "GET", "/trials/abc")[:2] == (
        400,
        {"error": "id: expected an integer series id, got 'abc'"},
    )
    big = {"trial": 1, "measured": y.tolist() * 4}
    status_, answer, _ = _call(world, "POST", f"/trials/{sid}/step", big)
    assert status_ == 413 and answer["error"].startswith("body: expected at most 65536 bytes")


def test_two_steps_racing_on_one_trial_never_both_record(world):
    sid = _start_inverse(world)["series"]
    stage = Stage(world["points"][0], seed=5)
    for trial in range(2):
        u = np.array(_call(world, "GET", f"/trials/{sid}/input")[1]["u"])
        outputs = [stage.measure(u), stage.measure(u)]  # two controllers, two measurements
        barrier, answers = threading.Barrier(2), [None, None]

        def post(i: int, trial=trial, outputs=outputs, barrier=barrier, answers=answers) -> None:
            barrier.wait()
            body = {"trial": trial, "measured": outputs[i].tolist()}
            answers[i] = _call(world, "POST", f"/trials/{sid}/step", body)

        threads = [threading.Thread(target=post, args=(i,)) for i in range(2)]
        for th in threads:
            th.start()
        for th in threads:
            th.join(300)
        codes = sorted(a[0] for a in answers)
        assert codes == [200, 409], answers
        loser = next(a for a in answers if a[0] == 409)[1]["error"]
        assert loser == (
            f"trial: trial {trial} of series {sid} is already recorded (another step "
            f"came first); the pending trial is {trial + 1}; nothing recorded"
        )
        st = _call(world, "GET", f"/trials/{sid}")[1]
        assert len(st["trials"]) == trial + 2  # one step recorded, not two


# ---------------------------------------------------------------------------- tokens
def test_tokens_missing_wrong_and_read_only_on_series(world):
    sid = _start_inverse(world)["series"]
    y = Stage(world["points"][0]).measure(
        np.array(_call(world, "GET", f"/trials/{sid}/input")[1]["u"])
    )
    start_body = {"machine": "xyz", "path": world["points"].tolist(), "first": "cold"}
    step_body = {"trial": 0, "measured": y.tolist()}
    before = _n_series(world)
    for method, path, body in [
        ("POST", "/trials", start_body),
        ("POST", f"/trials/{sid}/step", step_body),
        ("POST", f"/trials/{sid}/finish", {"force": True}),
    ]:
        assert _call(world, method, path, body, token=RO)[:2] == (
            403,
            {"error": f"{method} {path}: this token is read-only; writing needs an 'rw' token"},
        )
        assert _call(world, method, path, body, token=None)[0] == 401
        assert _call(world, method, path, body, token="w" * 24)[0] == 401
    for path in ("/trials", f"/trials/{sid}", f"/trials/{sid}/input"):
        assert _call(world, "GET", path, token=RO)[0] == 200  # read-only may read
        assert _call(world, "GET", path, token=None)[0] == 401
    assert _n_series(world) == before
    assert _call(world, "GET", f"/trials/{sid}")[1]["trials"][0]["pending"]


# ---------------------------------------------------------------------------- the client
def test_client_trials_have_the_python_api_names_and_types(world):
    c = Client(world["server"].url, token=RW)
    path = Trajectory.from_samples(world["points"], 0.005)
    res = c.trials.start(path, "xyz", first="inverse", name="by-client", margin=0.5)
    assert (
        isinstance(res, StartResult)
        and res.start == "inverse"
        and res.u.shape == (len(world["t"]), 3)
    )
    st = c.trials.status(res.series)
    assert st["options"]["margin"] == 0.5 and st["options"]["average"] == 32  # library default
    trial, t, u = c.trials.pending(res.series)
    assert trial == 0 and np.array_equal(u, res.u) and t[1] == 0.005
    stage = Stage(world["points"][0], seed=9)
    s0 = c.trials.step(res.series, stage.measure(u))  # trial asked for: the pending one
    assert isinstance(s0, StepResult) and s0.trial == 0
    seen = []
    run = c.trials.run(res.series, stage, max_trials=2, callback=seen.append)
    assert (
        run.stopped in ("max-trials", "converged")
        and [s.trial for s in seen] == [1, 2][: len(seen)]
    )
    with pytest.raises(RemoteInputError, match="already recorded") as exc:
        c.trials.step(res.series, stage.measure(u), trial=0)
    assert exc.value.status == 409
    with pytest.raises(pl.InputError, match="measured: expected finite positions"):
        c.trials.step(res.series, np.full((3, 3), np.nan))
    assert any(r["series"] == res.series for r in c.trials.list(machine="xyz"))
    pid = c.trials.finish(res.series, force=True)
    assert c.info(pid).name == "by-client"
    with pytest.raises(RemoteNotFoundError):
        c.trials.status(99999)
    with pytest.raises(RemoteInputError) as exc:
        Client(world["server"].url, token=RO).trials.start(path, "xyz")
    assert exc.value.status == 403
    c.remove(pid)


# ---------------------------------------------------------------------------- kill -9
def test_a_series_survives_kill_9_and_resumes_on_restart(tmp_path):
    db = tmp_path / "lib.duckdb"
    with pl.Library(db) as lib:
        lib.add_machine(MACHINE)
    t, p, _ = stored("arc-quarter")
    points = moved(p, 20.0, (100.0, 50.0, 10.0))
    stage = Stage(points[0], seed=11)
    server = Server(db)
    c = Client(server.url)
    res = c.trials.start(Trajectory.from_samples(points, 0.005), "xyz", first="inverse")
    y0 = stage.measure(res.u)
    s0 = c.trials.step(res.series, y0, trial=0)  # acknowledged: committed
    assert server.stop(signal.SIGKILL) == -signal.SIGKILL
    again = Server(db)
    try:
        c = Client(again.url)
        trial, _, u = c.trials.pending(res.series)
        assert trial == 1 and np.array_equal(u, s0.u)  # the acknowledged step, whole
        with pytest.raises(RemoteInputError, match="already recorded"):  # a resent step
            c.trials.step(res.series, y0 + 1e-6, trial=0)
        s1 = c.trials.step(res.series, stage.measure(u), trial=1)
        assert s1.trial == 1
        st = c.trials.status(res.series)
        assert [x["pending"] for x in st["trials"]] == [False, False, True]
        assert st["trials"][0]["rms"] == s0.rms
        pid = c.trials.finish(res.series, force=True)
        best = int(np.argmin([x["rms"] for x in st["trials"][:2]]))
        np.testing.assert_array_equal(c.signal(pid), [res.u, u][best])  # the best trial's input
    finally:
        again.stop()
    with pl.Library(db, read_only=True) as lib:  # and the file itself, closed cleanly
        assert status(lib, res.series).verdict == "finished"
        assert lib.info(pid).source.startswith(f"trial series {res.series}:")


# ---------------------------------------------------------------------------- CLI --remote
def test_cli_remote_trials_status_and_list(world, monkeypatch):
    from click.testing import CliRunner

    from primlib.cli import main

    monkeypatch.setenv("PRIMLIB_TOKEN", RO)
    sid = _start_inverse(world, name="cli")["series"]
    url = world["server"].url
    r = CliRunner().invoke(main, ["--remote", url, "trials", "status", str(sid), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.output) == _call(world, "GET", f"/trials/{sid}")[1]
    r = CliRunner().invoke(main, ["--remote", url, "trials", "status", str(sid)])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert lines[0].startswith(f"trial series {sid} (cli) on machine 'xyz', inverse start at (")
    assert lines[-1].startswith("started (noise floor -)")
    r = CliRunner().invoke(main, ["--remote", url, "trials", "list", "--machine", "xyz"])
    assert r.exit_code == 0, r.output
    assert any(
        ln.split()[:5] == [str(sid), "xyz", "cli", "running", "0"] for ln in r.output.splitlines()
    )
    out = world["folder"] / f"series{sid}-input.csv"
    r = CliRunner().invoke(main, ["--remote", url, "trials", "input", str(sid), "--out", str(out)])
    assert r.exit_code == 0 and r.output == f"wrote trial 0's input to {out}\n", r.output
    u = np.loadtxt(out, delimiter=",", skiprows=1)[:, 1:]
    np.testing.assert_array_equal(u, np.array(_call(world, "GET", f"/trials/{sid}/input")[1]["u"]))
    r = CliRunner().invoke(main, ["--remote", url, "trials", "status", "99999"])
    assert r.exit_code == 2 and "no trial series with id 99999" in r.output
    r = CliRunner().invoke(main, ["--remote", url, "trials", "finish", str(sid)])
    assert r.exit_code == 2 and "--remote" in r.output
    assert _call(world, "GET", f"/trials/{sid}")[1]["state"] == "running"
