"""primlib as a service: the library over HTTP for the controllers of a shop floor.

``primlib serve --db lib.duckdb`` runs :func:`serve`: an ASGI application (Starlette on
uvicorn, the optional extra ``primlib[serve]``) that owns the library file. Reads (lists,
match, warm start, a trial series' status and input) run side by side in reader threads,
each with its own connection; writes (machines, primitives, a trial series' start, step and
finish) go one at a time through a single writer thread, so a client never sees "busy".
Endpoints, status codes and the token file are described in ``docs/serve.md`` and served as
OpenAPI at ``/openapi.json``; :class:`primlib.client.Client` calls them with the library's
method names.
"""

from primlib.serve._app import DEFAULT_PORT, create_app, serve
from primlib.serve._auth import Tokens, is_loopback, read_tokens
from primlib.serve._http import DEFAULT_MAX_BODY
from primlib.serve._ops import Metrics
from primlib.serve._routes import endpoints
from primlib.serve._service import Service

__all__ = [
    "serve",
    "create_app",
    "Service",
    "Tokens",
    "read_tokens",
    "is_loopback",
    "Metrics",
    "DEFAULT_PORT",
    "DEFAULT_MAX_BODY",
    "endpoints",
]
