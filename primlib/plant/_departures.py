"""The departures of a realistic machine from its linear model: keys, checks, scaling.

Per axis, in the machine's own units: input units for forces (``coulomb``, ``ripple``,
``disturbance``), input units per (length unit / s) for ``viscous``, the user's length unit
for ``noise``, ``ripple_pitch`` and ``stribeck_velocity`` (per second), Hz for
``disturbance_bandwidth`` and ``resonance_hz``. Every key is optional; its default switches
that departure off (or is the value it takes once switched on).

"x % of the typical input" (:func:`scale_departures`): with ``U`` the typical input of an
axis (the RMS of the inputs it runs, input units) and ``V`` its typical speed (the RMS of
its velocity, length units per second; :func:`typical_scales` measures both), a fraction
``p`` of a force-like departure means ``p U`` (Coulomb level, ripple amplitude,
disturbance std) and of ``viscous`` the coefficient ``p U / V`` (the viscous force at the
typical speed is ``p U``).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.plant._spec import check_number

__all__ = [
    "DEPARTURE_KEYS",
    "FRACTION_KEYS",
    "check_count",
    "validate_departures",
    "scale_departures",
    "typical_scales",
]

# key -> (default, lower bound, bound is strict)
DEPARTURE_KEYS: dict[str, tuple[float, float, bool]] = {
    "coulomb": (0.0, 0.0, False),
    "static_ratio": (1.0, 1.0, False),
    "stribeck_velocity": (1.0, 0.0, True),
    "viscous": (0.0, 0.0, False),
    "ripple": (0.0, 0.0, False),
    "ripple_pitch": (5.0, 0.0, True),
    "ripple_phase": (0.0, -math.inf, False),
    "disturbance": (0.0, 0.0, False),
    "disturbance_bandwidth": (2.0, 0.0, True),
    "noise": (0.0, 0.0, False),
    "resonance_hz": (0.0, 0.0, False),
    "resonance_damping": (0.05, 0.0, True),
}

# keys read as fractions of the typical input by scale_departures
FRACTION_KEYS = ("coulomb", "ripple", "disturbance", "viscous")


def _validate_axis(axis: str, spec: Any) -> dict[str, float]:
    if not isinstance(spec, Mapping):
        raise InputError(
            f"departures of axis {axis!r}: expected a mapping of parameters, got {spec!r}"
        )
    unknown = sorted(set(spec) - set(DEPARTURE_KEYS))
    if unknown:
        raise InputError(
            f"departures of axis {axis!r}: got unknown parameter {unknown[0]!r} "
            f"(expected among {', '.join(DEPARTURE_KEYS)})"
        )
    out = {}
    for key, (default, low, strict) in DEPARTURE_KEYS.items():
        if key not in spec:
            out[key] = default
            continue
        value = check_number(spec[key], f"departure {key} of axis {axis!r}")
        if value < low or (strict and value == low):
            sign = ">" if strict else ">="
            raise InputError(
                f"departure {key} of axis {axis!r}: expected a number {sign} {low:g}, got {value}"
            )
        out[key] = value
    return out


def validate_departures(departures: Any, axes: tuple[str, ...]) -> dict[str, dict[str, float]]:
    """Per axis of ``axes`` the complete, checked departure parameters.

    ``departures`` maps (some of) the axes to mappings of :data:`DEPARTURE_KEYS`; None or a
    missing axis means no departure on it. Raises InputError naming the axis and the key.
    """
    if departures is None:
        departures = {}
    if not isinstance(departures, Mapping):
        raise InputError(f"departures: expected a mapping axis -> parameters, got {departures!r}")
    unknown = [a for a in departures if a not in axes]
    if unknown:
        raise InputError(
            f"departures: got parameters for unknown axis {unknown[0]!r} (axes are {list(axes)})"
        )
    return {a: _validate_axis(a, departures.get(a, {})) for a in axes}


def check_count(value: Any, what: str, low: int) -> int:
    """An integer >= ``low`` (not a bool, not a float), else an InputError naming ``what``."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Integral, np.integer)):
        raise InputError(f"{what}: expected an integer >= {low}, got {value!r}")
    if value < low:
        raise InputError(f"{what}: expected an integer >= {low}, got {value}")
    return int(value)


