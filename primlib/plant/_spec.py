"""Checks of a machine's definition (constructor arguments or its JSON dictionary).

Every check raises :class:`primlib.InputError` with one sentence naming the field (the key,
and the axis where there is one), what was expected and what was received. Numbers must be
numbers: a JSON string such as ``"0.005"`` or a boolean is refused, not converted.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.defaults import MAX_ABS_VALUE

__all__ = [
    "DT_RANGE",
    "check_axes",
    "check_axis_map",
    "check_dt",
    "check_keys",
    "check_number",
    "read_note",
    "validate_pid",
    "validate_tf",
    "write_note",
]

# Sample times a machine may have, in seconds. Below 1e-7 s (10 MHz) no servo loop runs,
# and the zero-order hold puts every discrete pole within |p| dt < 1e-7 of 1, where the
# closed-loop polynomials lose most of their digits; above 10 s a "motion stage" is sampled
# slower than it moves (a 1 ms typo in seconds, e.g. 5 for 0.005, lands here too).
DT_RANGE: tuple[float, float] = (1e-7, 10.0)

# A continuous pole counts as "in the right half plane" when its real part exceeds this
# fraction of its magnitude (or of 1 for poles near the origin): roots of a polynomial with
# an exact zero constant term come out as +-1e-17, which is an integrator, not instability.
_RHP_TOL = 1e-9
_PID_KEYS = ("kp", "ki", "kd", "tf")


def _is_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def check_number(value: Any, what: str) -> float:
    """``value`` as a float: a real number (not a string or a bool), finite, within
    :data:`primlib.defaults.MAX_ABS_VALUE` in magnitude; else an InputError naming ``what``."""
    if not _is_number(value):
        raise InputError(f"{what}: expected a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(f"{what}: expected a finite number, got {out}")
    if abs(out) > MAX_ABS_VALUE:
        raise InputError(
            f"{what}: expected a finite number of magnitude <= {MAX_ABS_VALUE:g}, got {out:g}"
        )
    return out


def check_dt(dt: Any) -> float:
    """A sample time in seconds within :data:`DT_RANGE`."""
    if not _is_number(dt):
        raise InputError(f"dt: expected a sample time in seconds, got {dt!r}")
    dt = float(dt)
    if not math.isfinite(dt) or dt <= 0:
        raise InputError(f"dt: expected a finite sample time > 0 s, got {dt}")
    lo, hi = DT_RANGE
    if not lo <= dt <= hi:
        raise InputError(f"dt: expected a sample time between {lo:g} s and {hi:g} s, got {dt:g} s")
    return dt


def check_axes(axes: Any) -> tuple[str, ...]:
    """Distinct non-empty axis names, at least one."""
    if isinstance(axes, str) or not all(isinstance(a, str) and a for a in axes):
        raise InputError(f"axes: expected a list of non-empty axis names, got {axes!r}")
    axes = tuple(axes)
    if not axes:
        raise InputError("axes: expected at least one axis, got none")
    if len(set(axes)) != len(axes):
        raise InputError(f"axes: expected distinct axis names, got {list(axes)}")
    return axes


def check_axis_map(d: Any, axes: tuple[str, ...], what: str, item: str, *, required: bool) -> None:
    """``d`` maps axis names (only of ``axes``; all of them when ``required``) to ``item``s."""
    if not isinstance(d, Mapping):
        kind = "transfer function" if what == "plants" else "PID gains"
        raise InputError(f"{what}: expected a mapping axis -> {kind}, got {d!r}")
    missing = [a for a in axes if a not in d] if required else []
    if missing:
        raise InputError(f"{what}: expected {item} for axis {missing[0]!r}, got none")
    unknown = [a for a in d if a not in axes]
    if unknown:
        raise InputError(
            f"{what}: got {item} for unknown axis {unknown[0]!r} (axes are {list(axes)})"
        )


def _as_poly(value: Any, what: str) -> np.ndarray:
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        items = value.tolist()
    elif isinstance(value, (list, tuple)):
        items = list(value)
    else:
        raise InputError(f"{what}: expected a list of numbers, got {value!r}")
    if not items:
        raise InputError(f"{what}: expected a non-empty list of numbers, got {value!r}")
    if not all(_is_number(v) for v in items):
        raise InputError(f"{what}: expected a list of numbers, got {value!r}")
    arr = np.asarray(items, dtype=float)
    if arr.ndim != 1:
        raise InputError(f"{what}: expected a non-empty list of numbers, got {value!r}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what}: expected finite coefficients, got {arr.tolist()}")
    if np.max(np.abs(arr)) > MAX_ABS_VALUE:
        raise InputError(
            f"{what}: expected coefficients of magnitude <= {MAX_ABS_VALUE:g}, got {arr.tolist()}"
        )
    return arr


def validate_tf(axis: str, spec: Any) -> tuple[np.ndarray, np.ndarray]:
    """Check one axis's continuous transfer function; return (num, den) with den[0] != 0."""
    if isinstance(spec, Mapping):
        extra = set(spec) - {"num", "den"}
        if extra or "num" not in spec or "den" not in spec:
            raise InputError(
                f"plant of axis {axis!r}: expected keys num and den, got {sorted(spec)}"
            )
        num_raw, den_raw = spec["num"], spec["den"]
    elif isinstance(spec, (tuple, list)) and len(spec) == 2:
        num_raw, den_raw = spec
    else:
        raise InputError(
            f"plant of axis {axis!r}: expected (num, den) or {{'num': ..., 'den': ...}}, "
            f"got {spec!r}"
        )
    num = _as_poly(num_raw, f"numerator of axis {axis!r}")
    den = _as_poly(den_raw, f"denominator of axis {axis!r}")
    if den[0] == 0.0:
        raise InputError(
            f"denominator of axis {axis!r}: expected a non-zero leading coefficient, "
            f"got {den.tolist()}"
        )
    num_trim = np.trim_zeros(num, "f")
    if num_trim.size == 0:
        raise InputError(f"numerator of axis {axis!r}: expected a non-zero polynomial, got zeros")
    if len(num_trim) > len(den):
        raise InputError(
            f"plant of axis {axis!r}: expected a proper transfer function (numerator degree "
            f"<= denominator degree {len(den) - 1}), got numerator degree {len(num_trim) - 1}"
        )
    if len(den) > 1:
        poles = np.roots(den)
        unstable = poles.real > _RHP_TOL * np.maximum(1.0, np.abs(poles))
        if np.any(unstable):
            bad = ", ".join(f"{p:.6g}" for p in poles[unstable])
            raise InputError(
                f"plant of axis {axis!r}: expected no pole with positive real part, got {bad}"
            )
    return num_trim, den


