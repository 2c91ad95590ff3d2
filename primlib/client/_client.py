"""A Python client of ``primlib serve`` with the library's method names (stdlib only).

Paths travel as their NURBS definition, so the server matches and warm-starts exactly the
curve the caller holds and a remote result equals the local one; arrays come back as JSON
lists of floats in shortest round-trip form (bit for bit).
"""

from __future__ import annotations

import http.client
import json
import os
import urllib.error
import urllib.parse
import urllib.request
from datetime import datetime
from typing import Any

import numpy as np

from primlib._errors import InputError, NotFoundError, PrimlibError

__all__ = ["Client", "RemoteError", "RemoteInputError", "RemoteNotFoundError"]


class RemoteError(PrimlibError):
    """The server could not be reached, or answered with a failure (5xx).

    ``status`` is the HTTP status (None when there was no answer).
    """

    def __init__(self, message: str, status: int | None = None) -> None:
        super().__init__(message)
        self.status = status


class RemoteInputError(InputError):
    """The server refused the request (400, 401, 403, 409, 413, 422); ``status`` says which."""

    def __init__(self, message: str, status: int) -> None:
        super().__init__(message)
        self.status = status


class RemoteNotFoundError(NotFoundError):
    """An unknown machine, primitive or endpoint (404)."""

    def __init__(self, message: str, status: int = 404) -> None:
        super().__init__(message)
        self.status = status


def nurbs_of(path: Any) -> dict[str, Any]:
    """A path as the server's NURBS definition (a CSV file name is read here, locally)."""
    from primlib.nurbs import Trajectory

    if isinstance(path, (str, os.PathLike)):
        path = Trajectory.from_csv(path)
    if not hasattr(path, "definition"):
        raise InputError(
            f"path: expected a Trajectory or a path CSV file, got {type(path).__name__}"
        )
    d = path.definition()
    return {
        "degree": int(d["degree"]),
        "knots": np.asarray(d["knots"], dtype=float).tolist(),
        "ctrlpts": np.asarray(d["ctrlpts"], dtype=float).tolist(),
        "weights": np.asarray(d["weights"], dtype=float).tolist(),
        "duration": float(d["duration"]),
    }


def _info(d: dict[str, Any]) -> Any:
    from primlib.store import PrimitiveInfo

    fields = {k: d[k] for k in PrimitiveInfo.__dataclass_fields__}
    fields["added"] = datetime.fromisoformat(d["added"])
    return PrimitiveInfo(**fields)


def _nan(x: Any) -> float:
    return float("nan") if x is None else float(x)


def match_from_dict(d: dict[str, Any], path: Any = None) -> Any:
    """A :class:`primlib.Match` from the server's JSON (``Match.to_dict`` plus extras)."""
    from primlib import Match, Segment

    segments = tuple(
        Segment(
            start=float(s["start"]),
            end=float(s["end"]),
            primitive=s["primitive"],
            primitive_name=s["primitive_name"],
            primitive_start=_nan(s["primitive_start"]),
            primitive_end=_nan(s["primitive_end"]),
            rotation=np.asarray(s["rotation"], dtype=float),
            translation=np.asarray(s["translation"], dtype=float),
            time_scale=_nan(s["time_scale"]),
            rmsd=_nan(s["rmsd"]),
        )
        for s in d["segments"]
    )
    return Match(
        segments=segments,
        machine=d["machine"],
        eps=float(d["eps"]),
        rotation_mode=d.get("rotation_mode", "full"),
        path=path,
        info=dict(d.get("info", {})),
    )


def warm_start_from_dict(d: dict[str, Any], path: Any = None) -> Any:
    """A :class:`primlib.WarmStart` from the server's JSON (no refined model, no pieces)."""
    from primlib import WarmStart
    from primlib.splice import Band

    return WarmStart(
        u=np.asarray(d["u"], dtype=float),
        t=np.asarray(d["t"], dtype=float),
        match=match_from_dict(d["match"], path),
        bands=tuple(Band(**b) for b in d["bands"]),
        sample_segment=np.asarray(d["sample_segment"], dtype=int),
        sources=tuple(d["sources"]),
        methods=tuple(d["methods"]),
        notes=tuple(d["notes"]),
        model_u=None if d.get("model_u") is None else np.asarray(d["model_u"], dtype=float),
        choices=tuple(d.get("choices", ())),
        predicted=tuple(float(p) for p in d.get("predicted", ())),
        weights=tuple(float(w) for w in d.get("weights", ())),
    )


