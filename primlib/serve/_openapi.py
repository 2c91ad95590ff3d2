"""The OpenAPI 3.1 description of the endpoints, served at ``/openapi.json``.

Written out by hand beside the routes (a test checks that both list the same endpoints):
the bodies are plain JSON whose large arrays are lists of rows or CSV text, which a
schema says in a few lines.
"""

from __future__ import annotations

from typing import Any

__all__ = ["schema", "DESCRIPTIONS"]

_ROWS = {"type": "array", "items": {"type": "array", "items": {"type": "number"}}}
_NURBS = {
    "type": "object",
    "required": ["degree", "knots", "ctrlpts"],
    "properties": {
        "degree": {"type": "integer"},
        "knots": {"type": "array", "items": {"type": "number"}},
        "ctrlpts": _ROWS,
        "weights": {"type": ["array", "null"], "items": {"type": "number"}},
        "duration": {"type": "number", "description": "seconds"},
    },
}
_PATH = {
    "description": "Points at t = 0, dt, ... (rows of x, y[, z]); path CSV text "
    "(t,x,y[,z]); or a NURBS definition whose parameter is normalised time.",
    "oneOf": [_ROWS, {"type": "string"}, _NURBS],
}
_SIGNAL = {
    "description": "Rows of ux, uy[, uz] on the path's grid, or signal CSV text.",
    "oneOf": [_ROWS, {"type": "string"}],
}
_MATCH_PROPS = {
    "machine": {"type": "string"},
    "path": _PATH,
    "dt": {"type": "number", "description": "sample time of points (default the machine's)"},
    "eps": {"type": "number", "description": "Kabsch RMSD tolerance (default 3e-4 of extent)"},
    "rotation": {"enum": ["full", "z", "none"]},
    "time_scale": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2},
    "min_segment": {"type": "number", "description": "shortest match worth a junction, s"},
}
_WARM_PROPS = {
    **_MATCH_PROPS,
    "band": {"type": "number", "description": "transition band, seconds"},
    "method": {"enum": ["auto", "model", "direct"]},
    "refine": {"type": "boolean"},
    "correction": {"enum": ["error", "input", "output", "junction", "none"]},
    "origin": {
        "type": "array",
        "items": {"type": "number"},
        "description": "where the path starts on the machine (absolute): ripple terms there",
    },
    "greybox": {"type": "boolean", "description": "use the grey-box model (default true)"},
}


def _body(props: dict[str, Any], required: list[str], csv: bool = False) -> dict[str, Any]:
    content: dict[str, Any] = {
        "application/json": {
            "schema": {"type": "object", "required": required, "properties": props}
        }
    }
    if csv:
        content["text/csv"] = {
            "schema": {"type": "string", "description": "the CSV file; fields as query parameters"}
        }
    return {"required": True, "content": content}


# (method, path) -> (summary, request body or None, success statuses, comma-separated)
DESCRIPTIONS: dict[tuple[str, str], tuple[str, dict[str, Any] | None, str]] = {
    ("GET", "/health"): ("Liveness (no token needed); 503 while shutting down.", None, "200"),
    ("GET", "/version"): ("primlib version and the library's schema version.", None, "200"),
    ("GET", "/metrics"): ("Prometheus text: request counts, latency histograms.", None, "200"),
    ("GET", "/openapi.json"): ("This description.", None, "200"),
    ("GET", "/machines"): ("Machines: name, kind, dt, axes, primitive count.", None, "200"),
    ("POST", "/machines"): (
        "Add a machine (body: machine JSON; ?replace=true overwrites). 409 when another "
        "machine of that name exists.",
        {"required": True, "content": {"application/json": {"schema": {"type": "object"}}}},
        "201",
    ),
    ("GET", "/machines/{name}"): ("One machine with its definition.", None, "200"),
    ("GET", "/primitives"): ("Primitives' metadata (?machine=NAME).", None, "200"),
    ("POST", "/primitives"): (
        "Store a path with its learned input: 201 with the new id; 200 with the id of the "
        "identical primitive (same machine, path and signal) already stored, nothing written "
        '("created": false).',
        _body(
            {
                "machine": {"type": "string"},
                "path": _PATH,
                "signal": _SIGNAL,
                "name": {"type": "string"},
                "source": {"type": "string"},
                "dt": {"type": "number"},
            },
            ["machine", "path", "signal"],
        ),
        "201,200",
    ),
    ("GET", "/primitives/{id}"): (
        "One primitive: metadata, NURBS, signal size (?arrays=true adds points, signal).",
        None,
        "200",
    ),
    ("DELETE", "/primitives/{id}"): ("Remove a primitive (ids are never reused).", None, "200"),
    ("GET", "/primitives/{id}/signal"): (
        "The stored input as JSON {t, u}, or CSV with Accept: text/csv.",
        None,
        "200",
    ),
    ("POST", "/match"): (
        "Cut a path into pieces of stored primitives.",
        _body(_MATCH_PROPS, ["machine", "path"], csv=True),
        "200",
    ),
    ("POST", "/warm-start"): (
        "First-trial input u0 for a path, with what each segment used (CSV u0 with "
        "Accept: text/csv).",
        _body(_WARM_PROPS, ["machine", "path"], csv=True),
        "200",
    ),
}

