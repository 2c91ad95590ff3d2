"""Request bodies to library arguments: paths, signals and options, checked.

Pure functions (no HTTP): each takes the decoded body and the machine and returns what the
library takes, or raises :class:`BadRequest` (the request cannot be understood: a field
missing, unknown or of the wrong JSON type; HTTP 400) or :class:`primlib.InputError` (it is
understood and wrong: a shape, a time step, NaN; HTTP 422), with the CLI's sentence where
the CLI has one, naming the field where the CLI names the file or option.

A path is given as one of

* ``[[x, y, z], ...]``: points at t = 0, dt, 2 dt, ... (``dt`` beside it, default the
  machine's), fitted like ``primlib ingest`` / ``primlib match`` fit a CSV file;
* ``"t,x,y,z\\n0,..."``: CSV text in the path file format;
* ``{"degree", "knots", "ctrlpts", "weights", "duration"}``: the NURBS definition
  (:meth:`primlib.nurbs.Trajectory.definition`), taken as it is (what the Python client
  sends, so a remote result equals the local one).

A signal is ``[[ux, uy, uz], ...]`` on the path's grid or CSV text in the signal format.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from primlib._errors import InputError, PrimlibError

__all__ = [
    "BadRequest",
    "fields",
    "path_of",
    "signal_of",
    "match_options",
    "warm_options",
    "optional_str",
    "as_bool",
    "series_options",
    "trial_of",
    "measured_of",
    "SERIES_FIELDS",
]

# Relative tolerance between a CSV file's time step and the machine's dt (as `ingest`).
_DT_RTOL = 1e-6
_NURBS_KEYS = ("degree", "knots", "ctrlpts", "weights", "duration")
_ROTATIONS = ("full", "z", "none")


class BadRequest(PrimlibError, ValueError):
    """A request that cannot be understood (HTTP 400)."""


def fields(body: Any, required: tuple[str, ...], optional: tuple[str, ...]) -> dict[str, Any]:
    """The body's fields, checked: a JSON object with every required name and no others."""
    if not isinstance(body, Mapping):
        raise BadRequest(f"body: expected a JSON object, got {type(body).__name__}")
    unknown = sorted(set(body) - set(required) - set(optional))
    if unknown:
        allowed = ", ".join((*required, *optional))
        raise BadRequest(f"body: unknown field {unknown[0]!r}; expected fields {allowed}")
    missing = [k for k in required if body.get(k) is None]
    if missing:
        raise BadRequest(f"body: expected field {missing[0]!r}, got none")
    return dict(body)


def optional_str(body: Mapping[str, Any], key: str) -> str | None:
    value = body.get(key)
    if value is not None and not isinstance(value, str):
        raise BadRequest(f"{key}: expected a string, got {type(value).__name__}")
    return value


def as_bool(key: str, value: Any) -> bool:
    """A JSON boolean, or a query string's true/false/1/0."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ("true", "1", "false", "0"):
        return value.lower() in ("true", "1")
    raise BadRequest(f"{key}: expected true or false, got {value!r}")


def _number(key: str, value: Any) -> float:
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise BadRequest(f"{key}: expected a number, got {value!r}") from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise BadRequest(f"{key}: expected a number, got {type(value).__name__}")
    return float(value)


def _rows(key: str, value: Any, d: int, what: str) -> np.ndarray:
    """A JSON list of rows as an (n, d) float array."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{key}: expected a list of rows of {d} numbers") from None
    if a.ndim != 2 or a.shape[1] != d:
        raise InputError(f"{key}: expected {what} of shape (n, {d}), got {a.shape}")
    if not np.isfinite(a).all():
        raise InputError(f"{key}: expected finite numbers, got NaN or inf")
    return a