class Client:
    """A primlib server, called with the names of :class:`primlib.Library`.

    Parameters
    ----------
    url : str
        The server, e.g. ``"http://127.0.0.1:8321"``.
    token : str, optional
        Bearer token (an ``rw`` token to write, ``ro`` to read); default ``$PRIMLIB_TOKEN``.
    timeout : float
        Seconds to wait for an answer.

    Raises
    ------
    RemoteInputError
        (an InputError) when the server refuses a request: the message is the server's
        sentence, ``status`` its HTTP status.
    RemoteNotFoundError
        (a NotFoundError) for an unknown machine or primitive.
    RemoteError
        When the server cannot be reached or fails.

    Examples
    --------
    >>> lib = Client("http://127.0.0.1:8321")  # was: lib = pl.Library("lib.duckdb")
    >>> ws = lib.warm_start(path, machine="xyz", eps=0.05)  # doctest: +SKIP
    """

    def __init__(self, url: str, token: str | None = None, timeout: float = 300.0) -> None:
        if not isinstance(url, str) or urllib.parse.urlsplit(url).scheme not in ("http", "https"):
            raise InputError(f"url: expected an http:// or https:// address, got {url!r}")
        self.url = url.rstrip("/")
        self.token = token if token is not None else os.environ.get("PRIMLIB_TOKEN") or None
        self.timeout = float(timeout)

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

    @property
    def trials(self) -> Any:
        """The server's trial series: :mod:`primlib.trials`' functions as methods
        (``client.trials.start(path, "xyz")`` for ``start(lib, path, "xyz")``; see
        :class:`primlib.client.RemoteTrials`)."""
        from primlib.client._trials import RemoteTrials

        return RemoteTrials(self)

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Nothing to release (each call is one HTTP request); here for Library's shape."""

    # ------------------------------------------------------------------ transport
    def request(
        self, method: str, path: str, body: Any = None, query: dict[str, Any] | None = None
    ) -> Any:
        """One call: JSON in, JSON out; a refusal raised with the server's sentence."""
        url = self.url + path
        if query:
            url += "?" + urllib.parse.urlencode({k: v for k, v in query.items() if v is not None})
        headers = {"Accept": "application/json"}
        data = None
        if body is not None:
            data = json.dumps(body, allow_nan=False).encode()
            headers["Content-Type"] = "application/json"
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        req = urllib.request.Request(url, data=data, headers=headers, method=method)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout) as resp:
                return json.loads(resp.read())
        except urllib.error.HTTPError as exc:
            raise _refusal(exc) from None
        except (urllib.error.URLError, OSError) as exc:
            reason = getattr(exc, "reason", exc)
            raise RemoteError(f"{self.url}: cannot reach the server ({reason})") from None
        except http.client.HTTPException as exc:
            # a server killed while it answered: the reply cut short (IncompleteRead) is no
            # OSError, and it came out raw -- a caller sees what any lost server gives
            raise RemoteError(
                f"{self.url}: the server closed the connection mid-reply ({exc!r})"
            ) from None

    # ------------------------------------------------------------------ service
    def health(self) -> dict[str, Any]:
        return self.request("GET", "/health")

    def version(self) -> dict[str, Any]:
        return self.request("GET", "/version")

    # ------------------------------------------------------------------ machines
    def machines(self) -> list[str]:
        """Names of the machines, sorted."""
        return [r["name"] for r in self.machine_summaries()]

    def machine_summaries(self) -> list[dict[str, Any]]:
        """One dict per machine: name, kind, dt, axes, primitives, added (UTC)."""
        rows = self.request("GET", "/machines")
        return [{**r, "added": datetime.fromisoformat(r["added"])} for r in rows]

    def machine(self, name: str) -> Any:
        """The machine called ``name``, a :class:`primlib.Machine`."""
        from primlib.plant import Machine

        quoted = urllib.parse.quote(name, safe="")
        return Machine.from_dict(self.request("GET", f"/machines/{quoted}")["definition"])

    def add_machine(self, machine: Any, replace: bool = False) -> str:
        """Store a machine; ``"added"``, ``"replaced"`` or ``"unchanged"``."""
        d = machine if isinstance(machine, dict) else machine.to_dict()
        query = {"replace": "true"} if replace else None
        return self.request("POST", "/machines", d, query)["status"]

    # ------------------------------------------------------------------ primitives
    def primitives(self, machine: str | None = None) -> list[Any]:
        """Metadata of the stored primitives (:class:`primlib.store.PrimitiveInfo`)."""
        return [_info(d) for d in self.request("GET", "/primitives", query={"machine": machine})]

    def info(self, id: int) -> Any:
        return _info(self.request("GET", f"/primitives/{int(id)}"))

    def get(self, id: int) -> Any:
        """One primitive with its trajectory, points and signal."""
        from primlib.nurbs import Trajectory
        from primlib.store import Primitive, PrimitiveInfo

        d = self.request("GET", f"/primitives/{int(id)}", query={"arrays": "true"})
        info = _info(d)
        n = d["nurbs"]
        traj = Trajectory.from_definition(
            n["degree"], np.asarray(n["knots"]), np.asarray(n["ctrlpts"]),
            np.asarray(n["weights"]), n["duration"],
        )  # fmt: skip
        return Primitive(
            **{f: getattr(info, f) for f in PrimitiveInfo.__dataclass_fields__},
            trajectory=traj,
            points=np.asarray(d["points"], dtype=float),
            signal=np.asarray(d["signal"], dtype=float),
        )

    def signal(self, id: int) -> np.ndarray:
        """The stored input of one primitive, shape (n, d)."""
        return np.asarray(self.request("GET", f"/primitives/{int(id)}/signal")["u"], dtype=float)

    def add(
        self, path: Any, u: Any, machine: str, name: str | None = None, source: str | None = None
    ) -> int:
        """Store one primitive; its id (as :meth:`Library.add`: the new one, or the id of the
        identical primitive the machine already holds, then nothing is written). The server
        checks it as :meth:`Library.add` does."""
        u = np.asarray(u, dtype=float)
        if not np.isfinite(u).all():
            raise InputError("signal: expected finite numbers, got NaN or inf")
        body = {"machine": machine, "path": nurbs_of(path), "signal": u.tolist()}
        body.update({k: v for k, v in (("name", name), ("source", source)) if v is not None})
        return int(self.request("POST", "/primitives", body)["id"])

    def remove(self, id: int) -> None:
        """Delete one primitive."""
        self.request("DELETE", f"/primitives/{int(id)}")

    # ------------------------------------------------------------------ pipeline
    def _path_body(self, path: Any, machine: str, eps: float | None, kw: dict) -> dict:
        body = {"machine": machine, "path": nurbs_of(path), "eps": eps}
        if "time_scale" in kw:
            kw = {**kw, "time_scale": [float(x) for x in kw["time_scale"]]}
        body.update(kw)
        return {k: v for k, v in body.items() if v is not None}

    def match(self, path: Any, machine: str, eps: float | None = None, **kw: Any) -> Any:
        """Match a path against the machine's primitives (:meth:`Library.match`)."""
        d = self.request("POST", "/match", self._path_body(path, machine, eps, kw))
        return match_from_dict(d, path if hasattr(path, "definition") else None)

    def warm_start(self, path: Any, machine: str, eps: float | None = None, **kw: Any) -> Any:
        """First-iteration input for a path (:meth:`Library.warm_start`)."""
        d = self.request("POST", "/warm-start", self._path_body(path, machine, eps, kw))
        return warm_start_from_dict(d, path if hasattr(path, "definition") else None)


def _refusal(exc: urllib.error.HTTPError) -> PrimlibError:
    raw = exc.read()
    try:
        message = json.loads(raw)["error"]
    except (ValueError, KeyError, TypeError):
        message = raw.decode("utf-8", "replace").strip() or exc.reason
    status = exc.code
    if status == 404:
        return RemoteNotFoundError(message)
    if 400 <= status < 500:
        return RemoteInputError(message, status)
    return RemoteError(message, status)
