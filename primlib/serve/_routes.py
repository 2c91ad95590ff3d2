"""The endpoints: machines, primitives, match and warm start, health, version, metrics
(and the trial series' of :mod:`primlib.serve._trial_routes`).

Each handler parses and checks its request (CPU work off the event loop, in a reader
thread), then runs one library call through :class:`~primlib.serve._service.Service`:
reads in a reader thread, writes in the writer thread. Nothing is written before every
check has passed, so a refused request leaves the library as it was.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from starlette.requests import Request
from starlette.responses import PlainTextResponse, Response

from primlib.serve._http import (
    Conflict,
    csv_text,
    json_response,
    need_write,
    path_request,
    read_json,
    wants_csv,
)
from primlib.serve._inputs import (
    MATCH_FIELDS,
    WARM_FIELDS,
    BadRequest,
    as_bool,
    fields,
    match_options,
    optional_str,
    path_of,
    signal_of,
    warm_options,
)
from primlib.serve._trial_routes import TRIAL_ROUTES

__all__ = ["ROUTES", "endpoints"]


def _service(request: Request) -> Any:
    return request.app.state.service


def _id(request: Request) -> int:
    raw = request.path_params["id"]
    try:
        return int(raw)
    except ValueError:
        raise BadRequest(f"id: expected an integer primitive id, got {raw!r}") from None


def _query_flag(request: Request, key: str) -> bool:
    value = request.query_params.get(key)
    return False if value is None else as_bool(key, value)


# ---------------------------------------------------------------------------- service
async def health(request: Request) -> Response:
    closing = _service(request).closing
    return json_response({"status": "closing" if closing else "ok"}, 503 if closing else 200)


async def version(request: Request) -> Response:
    import primlib

    schema = await _service(request).read(lambda lib: lib.schema_version)
    return json_response({"primlib": primlib.__version__, "schema_version": schema, "api": 1})


async def metrics(request: Request) -> Response:
    return PlainTextResponse(
        request.app.state.metrics.render(), media_type="text/plain; version=0.0.4"
    )


async def openapi(request: Request) -> Response:
    from primlib.serve._openapi import schema

    return json_response(schema())


# ---------------------------------------------------------------------------- machines
def _summary(row: dict[str, Any]) -> dict[str, Any]:
    return {**row, "added": row["added"].isoformat()}


async def machines_list(request: Request) -> Response:
    rows = await _service(request).read(lambda lib: lib.machine_summaries())
    return json_response([_summary(r) for r in rows])


async def machine_show(request: Request) -> Response:
    name = request.path_params["name"]

    def show(lib: Any) -> dict[str, Any]:
        definition = lib.machine(name).to_dict()
        row = next(r for r in lib.machine_summaries() if r["name"] == name)
        return {**_summary(row), "definition": definition}

    return json_response(await _service(request).read(show))


async def machine_add(request: Request) -> Response:
    need_write(request)
    body = await read_json(request)
    replace = _query_flag(request, "replace")
    if not isinstance(body, dict):
        raise BadRequest(f"body: expected a machine JSON object, got {type(body).__name__}")
    from primlib.plant import Machine

    machine = await _service(request).compute(lambda: Machine.from_dict(body))

    def add(lib: Any) -> str:
        existed = machine.name in lib.machines()
        try:
            return lib.add_machine(machine, replace=replace)
        except Conflict:
            raise
        except ValueError as exc:
            if existed:
                raise Conflict(str(exc)) from None
            raise

    status = await _service(request).write(add)
    code = 201 if status == "added" else 200
    return json_response({"status": status, "name": machine.name}, code)


# ---------------------------------------------------------------------------- primitives
async def primitives_list(request: Request) -> Response:
    machine = request.query_params.get("machine")
    infos = await _service(request).read(lambda lib: lib.primitives(machine=machine))
    return json_response([p.to_dict() for p in infos])


def _primitive_dict(lib: Any, pid: int, arrays: bool) -> dict[str, Any]:
    p = lib.get(pid)
    axes = list(lib.machine(p.machine).axes)
    traj = p.trajectory
    d = p.to_dict()
    d["axes"] = axes
    d["nurbs"] = {
        "degree": traj.degree,
        "knots": traj.knots.tolist(),
        "ctrlpts": traj.ctrlpts.tolist(),
        "weights": traj.weights.tolist(),
        "duration": traj.duration,
    }
    d["signal_rms"] = dict(zip(axes, np.sqrt(np.mean(p.signal**2, axis=0)).tolist(), strict=True))
    d["signal_peak"] = dict(zip(axes, np.max(np.abs(p.signal), axis=0).tolist(), strict=True))
    if arrays:
        d["points"] = p.points.tolist()
        d["signal"] = p.signal.tolist()
    return d


async def primitive_show(request: Request) -> Response:
    pid = _id(request)
    arrays = _query_flag(request, "arrays")
    return json_response(
        await _service(request).read(lambda lib: _primitive_dict(lib, pid, arrays))
    )


async def primitive_signal(request: Request) -> Response:
    pid = _id(request)

    def read(lib: Any) -> tuple[np.ndarray, float]:
        return lib.signal(pid), lib.info(pid).dt

    u, dt = await _service(request).read(read)
    t = np.arange(len(u)) * dt
    if wants_csv(request):
        header = ["t", "ux", "uy", "uz"][: u.shape[1] + 1]
        return Response(csv_text(header, t, u), media_type="text/csv")
    return json_response({"id": pid, "t": t.tolist(), "u": u.tolist()})


async def primitive_add(request: Request) -> Response:
    need_write(request)
    body = fields(await read_json(request), ("machine", "path", "signal"), ("name", "source", "dt"))
    name, source = optional_str(body, "name"), optional_str(body, "source")
    machine_name = optional_str(body, "machine")

    def add(lib: Any) -> tuple[dict[str, Any], bool]:
        # all in the writer thread: an ingest never queues behind the readers' warm starts
        machine = lib.machine(machine_name)
        traj, t = path_of(body, machine)
        u = signal_of(body, machine, t)
        done = lib.add_batch([(traj, u, name, source)], machine_name, single=True)
        return lib.info(done.ids[0]).to_dict(), not done.duplicates

    info, created = await _service(request).write(add)
    if created:
        return json_response({**info, "created": True}, 201)
    # the library keeps one copy of identical content (same machine, path and signal)
    note = (
        f"an identical primitive (same machine, path and signal) is stored already as id "
        f"{info['id']}; nothing was written"
    )
    return json_response({**info, "created": False, "note": note}, 200)


async def primitive_remove(request: Request) -> Response:
    need_write(request)
    pid = _id(request)

    def remove(lib: Any) -> dict[str, Any]:
        info = lib.info(pid)
        lib.remove(pid)
        return info.to_dict()

    return json_response({"removed": await _service(request).write(remove)})


# ---------------------------------------------------------------------------- match
def _parsed(lib: Any, body: dict[str, Any], parse_options) -> tuple:
    """(trajectory, eps, options) for the request's machine, in the reader thread that then
    computes (one trip through the reader queue per request)."""
    machine = lib.machine(body["machine"])
    traj, _ = path_of(body, machine)
    return traj, *parse_options(body, traj)


async def match(request: Request) -> Response:
    body = await path_request(request, MATCH_FIELDS)

    def run(lib: Any) -> dict[str, Any]:
        traj, eps, kw = _parsed(lib, body, match_options)
        mt = lib.match(traj, machine=body["machine"], eps=eps, **kw)
        return {**mt.to_dict(), "duration": float(traj.duration)}

    return json_response(await _service(request).read(run))


def warm_start_dict(ws: Any, duration: float) -> dict[str, Any]:
    """A WarmStart as JSON: u0 and its grid, the match, and per spliced piece what it used.

    The splice may merge a match's consecutive segments (a continuation of one primitive, a
    sliver): ``pieces`` lists the spliced ones, ``sample_segment`` maps samples to them.
    """
    d = ws.to_dict()
    d["pieces"] = [{"method": m, "source": s} for m, s in zip(ws.methods, ws.sources, strict=True)]
    d["duration"] = duration
    d["t"] = np.asarray(ws.t, dtype=float).tolist()
    d["u"] = np.asarray(ws.u, dtype=float).tolist()
    if ws.model_u is not None:
        d["model_u"] = np.asarray(ws.model_u, dtype=float).tolist()
    d["sample_segment"] = np.asarray(ws.sample_segment).astype(int).tolist()
    return d


async def warm_start(request: Request) -> Response:
    body = await path_request(request, WARM_FIELDS)
    csv = wants_csv(request)

    def run(lib: Any) -> Any:
        traj, eps, kw = _parsed(lib, body, warm_options)
        ws = lib.warm_start(traj, machine=body["machine"], eps=eps, **kw)
        if csv:
            return ws, csv_text(["t", "ux", "uy", "uz"][: ws.u.shape[1] + 1], ws.t, ws.u)
        return ws, warm_start_dict(ws, float(traj.duration))

    ws, answer = await _service(request).read(run)
    if csv:
        counts = {"x-primlib-segments": str(len(ws.methods))}
        counts["x-primlib-unmatched"] = str(ws.n_unmatched)
        return Response(answer, media_type="text/csv", headers=counts)
    return json_response(answer)


ROUTES: list[tuple[str, str, Any, bool]] = [
    # (method, path template, handler, writes): the endpoints, as /openapi.json lists them
    ("GET", "/health", health, False),
    ("GET", "/version", version, False),
    ("GET", "/metrics", metrics, False),
    ("GET", "/openapi.json", openapi, False),
    ("GET", "/machines", machines_list, False),
    ("POST", "/machines", machine_add, True),
    ("GET", "/machines/{name}", machine_show, False),
    ("GET", "/primitives", primitives_list, False),
    ("POST", "/primitives", primitive_add, True),
    ("GET", "/primitives/{id}", primitive_show, False),
    ("DELETE", "/primitives/{id}", primitive_remove, True),
    ("GET", "/primitives/{id}/signal", primitive_signal, False),
    ("POST", "/match", match, False),
    ("POST", "/warm-start", warm_start, False),
    *TRIAL_ROUTES,
]


def endpoints() -> list[tuple[str, str]]:
    """Every endpoint the server answers, as (method, path template) pairs."""
    return [(method, path) for method, path, _, _ in ROUTES]