def path_of(
    body: Mapping[str, Any], machine: Any, key: str = "path", own_dt: bool = False
) -> tuple[Any, np.ndarray]:
    """The path a request names, as a Trajectory, with its time grid.

    Parameters
    ----------
    body : mapping
        The request's fields: ``key`` (points, CSV text or NURBS) and optional ``dt``.
    machine : primlib.plant.Machine
        The machine it is for (its dt and axes).
    own_dt : bool
        CSV text is fitted at its own sample time (as ``primlib trials start`` reads a
        file: the path is sampled on the machine's grid afterwards); by default it must be
        sampled at the machine's dt (as ``primlib ingest`` requires of a stored path).

    Returns
    -------
    trajectory : Trajectory
    t : array, shape (n,)
        The grid the path was given on (the machine's for a NURBS definition).
    """
    from primlib.nurbs import Trajectory

    value = body.get(key)
    d, dt = machine.dim, machine.dt
    if isinstance(value, Mapping):
        nurbs = fields(value, _NURBS_KEYS[:3], ("weights", "duration"))
        duration = _number(f"{key}.duration", nurbs.get("duration", 1.0))
        try:
            traj = Trajectory.from_definition(
                int(_number(f"{key}.degree", nurbs["degree"])),
                np.asarray(nurbs["knots"], dtype=np.float64),
                np.asarray(nurbs["ctrlpts"], dtype=np.float64),
                None if nurbs.get("weights") is None else np.asarray(nurbs["weights"], np.float64),
                duration,
            )
        except (TypeError, ValueError) as exc:
            raise InputError(f"{key}: {exc}") from None
        t = np.arange(int(round(traj.duration / dt)) + 1) * dt
    elif isinstance(value, str):
        from primlib.io import parse_path_csv

        t, points = parse_path_csv(value, key)
        step = (t[-1] - t[0]) / (len(t) - 1)
        if not own_dt and abs(step - dt) > _DT_RTOL * dt:
            raise InputError(
                f"{key}: expected samples at the dt of machine '{machine.name}' ({dt:g} s), "
                f"got dt = {step:.9g} s"
            )
        traj = _fit(key, points, step if own_dt else dt)
    elif isinstance(value, list):
        step = _number("dt", body["dt"]) if body.get("dt") is not None else dt
        if not (math.isfinite(step) and step > 0):
            raise InputError(f"dt: expected a sample time > 0, got {step:g}")
        points = _rows(key, value, d, "points")
        t = np.arange(len(points)) * step
        traj = _fit(key, points, step)
    else:
        raise BadRequest(
            f"{key}: expected points (a list of rows), CSV text or a NURBS definition, "
            f"got {type(value).__name__}"
        )
    if traj.dim != d:
        raise InputError(
            f"{key}: expected a {d}-D path for machine {machine.name!r}, got {traj.dim}-D"
        )
    return traj, t


def _fit(key: str, points: np.ndarray, dt: float) -> Any:
    from primlib.nurbs import Trajectory

    try:
        return Trajectory.from_samples(points, dt)
    except InputError as exc:
        raise InputError(f"{key}: {exc}") from None


def signal_of(body: Mapping[str, Any], machine: Any, t: np.ndarray) -> np.ndarray:
    """The signal a request carries, shape (n, d), on the path's grid ``t``."""
    value = body.get("signal")
    d = machine.dim
    if isinstance(value, str):
        from primlib.io import parse_signal_csv

        _, u = parse_signal_csv(value, "signal", t=t)
        if u.shape[1] != d:
            raise InputError(
                f"signal: expected {d} signal columns for machine '{machine.name}', "
                f"got {u.shape[1]}"
            )
        return u
    if isinstance(value, list):
        return _rows("signal", value, d, "a signal")
    raise BadRequest(f"signal: expected a list of rows or CSV text, got {type(value).__name__}")


MATCH_FIELDS = ("eps", "rotation", "time_scale", "min_segment")
WARM_FIELDS = (*MATCH_FIELDS, "band", "method", "refine", "correction", "origin", "greybox")


def match_options(body: Mapping[str, Any], traj: Any) -> tuple[float, dict[str, Any]]:
    """``eps`` (default: the CLI's, relative to the path's extent) and the matcher's options."""
    from primlib.match import default_eps

    eps = body.get("eps")
    if eps is None:
        eps = default_eps(traj)
    else:
        eps = _number("eps", eps)
        if not (math.isfinite(eps) and eps > 0):
            raise InputError(f"eps: expected a tolerance > 0, got {eps:g}")
    kw: dict[str, Any] = {}
    rotation = body.get("rotation")
    if rotation is not None:
        if rotation not in _ROTATIONS:
            raise InputError(f"rotation: expected one of full, z, none, got {rotation!r}")
        kw["rotation"] = rotation
    scale = body.get("time_scale")
    if scale is not None:
        if isinstance(scale, str):
            scale = scale.split(",")
        if not isinstance(scale, (list, tuple)) or len(scale) != 2:
            raise BadRequest(f"time_scale: expected two numbers (low, high), got {scale!r}")
        kw["time_scale"] = (_number("time_scale", scale[0]), _number("time_scale", scale[1]))
    if body.get("min_segment") is not None:
        kw["min_segment"] = _number("min_segment", body["min_segment"])
    return eps, kw


