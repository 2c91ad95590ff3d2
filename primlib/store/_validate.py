"""Checks on what is about to be written: every item is checked before the first insert.

Each refusal is one sentence naming the item (``item 2 ('glyph-c'): ...``) and what was
expected; nothing is written when any item is refused.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib._rows import row_groups
from primlib.defaults import MAX_ABS_VALUE, MIN_EXTENT_REL

__all__ = [
    "check_id",
    "check_name",
    "check_item",
    "check_error_rms",
    "check_origin",
    "sample_points",
    "check_points",
    "content_hash",
]

# A path's duration must be a whole number of machine steps within this fraction of a step.
_STEP_RTOL = 1e-6
# A path that carries its own sample time must agree with the machine's to this relative.
_DT_RTOL = 1e-9


def check_id(id: Any) -> int:
    """The primitive id as an int (InputError for anything but an integer)."""
    if isinstance(id, bool) or not isinstance(id, (int, np.integer)):
        raise InputError(f"id: expected an integer primitive id, got {id!r}")
    return int(id)


def check_name(label: str, what: str, value: Any) -> None:
    """A name or source: None, or a non-empty printable string on one line."""
    if value is None:
        return
    if not isinstance(value, str):
        raise InputError(f"{label}: expected {what} to be a string, got {value!r}")
    if not value.strip() or not value.isprintable():
        raise InputError(
            f"{label}: expected {what} to be non-empty printable text on one line, got {value!r}"
        )


def _check_values(label: str, what: str, values: np.ndarray) -> None:
    """Finite and within +-MAX_ABS_VALUE (every sum primlib forms then stays finite)."""
    if not np.isfinite(values).all():
        raise InputError(f"{label}: expected a finite {what}, got NaN or inf")
    peak = float(np.max(np.abs(values))) if values.size else 0.0
    if peak > MAX_ABS_VALUE:
        raise InputError(
            f"{label}: expected {what} values within +-{MAX_ABS_VALUE:g}, got {peak:.6g}"
        )


def _label(i: int | None, name: Any) -> str:
    # add() names the primitive, add_many() the item too: "item 2 ('glyph-c'): ..."
    label = "primitive" if i is None else f"item {i}"
    if isinstance(name, str):
        label = f"primitive {name!r}" if i is None else f"{label} ({name!r})"
    return label


def _grid(label: str, path: Any, machine: str, dt: float, axes: list[str]) -> int:
    """The path's sample count on the machine's grid, after its dimension and dt checks."""
    d = len(axes)
    if path.dim != d:
        raise InputError(
            f"{label}: expected a {d}-D path for machine {machine!r} (axes "
            f"{', '.join(axes)}), got a {path.dim}-D path"
        )
    own_dt = getattr(path, "dt", None)
    if own_dt is not None and abs(float(own_dt) - dt) > _DT_RTOL * dt:
        raise InputError(
            f"{label}: expected a path sampled at the dt of machine {machine!r} ({dt:g} s), "
            f"got dt = {float(own_dt):g} s"
        )
    duration = float(path.duration)
    steps = duration / dt
    if not math.isfinite(steps) or steps < 1 or abs(steps - round(steps)) > _STEP_RTOL:
        raise InputError(
            f"{label}: expected a duration that is a whole number of steps of machine "
            f"{machine!r} (dt = {dt:g} s), got T = {duration:.9g} s"
        )
    n = int(round(steps)) + 1
    from primlib.nurbs import MIN_SAMPLES as MIN_ROWS  # nurbs loads scipy: only on writes

    if n < MIN_ROWS:
        raise InputError(
            f"{label}: expected at least {MIN_ROWS} samples on the grid of machine {machine!r} "
            f"(T >= {MIN_ROWS - 1} dt = {(MIN_ROWS - 1) * dt:g} s), got {n}"
        )
    return n


def check_origin(label: str, origin: Any, axes: Sequence[str]) -> np.ndarray | None:
    """None, or the absolute start position as a float array (d,): one finite coordinate
    per axis within +-MAX_ABS_VALUE; else an InputError naming ``label``."""
    if origin is None:
        return None
    d = len(axes)
    try:
        arr = np.asarray(origin, dtype=np.float64)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (d,):
        raise InputError(
            f"{label}: expected an origin of {d} coordinates (axes {', '.join(axes)}), "
            f"got {origin!r:.60}"
        )
    _check_values(label, "origin", arr)
    return arr


def check_error_rms(label: str, value: Any) -> float | None:
    """None, or a stored signal's error_rms as a float: finite, >= 0, within
    +-MAX_ABS_VALUE; else an InputError naming ``label``."""
    if value is None:
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        msg = f"{label}: expected error_rms as a number >= 0, got {value!r:.60}"
        raise InputError(msg) from None
    _check_values(label, "error_rms", np.array([out]))
    if out < 0:
        raise InputError(f"{label}: expected error_rms >= 0, got {out!r}")
    return out


def check_item(i: int | None, item: Any, machine: str, dt: float, axes: list[str]) -> dict:
    """Check one (path, u, name, source, origin, error_rms) item; return what the insert
    needs.

    Returns
    -------
    dict
        ``n``, ``u`` (n, d), ``path``, ``label``, ``name``, ``source``, ``origin`` ((d,)
        or None), ``error_rms`` (float or None), ``duration``, ``degree``, ``knots``,
        ``ctrlpts`` (m, d), ``weights``.
    """
    d = len(axes)
    if isinstance(item, (str, bytes)) or not isinstance(item, Sequence) or not 2 <= len(item) <= 6:
        raise InputError(
            f"item {i}: expected (path, u, name, source, origin, error_rms), got {item!r:.60}"
        )
    path, u = item[0], item[1]
    name = item[2] if len(item) > 2 else None
    source = item[3] if len(item) > 3 else None
    label = _label(i, name)
    check_name(label, "name", name)
    check_name(label, "source", source)
    origin = check_origin(label, item[4] if len(item) > 4 else None, axes)
    error_rms = check_error_rms(label, item[5] if len(item) > 5 else None)
    if not all(hasattr(path, a) for a in ("definition", "sample", "duration", "dim")):
        raise InputError(f"{label}: expected a Trajectory, got {type(path).__name__}")
    n = _grid(label, path, machine, dt, axes)
    try:
        u = np.asarray(u, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{label}: expected a numeric signal array, got {u!r:.60}") from None
    if u.shape != (n, d):
        raise InputError(
            f"{label}: expected a signal of shape ({n}, {d}) (the path's grid at "
            f"dt = {dt:g} s, T = {float(path.duration):g} s), got {u.shape}"
        )
    _check_values(label, "signal", u)
    definition = path.definition()
    ctrlpts = np.asarray(definition["ctrlpts"], dtype=np.float64)
    weights = np.asarray(definition["weights"], dtype=np.float64).ravel()
    knots = np.asarray(definition["knots"], dtype=np.float64).ravel()
    if ctrlpts.ndim != 2 or ctrlpts.shape[1] != d or len(weights) != len(ctrlpts):
        raise InputError(
            f"{label}: expected control points (m, {d}) and m weights, got "
            f"{ctrlpts.shape} and {weights.shape}"
        )
    _check_values(label, "path's control point", ctrlpts)
    return {
        "n": n,
        "u": u,
        "path": path,
        "label": label,
        "name": name,
        "source": source,
        "origin": origin,
        "error_rms": error_rms,
        "duration": float(path.duration),
        "degree": int(definition["degree"]),
        "knots": knots,
        "ctrlpts": ctrlpts,
        "weights": weights,
    }


def _sample_other(c: dict[str, Any], dt: float, d: int) -> np.ndarray:
    points = np.asarray(c["path"].sample(dt), dtype=np.float64)
    if points.shape != (c["n"], d):
        raise InputError(
            f"{c['label']}: expected the path to sample to ({c['n']}, {d}) finite points "
            f"at dt = {dt:g} s, got {points.shape}"
        )
    return points


def sample_points(
    checked: list[dict[str, Any]], dt: float, d: int, offsets: np.ndarray
) -> np.ndarray:
    """Every checked item's path on the machine grid, as one flat buffer (offsets in values).

    Trajectories go through :func:`primlib.nurbs.sample_many` (one sparse basis product per
    group of curves sharing degree, knots and sample count); other path objects through
    their own ``sample``. The samples are then checked (:func:`check_points`).
    """
    from primlib.nurbs import Trajectory, sample_many  # scipy: loaded on writes only

    native = [i for i, c in enumerate(checked) if isinstance(c["path"], Trajectory)]
    if len(native) == len(checked):
        out = sample_many([c["path"] for c in checked], dt)[0].reshape(-1)
    else:
        out = np.empty(int(offsets[-1]))
        if native:
            pts, _ = sample_many([checked[i]["path"] for i in native], dt)
            rows = np.array([checked[i]["n"] for i in native], dtype=np.int64)
            starts = offsets_of_rows(rows)
            for j, i in enumerate(native):
                out[offsets[i] : offsets[i + 1]] = pts[starts[j] : starts[j + 1]].ravel()
        for i in sorted(set(range(len(checked))) - set(native)):
            out[offsets[i] : offsets[i + 1]] = _sample_other(checked[i], dt, d).ravel()
    check_points(checked, out, dt, d, offsets)
    return out


def offsets_of_rows(rows: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.cumsum(rows)]).astype(np.int64)


def check_points(
    checked: list[dict[str, Any]], flat: np.ndarray, dt: float, d: int, offsets: np.ndarray
) -> None:
    """Sampled paths must be finite, within MAX_ABS_VALUE and move (a nonzero extent).

    The extent is the largest distance from the centroid; below ``MIN_EXTENT_REL`` times
    the largest coordinate magnitude (or 1 unit) the path does not move, and could neither
    be matched (its tolerance would be zero) nor learned.
    """
    if not np.isfinite(flat).all():
        bad = int(np.searchsorted(offsets, np.flatnonzero(~np.isfinite(flat))[0], side="right"))
        c = checked[bad - 1]
        raise InputError(
            f"{c['label']}: expected the path to sample to ({c['n']}, {d}) finite points at "
            f"dt = {dt:g} s, got NaN or inf"
        )
    if not checked:
        return
    pts = flat.reshape(-1, d)
    at = offsets // d  # each path's first sample, the total last
    starts, rows = at[:-1], np.diff(at)
    peak, extent = np.empty(len(checked)), np.empty(len(checked))
    # whole paths ~65,536 samples at a time: every pass over a group's samples runs in
    # cache, with no temporary the size of the batch (1,000 paths of 2,400 samples: 0.2 s
    # as ~10 small passes a path, 0.3 s in whole-batch passes that first-touch new memory)
    for g0, g1 in row_groups(at):
        r0, r1 = at[g0], at[g1]
        part, st, n = pts[r0:r1], starts[g0:g1] - r0, rows[g0:g1]
        peak[g0:g1] = np.maximum.reduceat(np.abs(flat[r0 * d : r1 * d]), st * d)
        dev = part - np.repeat(np.add.reduceat(part, st, axis=0) / n[:, None], n, axis=0)
        extent[g0:g1] = np.sqrt(np.maximum.reduceat(np.einsum("ij,ij->i", dev, dev), st))
    over = np.flatnonzero(peak > MAX_ABS_VALUE)
    still = np.flatnonzero(extent <= MIN_EXTENT_REL * np.maximum(peak, 1.0))
    first = min(np.concatenate([over, still, [len(checked)]]))
    if first == len(checked):
        return
    c = checked[first]
    _check_values(c["label"], "path", flat[offsets[first] : offsets[first + 1]])  # over: raises
    raise InputError(
        f"{c['label']}: expected a path that moves, got one that stays at "
        f"({', '.join(f'{x:.6g}' for x in pts[starts[first]])}) (extent {extent[first]:.3g})"
    )


def content_hash(machine: str, points: np.ndarray, signal: np.ndarray) -> str:
    """What makes two primitives the same: machine, path and signal on the machine's grid.

    A BLAKE2b digest (hex) of the machine's name, the shape, and the float64 bytes of the
    sampled path and signal; names, sources and times do not count.
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    signal = np.ascontiguousarray(signal, dtype=np.float64)
    h = hashlib.blake2b(digest_size=20)
    h.update(machine.encode())
    h.update(b"\0")
    h.update(np.array(points.shape, dtype=np.int64).tobytes())
    h.update(points.tobytes())
    h.update(signal.tobytes())
    return h.hexdigest()
