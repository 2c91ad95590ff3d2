"""The ASGI application and the process that serves it.

:func:`create_app` builds the Starlette application around a
:class:`~primlib.serve._service.Service`; :func:`serve` runs it on uvicorn until SIGINT or
SIGTERM. On either signal uvicorn stops accepting connections and lets the requests in
flight finish (writes included); then the application's shutdown refuses any write still
queued, waits for the running ones, and closes the library (DuckDB checkpoints the
write-ahead log into the file as the last connection closes), and logs ``"stopped"``.
uvicorn then ends the process by the signal it caught (exit status -15 for SIGTERM, as a
service manager expects).
"""

from __future__ import annotations

import contextlib
import json
import logging
import sys
from typing import Any

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from primlib._errors import InputError, PrimlibError
from primlib.serve._auth import Tokens, is_loopback, read_tokens
from primlib.serve._http import DEFAULT_MAX_BODY, ApiError, error_response
from primlib.serve._ops import LOGGER, Gate, Metrics
from primlib.serve._routes import ROUTES
from primlib.serve._service import Service

__all__ = ["create_app", "serve", "DEFAULT_PORT"]

DEFAULT_PORT = 8321


async def _refusal(request: Request, exc: Exception) -> Response:
    return error_response(exc)


async def _http_error(request: Request, exc: Exception) -> Response:
    status = getattr(exc, "status_code", 500)
    if status == 404:
        message = f"{request.method} {request.url.path}: no such endpoint (see /openapi.json)"
    elif status == 405:
        message = f"{request.method} {request.url.path}: method not allowed on this endpoint"
    else:
        message = str(getattr(exc, "detail", exc))
    return error_response(ApiError(status, message))


def create_app(
    service: Service, tokens: Tokens | None = None, max_body: int = DEFAULT_MAX_BODY
) -> Any:
    """The ASGI application serving ``service``.

    Parameters
    ----------
    service : Service
        The library it serves (closed when the application shuts down).
    tokens : Tokens, optional
        Accepted bearer tokens; None lets every caller read and write (loopback only:
        :func:`serve` refuses another host without tokens).
    max_body : int
        Largest request body in bytes; a larger one is refused with 413.

    Returns
    -------
    ASGI application
        A :class:`starlette.applications.Starlette` wrapped in the token, log and metrics
        middleware.
    """

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette):
        yield
        service.close()
        LOGGER.info(json.dumps({"event": "stopped", "db": service.db, "closed": True}))

    routes = [Route(path, handler, methods=[method]) for method, path, handler, _ in ROUTES]
    app = Starlette(
        routes=routes,
        lifespan=lifespan,
        exception_handlers={
            ApiError: _refusal,
            PrimlibError: _refusal,
            HTTPException: _http_error,
            Exception: _refusal,
        },
    )
    app.state.service = service
    app.state.max_body = int(max_body)
    metrics = Metrics()
    app.state.metrics = metrics
    return Gate(app, tokens, metrics)


def serve(
    db: str,
    host: str = "127.0.0.1",
    port: int = DEFAULT_PORT,
    token_file: str | None = None,
    *,
    readers: int = 2,
    max_body: int = DEFAULT_MAX_BODY,
    log_level: str = "info",
) -> None:
    """Serve the library ``db`` over HTTP until SIGINT or SIGTERM.

    Parameters
    ----------
    db : str
        Library file (created when missing).
    host, port : str, int
        Where to listen. A host other than loopback needs ``token_file``.
    token_file : str, optional
        Bearer tokens with their roles (see :mod:`primlib.serve._auth`).
    readers : int
        Reader threads (each with its own connection to the file).
    max_body : int
        Largest request body, bytes.
    log_level : str
        ``"info"`` logs one line per request.

    Raises
    ------
    InputError
        A non-loopback host without a token file, a bad token file, or a library file
        that cannot be opened.
    """
    import uvicorn

    tokens = read_tokens(token_file) if token_file is not None else None
    if tokens is None and not is_loopback(host):
        raise InputError(
            f"--host {host}: expected --token-file for a host other than loopback "
            "(127.0.0.1, ::1, localhost), got none"
        )
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    LOGGER.handlers[:] = [handler]
    LOGGER.setLevel(log_level.upper())
    LOGGER.propagate = False
    service = Service(db, readers=readers)
    LOGGER.info(
        json.dumps(
            {
                "event": "starting",
                "db": db,
                "url": f"http://{host}:{port}",
                "readers": readers,
                "tokens": "none" if tokens is None else len(tokens.entries),
            }
        )
    )
    try:
        app = create_app(service, tokens, max_body)
        config = uvicorn.Config(
            app,
            host=host,
            port=port,
            access_log=False,
            log_level="warning" if log_level == "info" else log_level,
            lifespan="on",
            timeout_graceful_shutdown=30,
        )
        uvicorn.Server(config).run()
    finally:
        service.close()