def _per_axis(value: Any, d: int, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(d, float(arr))
    if arr.shape != (d,) or not np.all(np.isfinite(arr)):
        raise InputError(f"{what}: expected a finite number or {d} of them, got {value!r}")
    return arr


def scale_departures(
    axes: Sequence[str],
    departures: Mapping[str, Any],
    typical_input: Any = None,
    typical_velocity: Any = None,
) -> dict[str, dict[str, float]]:
    """Per-axis departures from keyword values, each a number or one per axis.

    Parameters
    ----------
    axes : sequence of str
    departures : mapping
        Keys of :data:`DEPARTURE_KEYS`, each a number (all axes) or a sequence (per axis).
    typical_input : float or array, shape (d,), optional
        When given, the keys of :data:`FRACTION_KEYS` are fractions (module docstring):
        ``coulomb``, ``ripple`` and ``disturbance`` of it, ``viscous`` such that the
        viscous force at ``typical_velocity`` is that fraction of it.
    typical_velocity : float or array, shape (d,), optional
        Needed with ``typical_input`` and a non-zero ``viscous``.

    Returns
    -------
    dict
        Axis -> {key: absolute value}, for :class:`RealisticMachine`'s ``departures``.
    """
    d = len(axes)
    unknown = sorted(set(departures) - set(DEPARTURE_KEYS))
    if unknown:
        raise InputError(
            f"departures: got unknown parameter {unknown[0]!r} "
            f"(expected among {', '.join(DEPARTURE_KEYS)})"
        )
    cols = {k: _per_axis(v, d, k) for k, v in departures.items()}
    if typical_input is not None:
        big_u = _per_axis(typical_input, d, "typical_input")
        for key in ("coulomb", "ripple", "disturbance"):
            if key in cols:
                cols[key] = cols[key] * big_u
        if "viscous" in cols and np.any(cols["viscous"] != 0):
            if typical_velocity is None:
                raise InputError(
                    "typical_velocity: expected the typical speed to scale viscous, got None"
                )
            big_v = _per_axis(typical_velocity, d, "typical_velocity")
            if np.any(big_v <= 0):
                raise InputError(f"typical_velocity: expected speeds > 0, got {big_v.tolist()}")
            cols["viscous"] = cols["viscous"] * big_u / big_v
    return {a: {k: float(c[i]) for k, c in cols.items()} for i, a in enumerate(axes)}


def typical_scales(machine, inputs: Any) -> tuple[np.ndarray, np.ndarray]:
    """Typical input and speed of each axis over a set of inputs (the scaling convention).

    Parameters
    ----------
    machine : Machine
        Its nominal linear model (``nominal()`` where there is one) gives the motion.
    inputs : array, shape (n, d), or a sequence of them
        The inputs the machine typically runs (e.g. the nominal inverse of the paths).

    Returns
    -------
    typical_input : array, shape (d,)
        RMS over all samples of the inputs, per axis (input units).
    typical_velocity : array, shape (d,)
        RMS of the nominal output's velocity (central differences), length units per s.
    """
    model = machine.nominal() if hasattr(machine, "nominal") else machine
    arrays = [inputs] if isinstance(inputs, np.ndarray) else list(inputs)
    if not arrays:
        raise InputError("inputs: expected at least one input array, got none")
    us = [model.check_signal(u, "inputs") for u in arrays]
    vs = [np.gradient(model.simulate(u), model.dt, axis=0) for u in us if len(u) > 1]
    u_all = np.concatenate(us)
    v_all = np.concatenate(vs) if vs else np.zeros_like(u_all)
    return np.sqrt(np.mean(u_all**2, axis=0)), np.sqrt(np.mean(v_all**2, axis=0))