def validate_pid(axis: str, spec: Any) -> dict[str, float]:
    """Check one axis's PID gains ``{"kp", "ki", "kd", "tf"}`` (missing ones are 0)."""
    if not isinstance(spec, Mapping):
        raise InputError(
            f"feedback of axis {axis!r}: expected {{'kp': .., 'ki': .., 'kd': ..}}, got {spec!r}"
        )
    extra = set(spec) - set(_PID_KEYS)
    if extra:
        raise InputError(
            f"feedback of axis {axis!r}: expected keys among kp, ki, kd, tf, "
            f"got unknown {sorted(extra)}"
        )
    out = {
        key: check_number(spec.get(key, 0.0), f"feedback {key} of axis {axis!r}")
        for key in _PID_KEYS
    }
    if out["tf"] < 0:
        raise InputError(
            f"feedback tf of axis {axis!r}: expected a filter time constant >= 0, got {out['tf']}"
        )
    return out


def check_start(start: Any, dim: int) -> np.ndarray:
    """An absolute start position: ``dim`` finite coordinates (None: the origin, zeros)."""
    if start is None:
        return np.zeros(dim)
    s = np.asarray(start, dtype=float).reshape(-1)
    if s.shape != (dim,) or not np.all(np.isfinite(s)):
        raise InputError(f"start: expected {dim} finite coordinates (user units), got {start!r}")
    return s


def check_kind(
    d: Any, kind: str, allowed: set[str], required: tuple[str, ...]
) -> Mapping[str, Any]:
    """A machine dictionary of ``kind`` (a missing ``"kind"`` is taken as it) with only
    ``allowed`` keys and every ``required`` one; else one sentence why not."""
    if not isinstance(d, Mapping):
        raise InputError(f"machine: expected a JSON object, got {type(d).__name__}")
    if d.get("kind", kind) != kind:
        raise InputError(f"machine kind: expected {kind!r}, got {d.get('kind')!r}")
    check_keys(d, allowed, required)
    return d


def check_keys(d: Mapping[str, Any], allowed: set[str], required: tuple[str, ...]) -> None:
    """A machine dictionary has only ``allowed`` keys and every ``required`` one."""
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise InputError(
            f"machine: got unknown key {unknown[0]!r} (expected keys among "
            f"{', '.join(sorted(allowed))})"
        )
    for key in required:
        if key not in d:
            raise InputError(f"machine: expected key {key!r}, got none")


def read_note(machine, d: Mapping[str, Any]):
    """Attach the dictionary's optional free-text ``note`` to a machine built from it."""
    note = d.get("note")
    if note is not None:
        if not isinstance(note, str):
            raise InputError(f"note: expected a string, got {note!r}")
        machine._note = note
    return machine


def write_note(machine, out: dict[str, Any]) -> dict[str, Any]:
    """Add the machine's note, if it has one, to its JSON-ready dictionary."""
    note = getattr(machine, "_note", None)
    if note is not None:
        out["note"] = note
    return out
