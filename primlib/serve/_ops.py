"""Operations around every request: the bearer-token check, a log line, the metrics.

:class:`Metrics` keeps request counts and latency histograms per (method, route, status)
and renders them in the Prometheus text exposition format (version 0.0.4); the route is
the template (``/primitives/{id}``), never the concrete path, so the series stay few.
:class:`Gate` is the ASGI middleware that checks the token, times the request, writes one
structured log line (JSON: method, path, status, duration) and records the metrics.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from bisect import bisect_left
from collections.abc import Awaitable, Callable, MutableMapping
from datetime import UTC, datetime
from typing import Any

__all__ = ["Metrics", "Gate", "LOGGER", "OPEN_PATHS"]

LOGGER = logging.getLogger("primlib.serve")

# Latency histogram bucket bounds, seconds (a warm start takes tens to hundreds of ms).
BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0)

# Reachable without a token: a load balancer's liveness probe.
OPEN_PATHS = frozenset({"/health"})

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
ASGIApp = Callable[[Scope, Callable[[], Awaitable[Message]], Callable], Awaitable[None]]


class Metrics:
    """Request counters and latency histograms, rendered as Prometheus text."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._count: dict[tuple[str, str, str], int] = {}
        self._hist: dict[tuple[str, str], list[float]] = {}  # bucket counts, then sum, count

    def observe(self, method: str, route: str, status: int, seconds: float) -> None:
        with self._lock:
            key = (method, route, str(status))
            self._count[key] = self._count.get(key, 0) + 1
            h = self._hist.setdefault((method, route), [0.0] * (len(BUCKETS) + 2))
            i = bisect_left(BUCKETS, seconds)
            if i < len(BUCKETS):
                h[i] += 1
            h[-2] += seconds
            h[-1] += 1

    def render(self) -> str:
        """The exposition text: ``primlib_requests_total`` and
        ``primlib_request_duration_seconds`` (cumulative buckets, ``+Inf``, sum, count)."""

        def labels(**kv: str) -> str:
            body = ",".join(f'{k}="{_escape(v)}"' for k, v in kv.items())
            return "{" + body + "}"

        with self._lock:
            counts = sorted(self._count.items())
            hists = sorted((k, list(v)) for k, v in self._hist.items())
        out = [
            "# HELP primlib_requests_total HTTP requests answered, by method, route and status.",
            "# TYPE primlib_requests_total counter",
        ]
        out += [
            f"primlib_requests_total{labels(method=m, route=r, status=s)} {n}"
            for (m, r, s), n in counts
        ]
        out += [
            "# HELP primlib_request_duration_seconds Time from request to the last response "
            "byte, by method and route.",
            "# TYPE primlib_request_duration_seconds histogram",
        ]
        for (m, r), h in hists:
            running = 0.0
            for bound, n in zip(BUCKETS, h, strict=False):
                running += n
                le = labels(method=m, route=r, le=f"{bound:g}")
                out.append(f"primlib_request_duration_seconds_bucket{le} {running:g}")
            inf = labels(method=m, route=r, le="+Inf")
            out.append(f"primlib_request_duration_seconds_bucket{inf} {h[-1]:g}")
            out.append(f"primlib_request_duration_seconds_sum{labels(method=m, route=r)} {h[-2]!r}")
            out.append(
                f"primlib_request_duration_seconds_count{labels(method=m, route=r)} {h[-1]:g}"
            )
        return "\n".join(out) + "\n"


def _escape(value: str) -> str:
    return value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


def _bearer(scope: Scope) -> str | None:
    for name, value in scope.get("headers", ()):
        if name == b"authorization":
            scheme, _, token = value.decode("latin-1").partition(" ")
            return token.strip() if scheme.lower() == "bearer" else None
    return None


async def _refuse(send: Callable, status: int, message: str) -> None:
    body = json.dumps({"error": message}).encode()
    headers = [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode())]
    if status == 401:
        headers.append((b"www-authenticate", b'Bearer realm="primlib"'))
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})


class Gate:
    """ASGI middleware: token check, one log line and the metrics for every HTTP request.

    Parameters
    ----------
    app : ASGI application
    tokens : Tokens or None
        None: no token needed (a loopback server without a token file); every caller may
        write. Otherwise every path but :data:`OPEN_PATHS` needs a token of the file, and
        ``scope["primlib.role"]`` tells the handlers ``"rw"`` or ``"ro"``.
    metrics : Metrics
    """

    def __init__(self, app: ASGIApp, tokens: Any, metrics: Metrics) -> None:
        self.app = app
        self.tokens = tokens
        self.metrics = metrics

    async def __call__(self, scope: Scope, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        status = [500]

        async def send_status(message: Message) -> None:
            if message["type"] == "http.response.start":
                status[0] = message["status"]
            await send(message)

        try:
            if self.tokens is None:
                scope["primlib.role"] = "rw"
                await self.app(scope, receive, send_status)
            elif scope["path"] in OPEN_PATHS:
                scope["primlib.role"] = None
                await self.app(scope, receive, send_status)
            else:
                token = _bearer(scope)
                role = self.tokens.role(token)
                if role is None:
                    why = "no bearer token" if token is None else "a token the server does not know"
                    await _refuse(
                        send_status,
                        401,
                        f"authorization: expected 'Authorization: Bearer TOKEN' with a token of "
                        f"the server's token file, got {why}",
                    )
                else:
                    scope["primlib.role"] = role
                    await self.app(scope, receive, send_status)
        finally:
            seconds = time.perf_counter() - t0
            route = getattr(scope.get("route"), "path", None) or "(unrouted)"
            self.metrics.observe(scope["method"], route, status[0], seconds)
            LOGGER.info(
                json.dumps(
                    {
                        "ts": datetime.now(UTC).isoformat(timespec="milliseconds"),
                        "method": scope["method"],
                        "path": scope["path"],
                        "status": status[0],
                        "ms": round(seconds * 1e3, 3),
                        "client": (scope.get("client") or ("", 0))[0],
                    }
                )
            )
