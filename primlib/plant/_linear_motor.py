"""Two-axis permanent-magnet linear motor stage with friction and force ripple (nonlinear).

Per axis, in SI units (eq. (1) and (4), CEE-MFAC paper, parameters of Table 1)::

    M x'' = K u - B x' - A_f s(x') - C_c sin(w0 x) + D
    s(v)  = [1 + (r_s - 1) exp(-(|v| / v_s)^delta)] sgn(v)          (Stribeck / Coulomb)

``M`` moving mass, ``B`` viscous friction, ``A_f`` Coulomb friction level, ``r_s`` the
static-to-Coulomb ratio, ``v_s`` the Stribeck (lubrication) velocity, ``C_c`` the ripple
amplitude, ``w0 = 2 pi / pitch`` its spatial frequency, ``D`` a constant disturbance and
``K`` the input gain. The paper's eq. (1) writes ``f_c`` both for the Coulomb level and
for the ripple force (a typo); eq. (4) separates them as ``A_f f_f`` and ``C_c f_c``,
which is what we implement. Table 1 gives M, B, A_f, C_c, D only; ``K``, ``r_s``, the
pitch and the sample time are our stated choices (data/machines/linear-motor.json).

Integration (``advance``): the control is held over a sample (ZOH) and the sample is cut in
``substeps``; in each, the linear part ``M v' = F - B v`` is integrated exactly for the
force ``F`` held at its start value (ripple, friction, disturbance), so with friction and
ripple switched off the motor is *exactly* its nominal model ``K / (M s^2 + B s)`` under
ZOH. Friction is treated as a set-valued force (a time-stepping, Moreau-type scheme): at
rest the motor sticks while the other forces stay below the static level
``r_s A_f``; a velocity reversal inside a substep stops the motor at the end of that
substep, which then decides stick or slip. No stiff ODE solver is needed and there is no
chattering around v = 0. The loop over samples is in Python (a nonlinear recursion); the
per-axis step runs on plain floats (``_advance_axis``), since numpy's call overhead on a
two-element state costs ten times the arithmetic (about 50 us per sample for two axes,
PID included).

Positions outside are in the user's length unit (``length_unit`` metres, mm by default)
and relative to the start point, like every :class:`~primlib.plant.Machine`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from primlib._errors import InputError
from primlib.plant._machine import Machine, register_kind
from primlib.plant._spec import check_kind, check_number, check_start, read_note, write_note

__all__ = ["LinearMotor", "MOTOR_KEYS"]

# key -> (required, default)
MOTOR_KEYS: dict[str, tuple[bool, float | None]] = {
    "M": (True, None),
    "B": (True, None),
    "Af": (True, None),
    "Cc": (True, None),
    "D": (True, None),
    "K": (False, 1.0),
    "static_ratio": (False, 1.5),
    "stribeck_velocity": (False, 0.1),
    "stribeck_exponent": (False, 1.0),
    "ripple_pitch": (False, 0.03),
}
_POSITIVE = ("M", "B", "K", "static_ratio", "stribeck_velocity", "stribeck_exponent")
_NONNEG = ("Af", "ripple_pitch")
_TOP_KEYS = {"name", "kind", "dt", "axes", "motors", "length_unit", "substeps", "feedback", "note"}


def _validate_motor(axis: str, spec: Any) -> dict[str, float]:
    if not isinstance(spec, Mapping):
        raise InputError(f"motor of axis {axis!r}: expected a mapping of parameters, got {spec!r}")
    unknown = sorted(set(spec) - set(MOTOR_KEYS))
    if unknown:
        raise InputError(
            f"motor of axis {axis!r}: got unknown parameter {unknown[0]!r} "
            f"(expected among {', '.join(MOTOR_KEYS)})"
        )
    out = {}
    for key, (required, default) in MOTOR_KEYS.items():
        if key not in spec:
            if required:
                raise InputError(f"motor of axis {axis!r}: expected parameter {key!r}, got none")
            out[key] = float(default)
            continue
        value = check_number(spec[key], f"motor {key} of axis {axis!r}")
        if key in _POSITIVE and value <= 0:
            raise InputError(f"motor {key} of axis {axis!r}: expected a number > 0, got {value}")
        if key in _NONNEG and value < 0:
            raise InputError(f"motor {key} of axis {axis!r}: expected a number >= 0, got {value}")
        out[key] = value
    return out


class LinearMotor(Machine):
    """Linear-motor stage: a Machine whose ``simulate`` integrates the nonlinear model.

    Parameters
    ----------
    name : str
    dt : float
        Control sample time in seconds.
    axes : sequence of str
    motors : dict
        Per axis the parameters of :data:`MOTOR_KEYS` (SI units): ``M`` kg, ``B`` N s/m,
        ``Af`` N, ``Cc`` N, ``D`` N required; ``K`` N per input unit (1), ``static_ratio``
        (1.5), ``stribeck_velocity`` m/s (0.1), ``stribeck_exponent`` (1), ``ripple_pitch``
        m (0.03; 0 switches the ripple off).
    feedback : dict or None
        Per-axis PID as for :class:`Machine` (error in the user's length unit).
    length_unit : float
        Metres per user length unit (1e-3: positions in mm).
    substeps : int
        Integration sub-steps per sample (>= 1).

    Notes
    -----
    ``discrete``, ``impulse_response``, ``lifted`` and ``closed_loop`` describe the nominal
    linear part ``K / (M s^2 + B s)`` (in user units per input unit), which is what a
    learning law is designed on; ``simulate`` and ``reference_response`` run the nonlinear
    motor.

    Examples
    --------
    >>> lm = LinearMotor.from_json("data/machines/linear-motor.json")
    >>> y = lm.simulate(np.zeros((100, 2)))
    >>> bool(np.all(y == 0.0))  # no input: friction holds it (disturbance D < static level)
    True
    """

    kind: ClassVar[str] = "linear-motor"

    def __init__(
        self,
        name: str,
        dt: float,
        axes,
        motors: Mapping[str, Any],
        feedback: Mapping[str, Any] | None = None,
        *,
        length_unit: float = 1e-3,
        substeps: int = 4,
    ) -> None:
        if isinstance(axes, str) or not isinstance(axes, (list, tuple)):
            raise InputError(f"axes: expected a list of axis names, got {axes!r}")
        if not isinstance(motors, Mapping):
            raise InputError(f"motors: expected a mapping axis -> parameters, got {motors!r}")
        missing = [a for a in axes if a not in motors]
        if missing:
            raise InputError(f"motors: expected parameters for axis {missing[0]!r}, got none")
        unknown = [a for a in motors if a not in axes]
        if unknown:
            raise InputError(
                f"motors: got parameters for unknown axis {unknown[0]!r} (axes are {list(axes)})"
            )
        length_unit = check_number(length_unit, "length_unit")
        if length_unit <= 0:
            raise InputError(
                f"length_unit: expected a number > 0 (metres per unit), got {length_unit}"
            )
        if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)):
            raise InputError(f"substeps: expected an integer >= 1, got {substeps!r}")
        if substeps < 1:
            raise InputError(f"substeps: expected an integer >= 1, got {substeps}")
        self._motors = {a: _validate_motor(a, motors[a]) for a in axes}
        self._unit = length_unit
        self._substeps = int(substeps)
        plants = {
            a: ([p["K"] / length_unit], [p["M"], p["B"], 0.0]) for a, p in self._motors.items()
        }
        super().__init__(name, dt, axes, plants, feedback)
        par = [self._motors[a] for a in self.axes]
        col = lambda k: np.array([q[k] for q in par])  # noqa: E731
        self._M, self._B, self._K = col("M"), col("B"), col("K")
        self._Af, self._Cc, self._D = col("Af"), col("Cc"), col("D")
        self._rs, self._vs, self._delta = (
            col("static_ratio"),
            col("stribeck_velocity"),
            col("stribeck_exponent"),
        )
        pitch = col("ripple_pitch")
        self._w0 = np.where(pitch > 0, 2 * np.pi / np.where(pitch > 0, pitch, 1.0), 0.0)
        self._Cc = np.where(pitch > 0, self._Cc, 0.0)
        h = self.dt / self._substeps
        self._h = h
        self._a = np.exp(-self._B * h / self._M)  # exact ZOH of M v' = F - B v over h
        tau = self._M / self._B
        self._xv = tau * (1.0 - self._a)  # displacement per unit initial velocity
        self._xf = (h - tau * (1.0 - self._a)) / self._B  # displacement per unit force
        self._vf = (1.0 - self._a) / self._B  # velocity per unit force
        self._kernel = [
            tuple(
                float(q[i])
                for q in (
                    self._K,
                    self._Cc,
                    self._w0,
                    self._D,
                    self._a,
                    self._vf,
                    self._xv,
                    self._xf,
                    self._Af,
                    self._rs,
                    self._vs,
                    self._delta,
                )
            )
            + (self._substeps,)
            for i in range(self.dim)
        ]

    # ------------------------------------------------------------------ properties
    @property
    def motors(self) -> dict[str, dict[str, float]]:
        """Per-axis motor parameters (copies, SI units)."""
        return {a: dict(p) for a, p in self._motors.items()}

    @property
    def length_unit(self) -> float:
        return self._unit

    @property
    def substeps(self) -> int:
        return self._substeps

    # ------------------------------------------------------------------ dynamics
    def initial_state(self, start=None) -> np.ndarray:
        """State at rest at ``start`` (user units, shape (d,); default 0): array (2, d) of
        absolute position (m) and velocity (m/s)."""
        x0 = self._check_start(start)
        return np.stack([x0 * self._unit, np.zeros(self.dim)])

    def advance(self, state: np.ndarray, u: np.ndarray) -> np.ndarray:
        """State after one sample with the input ``u`` (d,) held (ZOH).

        Parameters
        ----------
        state : array, shape (2, d)
            Absolute position (m) and velocity (m/s).
        u : array, shape (d,)
            Input per axis (force = ``K u``).

        Returns
        -------
        array, shape (2, d)
        """
        out = np.empty((2, self.dim))
        for i, par in enumerate(self._kernel):
            out[0, i], out[1, i] = _advance_axis(
                par, float(state[0, i]), float(state[1, i]), float(u[i])
            )
        return out

    def position(self, state: np.ndarray) -> np.ndarray:
        """Absolute position of a state in user units, shape (d,)."""
        return state[0] / self._unit

    def _check_start(self, start) -> np.ndarray:
        return check_start(start, self.dim)

    def simulate(self, u: Any, reference: Any = None, start: Any = None) -> np.ndarray:
        """Output of the nonlinear motor for input ``u``, from rest at ``start``.

        Parameters
        ----------
        u : array, shape (n, d)
            Input per axis (feedforward added to the PID output where there is feedback).
        reference : array, shape (n, d), optional
            Reference of the PID loops (relative to the start), None = zeros.
        start : array, shape (d,), optional
            Absolute start position in user units (it sets the ripple's phase); default 0.

        Returns
        -------
        y : array, shape (n, d)
            Position relative to the start, user units; ``y[k]`` responds to ``u[: k]``.
        """
        u = self.check_signal(u, "u")
        n = u.shape[0]
        r = np.zeros_like(u)
        if reference is not None:
            r = self.check_signal(reference, "reference")
            if r.shape != u.shape:
                raise InputError(f"reference: expected the shape of u {u.shape}, got {r.shape}")
        state = self.initial_state(start)
        x0 = state[0].copy()
        y = np.empty_like(u)
        fb = self.feedback or {}
        gains = np.array(
            [[fb.get(a, {}).get(k, 0.0) for k in ("kp", "ki", "kd", "tf")] for a in self.axes]
        )
        closed = bool(fb)
        kp, ki, kd, tf = gains.T
        integ = np.zeros(self.dim)
        deriv = np.zeros(self.dim)
        e_prev = np.zeros(self.dim)
        dt = self.dt
        kernel = self._kernel
        for k in range(n):
            y[k] = (state[0] - x0) / self._unit
            cmd = u[k]
            if closed:
                # backward-Euler PID, as Machine's (primlib.plant._pid); zero gains on axes
                # without feedback
                e = r[k] - y[k]
                integ = integ + ki * dt * e
                deriv = (tf * deriv + kd * (e - e_prev)) / (tf + dt)
                e_prev = e
                cmd = cmd + kp * e + integ + deriv
            for i, par in enumerate(kernel):
                state[0, i], state[1, i] = _advance_axis(par, state[0, i], state[1, i], cmd[i])
        return y

    def reference_response(self, reference: Any) -> np.ndarray:
        """Output of the nonlinear motor in its PID loops for u = 0, shape (n, d)."""
        r = self.check_signal(reference, "reference")
        return self.simulate(np.zeros_like(r), r)

    def impulse_response(self, n: int) -> np.ndarray:
        """Markov parameters of the nominal linear part (closed loop where there is feedback).

        The motor is not linear (friction, ripple, disturbance act without input), so this
        is the response of ``K / (M s^2 + B s)`` under ZOH, which learning laws design on.
        """
        return Machine(self.name, self.dt, self.axes, self.plants, self.feedback).impulse_response(
            n
        )

    def nominal(self) -> Machine:
        """The nominal linear Machine ``K / (M s^2 + B s)`` per axis, same feedback."""
        return Machine(self.name, self.dt, self.axes, self.plants, self.feedback)

    # ------------------------------------------------------------------ (de)serialise
    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LinearMotor:
        """Build from the JSON dictionary (``"kind": "linear-motor"``).

        Raises
        ------
        InputError
            Unknown or missing keys, or any invalid field.
        """
        check_kind(d, cls.kind, _TOP_KEYS, ("name", "dt", "axes", "motors"))
        m = cls(
            d["name"],
            d["dt"],
            d["axes"],
            d["motors"],
            d.get("feedback"),
            length_unit=d.get("length_unit", 1e-3),
            substeps=d.get("substeps", 4),
        )
        return read_note(m, d)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary; ``LinearMotor.from_dict(m.to_dict()) == m``."""
        out: dict[str, Any] = {
            "name": self.name,
            "kind": self.kind,
            "dt": self.dt,
            "axes": list(self.axes),
            "length_unit": self._unit,
            "substeps": self._substeps,
            "motors": self.motors,
            "feedback": self.feedback,
        }
        return write_note(self, out)

    def __repr__(self) -> str:
        fb = "PID" if self.feedback else "open loop"
        return f"LinearMotor({self.name!r}, dt={self.dt}, axes={list(self.axes)}, {fb})"


def _advance_axis(par: tuple, x: float, v: float, u: float) -> tuple[float, float]:
    """One sample of one axis in plain floats (numpy's call overhead on a 2-vector is ten
    times the arithmetic, and this runs once per axis per sample)."""
    K, Cc, w0, D, a, vf, xv, xf, Af, rs, vs, delta, nsub = par
    static = rs * Af
    for _ in range(nsub):
        f_nf = K * u - Cc * math.sin(w0 * x) + D
        v_free = a * v + vf * f_nf  # the substep without Coulomb friction
        if v != 0.0:
            level = Af * (1.0 + (rs - 1.0) * math.exp(-((abs(v) / vs) ** delta)))
            sigma = 1.0 if v > 0.0 else -1.0
            v_try = v_free - vf * level * sigma
            turn = not (v_try * sigma > 0.0)
        else:
            level = static
            turn = True
        if turn:
            # friction as a set-valued force, implicit in its sign: where the substep would
            # reverse the motion (or start it from rest), friction stops the motor if it can
            # absorb the whole free motion (up to the static level), else it slides on
            if abs(v_free) <= vf * static:
                v_new = 0.0
            else:
                v_new = v_free - vf * level * (1.0 if v_free > 0.0 else -1.0)
        else:
            v_new = v_try
        fric = (v_free - v_new) / vf  # the friction force consistent with v_new
        x = x + xv * v + xf * (f_nf - fric)
        v = v_new
    return x, v


register_kind("linear-motor", LinearMotor)
