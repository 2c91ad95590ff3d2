"""The trial-series endpoints: start, step, status, list, the pending input, finish.

A series learns one path's input on a real stage (:mod:`primlib.trials`): the controller
asks for the first input, runs it, posts the measured output and gets the next input,
until the stop rule says converged; then ``finish`` stores the pair as a primitive. Start,
step and finish go through the server's single writer thread, so they never interleave.

A step names the trial it measured (``trial``: the number start, the previous step or
``/input`` gave). The writer refuses it with 409 unless that is the series' pending trial,
so two controllers that post a step of the same trial never both succeed: one is recorded,
the other gets 409 and nothing is written. Errors of the series' state (finished, already
stepped, not converged, nothing measured yet) are 409; a measured output that is wrong in
itself (grid, columns, NaN, length, the same as the last trial, a start away from the
path) is 422 with ``primlib trials step``'s sentence, naming ``measured``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from starlette.requests import Request
from starlette.responses import Response

from primlib._errors import InputError, LibraryBusyError
from primlib.serve._http import (
    Conflict,
    csv_text,
    json_response,
    need_write,
    path_request,
    read_json,
    service_of,
    wants_csv,
)
from primlib.serve._inputs import (
    SERIES_FIELDS,
    BadRequest,
    as_bool,
    fields,
    measured_of,
    optional_str,
    path_of,
    series_options,
    trial_of,
)

__all__ = ["TRIAL_ROUTES"]


def _series_id(request: Request) -> int:
    raw = request.path_params["id"]
    try:
        return int(raw)
    except ValueError:
        raise BadRequest(f"id: expected an integer series id, got {raw!r}") from None


def _store(lib: Any) -> Any:
    from primlib.store import TrialStore

    return TrialStore(lib)


def _input_response(
    request: Request, payload: dict[str, Any], status: int = 200, trial: str = "trial"
) -> Response:
    """A series' next input: JSON with ``t`` and ``u``, or the signal CSV (``Accept:
    text/csv``) with the series and the trial it is for (``payload[trial]``) in headers."""
    t, u = np.asarray(payload.pop("t"), dtype=float), np.asarray(payload.pop("u"), dtype=float)
    if wants_csv(request):
        headers = {"x-primlib-series": str(payload["series"])}
        headers["x-primlib-trial"] = str(payload[trial])
        header = ["t", "ux", "uy", "uz"][: u.shape[1] + 1]
        return Response(csv_text(header, t, u), status_code=status, media_type="text/csv",
                        headers=headers)  # fmt: skip
    return json_response({**payload, "t": t.tolist(), "u": u.tolist()}, status)


# ---------------------------------------------------------------------------- writes
async def series_start(request: Request) -> Response:
    need_write(request)
    body = await path_request(request, SERIES_FIELDS)
    first, eps, name, options = series_options(body)

    def start(lib: Any) -> Any:
        from primlib.trials import start as start_series

        machine = lib.machine(body["machine"])
        traj, _ = path_of(body, machine, own_dt=True)
        return start_series(lib, traj, machine.name, first=first, eps=eps, name=name, **options)

    res = await service_of(request).write(start)
    payload = {"series": res.series, "trial": 0, "start": res.start, "notes": list(res.notes),
               "t": res.t, "u": res.u}  # fmt: skip
    return _input_response(request, payload, 201)


def _check_pending(rec: Any, series: int, trial: int) -> None:
    """Refuse (409) a step of a finished series or of a trial that is not the pending one."""
    if rec.state != "running":
        raise Conflict(f"trial series {series} is {rec.state}; it takes no more trials")
    if trial < rec.steps:
        raise Conflict(
            f"trial: trial {trial} of series {series} is already recorded (another step came "
            f"first); the pending trial is {rec.steps}; nothing recorded"
        )
    if trial > rec.steps:
        raise Conflict(
            f"trial: expected the pending trial {rec.steps} of series {series}, got {trial}; "
            "nothing recorded"
        )


async def series_step(request: Request) -> Response:
    need_write(request)
    series = _series_id(request)
    body = await path_request(request, (), ("trial", "measured"), key="measured")
    trial = trial_of(body)

    def step(lib: Any) -> Any:
        from primlib.trials import step as step_series

        rec = _store(lib).series(series)
        _check_pending(rec, series, trial)
        y = measured_of(body["measured"], rec.n_samples, rec.dim, rec.dt)
        try:
            return step_series(lib, series, y, label="measured")
        except LibraryBusyError as exc:  # another process (none while the server owns it)
            raise Conflict(str(exc)) from None

    res = await service_of(request).write(step)
    verdict = "converged" if res.converged else "diverging" if res.diverging else "learning"
    payload = {
        "series": series,
        "trial": res.trial,  # the trial just recorded (as StepResult.trial)
        "next_trial": res.trial + 1,  # the trial the returned input is for
        "rms": res.rms,
        "contour_rms": res.contour_rms,
        "noise_floor": res.noise_floor,
        "q_cutoff": res.q_cutoff,
        "converged": res.converged,
        "diverging": res.diverging,
        "verdict": verdict,
        "t": res.t,
        "u": res.u,
    }
    return _input_response(request, payload, trial="next_trial")


async def series_finish(request: Request) -> Response:
    need_write(request)
    series = _series_id(request)
    raw = await read_json(request, allow_empty=True)
    body = fields({} if raw is None else raw, (), ("name", "force"))
    name = optional_str(body, "name")
    force = False if body.get("force") is None else as_bool("force", body["force"])

    def finish(lib: Any) -> dict[str, Any]:
        from primlib.trials import finish as finish_series
        from primlib.trials import status

        st = status(lib, series)
        measured = any(not t.pending for t in st.trials)
        state_says_no = st.record.state != "running" or not measured
        state_says_no = state_says_no or (not st.converged and not force)
        try:
            pid = finish_series(lib, series, name=name, force=force)
        except InputError as exc:
            if state_says_no:  # finished, nothing measured, not converged: the series' state
                raise Conflict(str(exc)) from None
            raise
        return {"series": series, "primitive": pid, "info": lib.info(pid).to_dict()}

    return json_response(await service_of(request).write(finish), 201)


# ---------------------------------------------------------------------------- reads
async def series_status(request: Request) -> Response:
    series = _series_id(request)

    def status(lib: Any) -> dict[str, Any]:
        from primlib.trials import status as series_status

        return series_status(lib, series).to_dict()

    return json_response(await service_of(request).read(status))


async def series_list(request: Request) -> Response:
    machine = request.query_params.get("machine")

    def rows(lib: Any) -> list[dict[str, Any]]:
        if machine is not None:
            lib.machine(machine)  # 404 for an unknown machine
        store = _store(lib)
        out = []
        for sid in store.ids(machine):
            r = store.series(sid)
            done = [t for t in store.trials(sid) if not t.pending]
            out.append({"series": sid, "machine": r.machine, "name": r.name, "state": r.state,
                        "start": r.start, "steps": r.steps, "primitive": r.primitive,
                        "last_rms": done[-1].rms if done else None})  # fmt: skip
        return out

    return json_response(await service_of(request).read(rows))


async def series_input(request: Request) -> Response:
    series = _series_id(request)

    def pending(lib: Any) -> tuple[int, np.ndarray, np.ndarray]:
        from primlib.trials import pending as pending_input

        rec = _store(lib).series(series)  # 404 first
        if rec.state != "running":
            raise Conflict(f"trial series {series} is {rec.state}; no trial is pending")
        return pending_input(lib, series)

    trial, t, u = await service_of(request).read(pending)
    return _input_response(request, {"series": series, "trial": trial, "t": t, "u": u})


TRIAL_ROUTES: list[tuple[str, str, Any, bool]] = [
    ("GET", "/trials", series_list, False),
    ("POST", "/trials", series_start, True),
    ("GET", "/trials/{id}", series_status, False),
    ("GET", "/trials/{id}/input", series_input, False),
    ("POST", "/trials/{id}/step", series_step, True),
    ("POST", "/trials/{id}/finish", series_finish, True),
]
