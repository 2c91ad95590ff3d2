"""HTTP plumbing shared by the routes: the body under a size limit, errors to status codes.

Every refusal is a JSON object ``{"error": "<one sentence>"}`` with the status that says
which kind it is:

=====  ==============================================================================
400    the request cannot be understood (not JSON, a missing or unknown field, a field
       of the wrong JSON type, an unsupported content type)
401    no token, or a token the server does not know (when the server needs tokens)
403    a read-only token asking to write
404    an unknown machine, primitive or route
409    a conflict with what the library holds (another machine of that name)
413    a body over the server's limit
422    understood but invalid: the library's or the file readers' checks (shape, dt,
       NaN, a CSV table's faults, nothing to match), with the CLI's sentence
503    the server is shutting down and refused a write
=====  ==============================================================================
"""

from __future__ import annotations

import json
from typing import Any

from starlette.requests import Request
from starlette.responses import JSONResponse, Response

from primlib._errors import InputError, LibraryBusyError, NotFoundError, PrimlibError
from primlib.serve._inputs import BadRequest, fields, optional_str
from primlib.serve._ops import LOGGER

__all__ = [
    "ApiError",
    "Conflict",
    "read_body",
    "read_json",
    "need_write",
    "error_response",
    "json_response",
    "wants_csv",
    "csv_text",
    "path_request",
    "service_of",
    "DEFAULT_MAX_BODY",
]

DEFAULT_MAX_BODY = 64 * 2**20


class ApiError(Exception):
    """A refusal with its HTTP status and one sentence."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


class Conflict(InputError):
    """The request contradicts what the library holds (HTTP 409)."""


def _status(exc: Exception) -> int:
    if isinstance(exc, ApiError):
        return exc.status
    if isinstance(exc, BadRequest):
        return 400
    if isinstance(exc, NotFoundError):
        return 404
    if isinstance(exc, Conflict):
        return 409
    if isinstance(exc, InputError):
        return 422
    if isinstance(exc, LibraryBusyError):
        return 503
    return 500


def error_response(exc: Exception) -> JSONResponse:
    """The JSON refusal for ``exc`` (an unexpected exception is logged, its text not sent)."""
    status = _status(exc)
    if status == 500 and not isinstance(exc, PrimlibError):
        LOGGER.exception("internal error", exc_info=exc)
        message = f"internal error ({type(exc).__name__}); the server log has the details"
    else:
        message = str(exc)
    return JSONResponse({"error": message}, status_code=status)


def json_response(content: Any, status: int = 200) -> Response:
    """JSON with floats in their shortest round-trip form (arrays read back bit for bit)."""
    body = json.dumps(content, allow_nan=False, separators=(",", ":")).encode()
    return Response(body, status_code=status, media_type="application/json")


async def read_body(request: Request) -> bytes:
    """The whole body, refused with 413 as soon as it passes the server's limit."""
    limit = request.app.state.max_body
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise ApiError(
            413, f"body: expected at most {limit} bytes, got {int(declared)} (Content-Length)"
        )
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise ApiError(413, f"body: expected at most {limit} bytes, got more")
        chunks.append(chunk)
    return b"".join(chunks)


def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise BadRequest("body: expected UTF-8 text, got binary data") from None


async def read_json(request: Request, csv_ok: bool = False, allow_empty: bool = False) -> Any:
    """The body as JSON (or, with ``csv_ok``, as CSV text: ``str``), by its content type;
    with ``allow_empty``, None for an empty body (all fields optional)."""
    kind = request.headers.get("content-type", "application/json").split(";")[0].strip().lower()
    raw = await read_body(request)
    if allow_empty and not raw.strip():
        return None
    if csv_ok and kind == "text/csv":
        return _decode(raw)
    if kind not in ("application/json", ""):
        accepted = "application/json or text/csv" if csv_ok else "application/json"
        raise BadRequest(f"content-type: expected {accepted}, got {kind}")
    text = _decode(raw)
    if not text.strip():
        raise BadRequest("body: expected a JSON object, got an empty body")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadRequest(
            f"body: expected JSON, got a syntax error at line {exc.lineno}, column {exc.colno} "
            f"({exc.msg})"
        ) from None


def need_write(request: Request) -> None:
    """Refuse (403) a caller whose token may only read."""
    if request.scope.get("primlib.role") != "rw":
        raise ApiError(
            403,
            f"{request.method} {request.url.path}: this token is read-only; writing "
            "needs an 'rw' token",
        )


def wants_csv(request: Request) -> bool:
    return "text/csv" in request.headers.get("accept", "")


def csv_text(header: list[str], t: Any, values: Any) -> str:
    """A CSV table (the signal file format), numbers in shortest round-trip form."""
    import numpy as np

    table = np.column_stack([np.asarray(t, dtype=float), np.asarray(values, dtype=float)])
    rows = "\n".join(",".join(map(repr, row)) for row in table.tolist())
    return ",".join(header) + "\n" + rows + "\n"


def service_of(request: Request) -> Any:
    """The :class:`~primlib.serve._service.Service` the application serves."""
    return request.app.state.service


async def path_request(
    request: Request,
    options: tuple[str, ...],
    required: tuple[str, ...] = ("machine", "path"),
    key: str = "path",
) -> dict[str, Any]:
    """The fields of a request that posts a path (match, warm start, a series' start and
    step, where ``key`` is ``"measured"``).

    A JSON body carries every field; a CSV body (``Content-Type: text/csv``) is the path
    file (field ``key``) and the other fields come as query parameters.
    """
    got = await read_json(request, csv_ok=True)
    if isinstance(got, str):
        body: dict[str, Any] = dict(request.query_params)
        if key in body:
            raise BadRequest(f"{key}: expected in the CSV body, got a query parameter too")
        body[key] = got
    else:
        body = got
    body = fields(body, required, ("dt", *options) if key == "path" else options)
    optional_str(body, "machine")
    return body