_SERIES_PROPS = {
    "machine": {"type": "string"},
    "path": _PATH,
    "dt": {"type": "number", "description": "sample time of points (default the machine's)"},
    "first": {"enum": ["warm", "inverse", "cold"], "description": "first input (default warm)"},
    "eps": {"type": "number", "description": "match tolerance (default 3e-4 of extent)"},
    "name": {"type": "string"},
    "law": {"enum": ["p", "pd", "pid", "norm-optimal"]},
    "plain": {"type": "boolean", "description": "learn from the last error only"},
    "noise_aware": {"type": "boolean", "description": "the opposite of plain (default true)"},
    "average": {"type": "integer", "minimum": 1, "description": "default 8, plain 1"},
    "margin": {"type": "number", "description": "stop rule margin (default 0.2)"},
    "q_cutoff": {"type": ["number", "null"], "description": "fixed Q cut-off, Hz"},
}
_STEP_PROPS = {
    "trial": {"type": "integer", "description": "the pending trial this output was measured on"},
    "measured": {
        "description": "Measured positions, absolute: rows on the series' grid, or path CSV text.",
        "oneOf": [_ROWS, {"type": "string"}],
    },
}
DESCRIPTIONS.update(
    {
        ("GET", "/trials"): ("Trial series (?machine=NAME): state, steps, last rms.", None, "200"),
        ("POST", "/trials"): (
            "Start a trial series: its id and trial 0's input (CSV with Accept: text/csv).",
            _body(_SERIES_PROPS, ["machine", "path"], csv=True),
            "201",
        ),
        ("GET", "/trials/{id}"): (
            "A series' trials, errors and the stop rule's verdict.",
            None,
            "200",
        ),  # fmt: skip
        ("GET", "/trials/{id}/input"): (
            "The pending trial's input again (409 when finished).",
            None,
            "200",
        ),
        ("POST", "/trials/{id}/step"): (
            "Record the pending trial's measured output; the next input. 409 when 'trial' is "
            "not the pending one (another step came first) or the series is finished.",
            _body(_STEP_PROPS, ["trial", "measured"], csv=True),
            "200",
        ),
        ("POST", "/trials/{id}/finish"): (
            "Store the converged input as a primitive (409 unless converged or force).",
            {
                "required": False,
                "content": {
                    "application/json": {
                        "schema": {
                            "type": "object",
                            "properties": {
                                "name": {"type": "string"},
                                "force": {"type": "boolean"},
                            },
                        }
                    }
                },
            },
            "201",
        ),
    }
)

_ERROR = {
    "description": "Refused: {error: one sentence}",
    "content": {
        "application/json": {
            "schema": {"type": "object", "properties": {"error": {"type": "string"}}}
        }
    },
}


def schema() -> dict[str, Any]:
    """The OpenAPI document."""
    import primlib

    paths: dict[str, Any] = {}
    for (method, path), (summary, body, ok) in DESCRIPTIONS.items():
        op: dict[str, Any] = {
            "summary": summary,
            "responses": {
                **{code: {"description": "done"} for code in ok.split(",")},
                **{c: _ERROR for c in ("400", "401", "403", "404", "409", "413", "422")},
            },
        }
        params = [
            {"name": name, "in": "path", "required": True, "schema": {"type": kind}}
            for name, kind in (("id", "integer"), ("name", "string"))
            if "{" + name + "}" in path
        ]
        if params:
            op["parameters"] = params
        if body is not None:
            op["requestBody"] = body
        paths.setdefault(path, {})[method.lower()] = op
    return {
        "openapi": "3.1.0",
        "info": {"title": "primlib", "version": primlib.__version__},
        "components": {
            "securitySchemes": {"bearer": {"type": "http", "scheme": "bearer"}},
        },
        "security": [{"bearer": []}],
        "paths": paths,
    }
