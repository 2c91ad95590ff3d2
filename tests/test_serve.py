"""``primlib serve`` as a real process on a loopback port, called over HTTP.

One server (no token, loopback) serves a small library built here; every endpoint is called
and every refusal code provoked, and the answers are compared with the library's own
(computed in this process before the server took the file). A second server with a token
file checks who may do what.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from serve_helpers import ROOT, Server, machine_dict, moved, stored

import primlib as pl
from primlib.client import Client, RemoteInputError, RemoteNotFoundError
from primlib.nurbs import Trajectory

pytestmark = pytest.mark.slow

EPS = 0.01  # mm: the moved arc matches its primitive to ~1e-9, nothing else comes close
FAST = {"refine": False}  # the warm start without the model refinement (seconds faster)


def _csv(header: str, t: np.ndarray, values: np.ndarray) -> str:
    rows = "\n".join(",".join(map(repr, r)) for r in np.column_stack([t, values]).tolist())
    return header + "\n" + rows + "\n"


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """A library file (xyz, two primitives), the local answers, and a server on it."""
    folder = tmp_path_factory.mktemp("serve")
    db = folder / "lib.duckdb"
    t, p, u = stored("arc-quarter")
    query = Trajectory.from_samples(moved(p), 0.005)
    with pl.Library(db) as lib:
        lib.add_machine(pl.Machine.from_dict(machine_dict()))
        for stem in ("line-x-fast", "arc-quarter"):
            _, ps, us = stored(stem)
            lib.add(Trajectory.from_samples(ps, 0.005), us, "xyz", name=stem)
        local_match = lib.match(query, machine="xyz", eps=EPS)
        local_ws = lib.warm_start(query, machine="xyz", eps=EPS, **FAST)
    server = Server(db)
    yield {
        "server": server,
        "db": db,
        "query": query,
        "query_points": moved(p),
        "t": t,
        "match": local_match,
        "ws": local_ws,
        "folder": folder,
    }
    server.stop()


def _count(server: Server) -> int:
    return len(server.call("GET", "/primitives")[1])


# ---------------------------------------------------------------------------- service
def test_health_version_openapi_and_every_route_documented(world):
    s = world["server"]
    assert s.call("GET", "/health")[:2] == (200, {"status": "ok"})
    status, v, _ = s.call("GET", "/version")
    assert status == 200 and v["primlib"] == pl.__version__ and v["schema_version"] >= 1
    status, doc, _ = s.call("GET", "/openapi.json")
    assert status == 200 and doc["openapi"].startswith("3.")
    from primlib.serve import endpoints

    documented = {(m.upper(), p) for p, ops in doc["paths"].items() for m in ops}
    assert documented == set(endpoints())


def test_unknown_route_and_method(world):
    s = world["server"]
    status, body, _ = s.call("GET", "/nope")
    assert status == 404 and body["error"] == "GET /nope: no such endpoint (see /openapi.json)"
    status, body, _ = s.call("PUT", "/machines", {})
    assert status == 405 and "method not allowed" in body["error"]


# ---------------------------------------------------------------------------- machines
def test_machines_list_show_add(world):
    s = world["server"]
    status, rows, _ = s.call("GET", "/machines")
    assert status == 200 and [r["name"] for r in rows] == ["xyz"] and rows[0]["primitives"] >= 2
    status, one, _ = s.call("GET", "/machines/xyz")
    assert status == 200 and one["definition"]["dt"] == 0.005 and one["axes"] == ["x", "y", "z"]
    # the same machine again: nothing changes
    assert s.call("POST", "/machines", machine_dict())[:2] == (
        200,
        {"status": "unchanged", "name": "xyz"},
    )
    other = {**machine_dict(), "name": "xy2", "axes": ["x", "y"]}
    other["plants"] = {a: other["plants"][a] for a in ("x", "y")}
    assert s.call("POST", "/machines", other)[:2] == (201, {"status": "added", "name": "xy2"})
    assert s.call("GET", "/machines/xy2")[1]["dt"] == 0.005


def test_machine_refusals(world):
    s = world["server"]
    with pl.Library() as lib:  # the library's own sentence for the same conflict
        lib.add_machine(pl.Machine.from_dict(machine_dict()))
        changed = {**machine_dict(), "dt": 0.001}
        with pytest.raises(pl.InputError) as local:
            lib.add_machine(pl.Machine.from_dict(changed))
    status, body, _ = s.call("POST", "/machines", changed)
    assert status == 409
    assert body["error"] == str(local.value).replace("the in-memory library", str(world["db"]))
    status, body, _ = s.call("GET", "/machines/nosuch")
    assert status == 404 and body["error"].startswith("unknown machine 'nosuch'; the library has:")
    status, body, _ = s.call("POST", "/machines", "{not json")
    assert status == 400 and body["error"].startswith("body: expected JSON, got a syntax error")
    status, body, _ = s.call("POST", "/machines", {"name": "bad", "dt": -1})
    assert status == 422 and body["error"]
    status, body, _ = s.call("POST", "/machines", [1, 2])
    assert status == 400 and body["error"] == "body: expected a machine JSON object, got list"
    assert s.call("GET", "/machines/xyz")[1]["definition"]["dt"] == 0.005  # not replaced


# ---------------------------------------------------------------------------- primitives
def test_primitive_add_as_points_and_as_csv_then_show_signal_remove(world):
    s = world["server"]
    t, p, u = stored("line-diagonal")
    before = _count(s)
    status, info, _ = s.call(
        "POST",
        "/primitives",
        {"machine": "xyz", "path": p.tolist(), "signal": u.tolist(), "name": "diag"},
    )
    assert status == 201 and info["name"] == "diag" and info["n_samples"] == len(t)
    pid = info["id"]
    status, info2, _ = s.call(
        "POST",
        "/primitives",
        {
            "machine": "xyz",
            "path": _csv("t,x,y,z", t, p),
            "signal": _csv("t,ux,uy,uz", t, 1.01 * u),  # another primitive (same is kept once)
            "source": "csv",
        },
    )
    assert status == 201 and info2["source"] == "csv"
    assert _count(s) == before + 2
    status, shown, _ = s.call("GET", f"/primitives/{pid}?arrays=true")
    assert status == 200 and shown["axes"] == ["x", "y", "z"]
    np.testing.assert_array_equal(np.array(shown["signal"]), u)  # bit for bit through JSON
    fitted = Trajectory.from_samples(p, 0.005).sample(0.005)  # what `ingest` would store
    np.testing.assert_allclose(np.array(shown["points"]), fitted, rtol=0, atol=1e-12)
    status, sig, _ = s.call("GET", f"/primitives/{pid}/signal")
    np.testing.assert_array_equal(np.array(sig["u"]), u)
    status, text, hdrs = s.call("GET", f"/primitives/{pid}/signal", accept="text/csv")
    assert status == 200 and hdrs["content-type"].startswith("text/csv")
    assert text.splitlines()[0] == "t,ux,uy,uz" and len(text.splitlines()) == len(t) + 1
    status, gone, _ = s.call("DELETE", f"/primitives/{pid}")
    assert status == 200 and gone["removed"]["id"] == pid
    assert s.call("DELETE", f"/primitives/{pid}")[0] == 404
    assert s.call("DELETE", f"/primitives/{info2['id']}")[0] == 200
    assert _count(s) == before
    listed = s.call("GET", "/primitives?machine=xyz")[1]
    assert [r["name"] for r in listed][:2] == ["line-x-fast", "arc-quarter"]


def test_an_identical_primitive_is_kept_once_and_answered_200_with_its_id(world):
    s = world["server"]
    t, p, u = stored("line-x-slow")
    body = {"machine": "xyz", "path": p.tolist(), "signal": u.tolist(), "name": "once"}
    status, first, _ = s.call("POST", "/primitives", body)
    assert status == 201 and first["created"] is True and "note" not in first
    before = _count(s)
    # the same content again (another name, and as CSV): nothing new, the existing id
    again = {**body, "name": "twice", "path": _csv("t,x,y,z", t, p)}
    status, second, _ = s.call("POST", "/primitives", again)
    assert status == 200 and second["created"] is False and second["id"] == first["id"]
    assert second["name"] == "once"  # the stored row, unchanged
    assert second["note"] == (
        f"an identical primitive (same machine, path and signal) is stored already as id "
        f"{first['id']}; nothing was written"
    )
    assert _count(s) == before
    c = Client(s.url)  # the client returns the id either way, as Library.add does
    assert c.add(Trajectory.from_samples(p, 0.005), u, machine="xyz") == first["id"]
    assert _count(s) == before
    status, nudged, _ = s.call("POST", "/primitives", {**body, "signal": (u * 1.001).tolist()})
    assert status == 201 and nudged["created"] is True and nudged["id"] != first["id"]
    for pid in (first["id"], nudged["id"]):
        assert s.call("DELETE", f"/primitives/{pid}")[0] == 200


def _refused(s: Server, method: str, path: str, body, **kw) -> tuple[int, str]:
    before = _count(s)
    status, answer, _ = s.call(method, path, body, **kw)
    assert _count(s) == before, "a refused request wrote"
    return status, answer["error"]


def test_primitive_refusals_write_nothing(world):
    s = world["server"]
    t, p, u = stored("line-diagonal")
    ok = {"machine": "xyz", "path": p.tolist(), "signal": u.tolist()}
    with pl.Library() as lib:  # the library's sentence for a signal of the wrong length
        lib.add_machine(pl.Machine.from_dict(machine_dict()))
        traj = Trajectory.from_samples(p, 0.005)
        with pytest.raises(pl.InputError) as local:
            lib.add(traj, u[:-1], "xyz")
    assert _refused(s, "POST", "/primitives", {**ok, "signal": u[:-1].tolist()}) == (
        422,
        str(local.value),
    )
    assert _refused(s, "POST", "/primitives", {**ok, "machine": "q"}) == (
        404,
        "unknown machine 'q'; the library has: xy2, xyz",
    )
    assert _refused(s, "POST", "/primitives", {**ok, "colour": 1}) == (
        400,
        "body: unknown field 'colour'; expected fields machine, path, signal, name, source, dt",
    )
    assert _refused(s, "POST", "/primitives", {k: ok[k] for k in ("machine", "path")}) == (
        400,
        "body: expected field 'signal', got none",
    )
    bad = u.copy()
    bad[3, 1] = np.nan
    assert _refused(s, "POST", "/primitives", json.dumps({**ok, "signal": bad.tolist()})) == (
        422,
        "signal: expected finite numbers, got NaN or inf",
    )
    status, msg = _refused(s, "POST", "/primitives", {**ok, "signal": [[1.0, 2.0]] * len(u)})
    assert (status, msg) == (422, f"signal: expected a signal of shape (n, 3), got ({len(u)}, 2)")
    # a CSV path at another sample time: the sentence `primlib ingest` gives for that file
    csv = _csv("t,x,y,z", t * 2, p)
    status, msg = _refused(s, "POST", "/primitives", {**ok, "path": csv})
    assert (status, msg) == (
        422,
        "path: expected samples at the dt of machine 'xyz' (0.005 s), got dt = 0.01 s",
    )
    status, msg = _refused(s, "POST", "/primitives", {**ok, "path": "t,x,y,z\n0,1,2,3\n"})
    assert (status, msg) == (422, "path: expected at least 8 path rows, got 1")
    assert _refused(s, "GET", "/primitives/abc", None) == (
        400,
        "id: expected an integer primitive id, got 'abc'",
    )
    assert s.call("GET", "/primitives/99999")[:2] == (
        404,
        {"error": f"no primitive with id 99999 in {world['db']}"},
    )
    assert _refused(s, "POST", "/primitives", "x", content_type="text/plain")[0] == 400


# ---------------------------------------------------------------------------- match
def test_match_json_and_csv_equal_the_library(world):
    s = world["server"]
    local = world["match"].to_dict()
    status, got, _ = s.call(
        "POST", "/match", {"machine": "xyz", "path": world["query_points"].tolist(), "eps": EPS}
    )
    assert status == 200 and got["n_segments"] == local["n_segments"] == 1
    assert got["segments"][0]["primitive_name"] == "arc-quarter"
    assert [g["primitive"] for g in got["segments"]] == [g["primitive"] for g in local["segments"]]
    np.testing.assert_allclose(
        got["segments"][0]["rotation"], local["segments"][0]["rotation"], atol=1e-9
    )
    body = _csv("t,x,y,z", world["t"], world["query_points"])
    status, got_csv, _ = s.call(
        "POST", f"/match?machine=xyz&eps={EPS}", body, content_type="text/csv"
    )
    assert status == 200 and got_csv["segments"] == got["segments"]
    # the matcher's min_segment goes through (a match longer than the path: all unmatched)
    body = {"machine": "xyz", "path": world["query_points"].tolist(), "eps": EPS}
    status, whole, _ = s.call("POST", "/match", {**body, "min_segment": 1e6})
    assert status == 200 and whole["matched_fraction"] == 0.0
    status, bad, _ = s.call("POST", "/match", {**body, "min_segment": -1})
    assert status == 422 and "min_segment" in bad["error"]


def test_warm_start_json_and_csv_equal_the_library(world):
    s = world["server"]
    local = world["ws"]
    body = {"machine": "xyz", "path": world["query_points"].tolist(), "eps": EPS, **FAST}
    status, got, _ = s.call("POST", "/warm-start", body)
    assert status == 200
    np.testing.assert_array_equal(np.array(got["u"]), local.u)  # same fit, same numbers
    assert [pc["method"] for pc in got["pieces"]] == list(local.methods)
    assert "arc-quarter" in got["pieces"][0]["source"]
    status, text, hdrs = s.call("POST", "/warm-start", body, accept="text/csv")
    assert status == 200 and hdrs["x-primlib-unmatched"] == "0"
    u = np.loadtxt(text.splitlines()[1:], delimiter=",")[:, 1:]
    np.testing.assert_array_equal(u, local.u)


def test_match_refusals(world):
    s = world["server"]
    pts = world["query_points"].tolist()
    assert _refused(s, "POST", "/match", {"machine": "xyz", "path": pts, "eps": -1}) == (
        422,
        "eps: expected a tolerance > 0, got -1",
    )
    two_d = [r[:2] for r in pts]
    assert _refused(s, "POST", "/match", {"machine": "xyz", "path": two_d}) == (
        422,
        f"path: expected points of shape (n, 3), got ({len(pts)}, 2)",
    )
    assert _refused(s, "POST", "/match", {"machine": "q", "path": pts})[0] == 404
    assert _refused(s, "POST", "/warm-start", {"machine": "xyz", "path": 3})[0] == 400
    status, msg = _refused(
        s, "POST", "/match?machine=xyz", "t,x,y,z\n0,1\n", content_type="text/csv"
    )
    assert (status, msg) == (422, "path, line 2: expected 4 columns, got 2")
    with pl.Library() as lib:  # the library's sentence for a machine without primitives
        lib.add_machine(pl.Machine.from_dict(machine_dict()))
        with pytest.raises(pl.NoMatchError) as local:
            lib.match(world["query"], machine="xyz", eps=EPS)
    empty = {**machine_dict(), "name": "empty"}
    assert s.call("POST", "/machines", empty)[0] == 201
    status, msg = _refused(s, "POST", "/match", {"machine": "empty", "path": pts})
    assert (status, msg) == (422, str(local.value).replace("'xyz'", "'empty'"))


def test_request_size_limit(tmp_path):
    with pl.Library(tmp_path / "small.duckdb") as lib:
        lib.add_machine(pl.Machine.from_dict(machine_dict()))
    s = Server(tmp_path / "small.duckdb", "--max-body", "4096")
    try:
        _, p, u = stored("line-x-fast")
        body = {"machine": "xyz", "path": p.tolist(), "signal": u.tolist()}
        status, answer, _ = s.call("POST", "/primitives", body)
        assert status == 413 and answer["error"].startswith("body: expected at most 4096 bytes")
        assert s.call("GET", "/primitives")[1] == []
    finally:
        s.stop()


# ---------------------------------------------------------------------------- operations
def test_metrics_and_request_log(world):
    s = world["server"]
    s.call("GET", "/machines")
    status, text, hdrs = s.call("GET", "/metrics", accept="text/plain")
    assert status == 200 and hdrs["content-type"].startswith("text/plain; version=0.0.4")
    lines = text.splitlines()
    assert "# TYPE primlib_requests_total counter" in lines
    assert any(ln.startswith('primlib_requests_total{method="GET",route="/machines",status="200"}')
               for ln in lines)  # fmt: skip
    bucket = 'primlib_request_duration_seconds_bucket{method="GET",route="/machines",le="+Inf"}'
    count = [ln for ln in lines if ln.startswith(bucket)]
    assert count and float(count[0].split()[-1]) >= 1
    logged = [json.loads(ln) for ln in s.log.read_text().splitlines() if ln.startswith("{")]
    assert logged[0]["event"] == "starting"
    requests = [r for r in logged if "event" not in r]
    assert all({"ts", "method", "path", "status", "ms"} <= set(r) for r in requests)
    assert any(r["path"] == "/machines" and r["status"] == 200 for r in requests)


# ---------------------------------------------------------------------------- client
def test_client_has_the_library_names_and_types(world):
    c = Client(world["server"].url)
    assert "xyz" in c.machines() and c.machine("xyz").dt == 0.005
    infos = c.primitives(machine="xyz")
    assert [i.name for i in infos][:2] == ["line-x-fast", "arc-quarter"]
    mt = c.match(world["query"], machine="xyz", eps=EPS)
    assert isinstance(mt, pl.Match) and isinstance(mt.segments[0], pl.Segment)
    assert mt.segments[0].primitive == world["match"].segments[0].primitive
    np.testing.assert_allclose(mt.segments[0].rotation, world["match"].segments[0].rotation)
    ws = c.warm_start(world["query"], machine="xyz", eps=EPS, **FAST)
    assert isinstance(ws, pl.WarmStart)
    np.testing.assert_array_equal(ws.u, world["ws"].u)  # the NURBS travels: same curve
    _, p, u = stored("line-diagonal")
    pid = c.add(Trajectory.from_samples(p, 0.005), u, machine="xyz", name="by-client")
    got = c.get(pid)
    assert got.name == "by-client" and got.trajectory.duration == pytest.approx(
        0.005 * (len(u) - 1)
    )
    np.testing.assert_array_equal(c.signal(pid), u)
    c.remove(pid)
    with pytest.raises(RemoteNotFoundError, match=f"no primitive with id {pid}"):
        c.info(pid)
    with pytest.raises(RemoteInputError, match=r"expected a signal of shape") as exc:
        c.add(Trajectory.from_samples(p, 0.005), u[:5], machine="xyz")
    assert exc.value.status == 422


# ---------------------------------------------------------------------------- CLI --remote
def test_cli_remote_read_commands_print_what_local_ones_print(world):
    from click.testing import CliRunner

    from primlib.cli import main

    url = world["server"].url
    r = CliRunner().invoke(main, ["--remote", url, "list", "--json"])
    assert r.exit_code == 0, r.output
    assert [d["name"] for d in json.loads(r.output)][:2] == ["line-x-fast", "arc-quarter"]
    r = CliRunner().invoke(main, ["--remote", url, "show", "2", "--json"])
    assert r.exit_code == 0 and json.loads(r.output)["name"] == "arc-quarter"
    path_csv = world["folder"] / "query.csv"
    path_csv.write_text(_csv("t,x,y,z", world["t"], world["query_points"]))
    r = CliRunner().invoke(main, ["--remote", url, "match", str(path_csv), "--machine", "xyz",
                                  "--eps", str(EPS), "--json"])  # fmt: skip
    assert r.exit_code == 0, r.output
    assert json.loads(r.output)["segments"][0]["primitive_name"] == "arc-quarter"
    r = CliRunner().invoke(main, ["--remote", url, "show", "9999"])
    assert r.exit_code == 2 and "no primitive with id 9999" in r.output
    r = CliRunner().invoke(main, ["--remote", url, "remove", "1"])
    assert r.exit_code == 2 and "--remote" in r.output


# ---------------------------------------------------------------------------- tokens
RW, RO = "rw-token-0123456789abcdef", "ro-token-0123456789abcdef"


def test_tokens_missing_wrong_and_read_only(tmp_path, world):
    tokens = tmp_path / "tokens.txt"
    tokens.write_text(f"# who may do what\nrw {RW}\nro {RO}  # the stage PCs\n")
    s = Server(world["db"].with_name("tok.duckdb"), "--token-file", str(tokens))
    try:
        assert s.call("GET", "/health")[0] == 200  # open: liveness probes
        status, body, hdrs = s.call("GET", "/machines")
        assert status == 401 and hdrs["www-authenticate"].startswith("Bearer")
        assert "got no bearer token" in body["error"]
        status, body, _ = s.call("GET", "/machines", token="x" * 24)
        assert status == 401 and "a token the server does not know" in body["error"]
        assert s.call("POST", "/machines", machine_dict(), token=RO)[:2] == (
            403,
            {"error": "POST /machines: this token is read-only; writing needs an 'rw' token"},
        )
        assert s.call("POST", "/machines", machine_dict(), token=RW)[0] == 201
        _, p, u = stored("arc-quarter")
        add = {"machine": "xyz", "path": p.tolist(), "signal": u.tolist()}
        assert s.call("POST", "/primitives", add, token=RO)[0] == 403
        assert s.call("GET", "/primitives", token=RO)[1] == []
        status, info, _ = s.call("POST", "/primitives", add, token=RW)
        assert status == 201
        assert s.call("DELETE", f"/primitives/{info['id']}", token=RO)[0] == 403
        q = {"machine": "xyz", "path": world["query_points"].tolist(), "eps": EPS}
        assert s.call("POST", "/match", q, token=RO)[0] == 200  # read-only may match
        assert s.call("POST", "/warm-start", {**q, **FAST}, token=RO)[0] == 200  # and warm-start
        with pytest.raises(RemoteInputError) as exc:
            Client(s.url, token=RO).add(Trajectory.from_samples(p, 0.005), u, machine="xyz")
        assert exc.value.status == 403
        assert len(Client(s.url, token=RW).primitives()) == 1
    finally:
        s.stop()


def _serve_exit(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "primlib", "serve", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )


def test_a_host_other_than_loopback_needs_a_token_file(tmp_path):
    r = _serve_exit("--db", str(tmp_path / "x.duckdb"), "--host", "0.0.0.0")
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1] == (
        "Error: --host 0.0.0.0: expected --token-file for a host other than loopback "
        "(127.0.0.1, ::1, localhost), got none"
    )
    bad = tmp_path / "tokens.txt"
    bad.write_text("admin abc\n")
    r = _serve_exit("--db", str(tmp_path / "x.duckdb"), "--token-file", str(bad))
    assert r.returncode == 2 and "line 1: expected 'rw TOKEN' or 'ro TOKEN'" in r.stderr
    bad.write_text("rw short\n")
    r = _serve_exit("--db", str(tmp_path / "x.duckdb"), "--token-file", str(bad))
    assert r.returncode == 2 and "a token of at least 16 characters, got 5" in r.stderr
    assert not (tmp_path / "x.duckdb").exists()


def test_a_server_that_dies_mid_reply_is_a_remote_error_not_a_raw_http_exception():
    # the durability test's kill can land while a reply is on the wire: the client read a
    # Content-Length it never got (http.client.IncompleteRead, no OSError) and raised it
    # raw, so a caller catching PrimlibError -- the durability test's ingest -- lost it
    import socket
    import threading

    from primlib.client import RemoteError

    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(1)

    def cut_short() -> None:
        conn, _ = sock.accept()
        conn.recv(65536)
        conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n")
        conn.sendall(b'Content-Length: 189\r\n\r\n{"id"')
        conn.close()

    t = threading.Thread(target=cut_short, daemon=True)
    t.start()
    try:
        with pytest.raises(RemoteError, match="closed the connection mid-reply"):
            Client(f"http://127.0.0.1:{sock.getsockname()[1]}").request("GET", "/health")
    finally:
        t.join(10)
        sock.close()