def warm_options(body: Mapping[str, Any], traj: Any) -> tuple[float, dict[str, Any]]:
    """As :func:`match_options`, plus the warm start's own options."""
    eps, kw = match_options(body, traj)
    if body.get("band") is not None:
        kw["band"] = _number("band", body["band"])
    for key in ("method", "correction"):
        if body.get(key) is not None:
            kw[key] = optional_str(body, key)
    for key in ("refine", "greybox"):
        if body.get(key) is not None:
            kw[key] = as_bool(key, body[key])
    origin = body.get("origin")
    if origin is not None:
        if isinstance(origin, str):
            origin = origin.split(",")
        if not isinstance(origin, (list, tuple)):
            raise BadRequest(f"origin: expected a list of coordinates, got {origin!r}")
        kw["origin"] = [_number("origin", v) for v in origin]
    return eps, kw


# ---------------------------------------------------------------------------- trial series
LAWS = ("p", "pd", "pid", "norm-optimal")
SERIES_FIELDS = (
    "first", "eps", "name", "law", "plain", "noise_aware", "average", "margin", "q_cutoff",
)  # fmt: skip


def _integer(key: str, value: Any) -> int:
    if isinstance(value, str) and value.strip().lstrip("+-").isdigit():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int):
        raise BadRequest(f"{key}: expected an integer, got {value!r}")
    return value


def series_options(body: Mapping[str, Any]) -> tuple[str, float | None, str | None, dict]:
    """``(first, eps, name, options)`` of a series start.

    ``first`` is ``"warm"`` (default), ``"inverse"`` or ``"cold"``. The law's options are
    those of ``primlib trials start``: ``law``, ``plain`` (or its opposite, the Python
    API's ``noise_aware``), ``average``, ``margin``, ``q_cutoff``. Only the options given
    are returned: the others take :func:`primlib.trials.start`'s defaults (so a remote
    start equals a local one), except that ``plain`` averages 1 trial unless told, as the
    CLI's ``--plain``. The learner checks the values before anything is written.
    """
    first = optional_str(body, "first") or "warm"
    eps = body.get("eps")
    if eps is not None:
        eps = _number("eps", eps)
        if not (math.isfinite(eps) and eps > 0):
            raise InputError(f"eps: expected a match tolerance > 0, got {eps:g}")
    options: dict[str, Any] = {}
    if body.get("law") is not None:
        options["law"] = optional_str(body, "law")
        if options["law"] not in LAWS:
            raise InputError(f"law: expected one of {', '.join(LAWS)}, got {options['law']!r}")
    plain = None if body.get("plain") is None else as_bool("plain", body["plain"])
    aware = None if body.get("noise_aware") is None else as_bool("noise_aware", body["noise_aware"])
    if plain is not None and aware is not None and plain == aware:
        raise BadRequest(f"plain: contradicts noise_aware ({plain} and {aware}); give one of them")
    if plain is not None or aware is not None:
        options["noise_aware"] = aware if aware is not None else not plain
    if plain and body.get("average") is None:
        options["average"] = 1
    if body.get("average") is not None:
        options["average"] = _integer("average", body["average"])
        if options["average"] < 1:
            raise InputError(f"average: expected an integer >= 1, got {options['average']}")
    for key in ("margin", "q_cutoff"):
        if body.get(key) is not None:
            options[key] = _number(key, body[key])
    return first, eps, optional_str(body, "name"), options


def trial_of(body: Mapping[str, Any]) -> int:
    """The ``trial`` a step says it measured (required: a step for another trial is refused)."""
    return _integer("trial", body["trial"])


def measured_of(value: Any, n: int, d: int, dt: float) -> np.ndarray:
    """A step's measured positions: rows, or path CSV text checked as ``trials step`` checks
    its ``--measured`` file (axes, time step, length), naming ``measured``."""
    if isinstance(value, str):
        from primlib.io import parse_path_csv

        t, y = parse_path_csv(value, "measured")
        if y.shape[1] != d:
            raise InputError(f"measured: expected measured positions on {d} axes, got {y.shape[1]}")
        step = (t[-1] - t[0]) / (len(t) - 1)
        if abs(step - dt) > _DT_RTOL * dt:
            raise InputError(
                f"measured: expected samples every dt = {dt:g} s, got dt = {step:.9g} s"
            )
        if len(t) != n:
            raise InputError(
                f"measured: expected a trial of {n} samples (T = {(n - 1) * dt:g} s), got "
                f"{len(t)} (T = {t[-1]:.9g} s)"
            )
        return y
    if isinstance(value, list):
        try:
            return np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            raise InputError(f"measured: expected a list of rows of {d} numbers") from None
    raise BadRequest(f"measured: expected a list of rows or CSV text, got {type(value).__name__}")
