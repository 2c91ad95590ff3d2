"""The per-sample loop of a realistic machine's nonlinear axes (friction, ripple).

The model, the state space and the stick/slip step are described in
:mod:`primlib.plant._realistic`; this module builds each loop axis's constants
(:func:`loop_kernel`) and runs it on plain floats (:func:`run_axis`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from scipy import linalg, signal

from primlib._errors import InputError

__all__ = ["hf_sign", "linear_plant", "loop_kernel", "run_axis"]


def hf_sign(num: np.ndarray, den: np.ndarray) -> float:
    """Sign of the high-frequency gain (leading coefficients' ratio)."""
    return 1.0 if num[0] / den[0] > 0 else -1.0


def _resonance(dep: Mapping[str, float]) -> tuple[float, float] | None:
    hz = dep["resonance_hz"]
    return None if hz == 0 else (2 * math.pi * hz, dep["resonance_damping"])


def linear_plant(num, den, dep) -> tuple[np.ndarray, np.ndarray]:
    """``G R / (1 + c_v s G)``: the axis with its linear departures (unchanged without)."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    if dep["viscous"] != 0:
        s_num = np.concatenate([num, [0.0]]) * hf_sign(num, den) * dep["viscous"]
        den = np.polyadd(den, s_num)
    res = _resonance(dep)
    if res is not None:
        w, zeta = res
        num, den = num * w**2, np.polymul(den, [1.0, 2 * zeta * w, w**2])
    return num, den


def loop_kernel(axis: str, num, den, dep, dt: float, substeps: int) -> tuple:
    """Plain-float constants of one loop axis (module docstring), per substep."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    if len(den) - len(num) < 2:
        raise InputError(
            f"departures of axis {axis!r}: Coulomb friction and ripple act as a force, "
            f"expected a plant of relative degree >= 2, got {len(den) - len(num)}"
        )
    g = hf_sign(num, den)
    A, B, C, _ = signal.tf2ss(num, den)
    B, C = B[:, 0], C[0]
    A = A - g * dep["viscous"] * np.outer(B, C @ A)  # viscous friction: -c_v v at the input
    m = len(B)
    res = _resonance(dep)
    Cp = np.concatenate([C, [0.0, 0.0]]) if res else C
    Cv = Cp.copy()
    Cv[:m] = C @ A
    if res:
        w, zeta = res
        full = np.zeros((m + 2, m + 2))
        full[:m, :m] = A
        full[m, m + 1] = 1.0  # the mode's position and velocity follow the motor's position
        full[m + 1, :m] = w**2 * C
        full[m + 1, m:] = -(w**2), -2 * zeta * w
        A = full
        B = np.concatenate([B, [0.0, 0.0]])
        Cy = np.zeros(m + 2)
        Cy[m] = 1.0
    else:
        Cy = Cp
    h = dt / substeps
    k = len(B)
    aug = np.zeros((k + 1, k + 1))
    aug[:k, :k], aug[:k, k] = A * h, B * h
    E = linalg.expm(aug)
    Ad, Bd = E[:k, :k], E[:k, k]
    vf = float(Cv @ Bd)
    w0 = 2 * math.pi / dep["ripple_pitch"]
    return (
        tuple(tuple(float(a) for a in row) for row in Ad),
        tuple(float(b) for b in Bd),
        tuple(float(c) for c in Cp),
        tuple(float(c) for c in Cv @ Ad),
        vf,
        tuple(float(c) for c in Cy),
        (dep["coulomb"], dep["static_ratio"], dep["stribeck_velocity"]),
        (dep["ripple"], w0, dep["ripple_phase"], h / 2),
        substeps,
        m,
    )


def _friction(v: float, v_free: float, vf: float, fr: tuple) -> tuple[float, float]:
    """Coulomb/Stribeck friction of one substep (set-valued, Moreau-type): the force
    (input units, ``v_new = v_free - vf * force``) and the end-of-substep velocity."""
    coulomb, rs, vs = fr
    if coulomb == 0.0:
        return 0.0, v_free
    gain = abs(vf)
    static = rs * coulomb
    if v != 0.0:
        level = coulomb * (1.0 + (rs - 1.0) * math.exp(-((v / vs) ** 2)))
        sigma = 1.0 if v > 0.0 else -1.0
        v_try = v_free - gain * level * sigma
        if v_try * sigma > 0.0:  # still moving the same way: kinetic friction
            return (v_free - v_try) / vf, v_try
    else:
        level = static
    # at rest, or the substep would reverse the motion: stick if friction up to the static
    # level absorbs the whole free motion, else slide on
    if abs(v_free) <= gain * static:
        return v_free / vf, 0.0
    v_new = v_free - gain * level * (1.0 if v_free > 0.0 else -1.0)
    return (v_free - v_new) / vf, v_new


def _note(record: list, force: float, fric: float, v_new: float, v: float) -> None:
    """One substep's ``(force, slip, v)`` appended to ``record`` (:func:`_stepper`)."""
    record.append((force, 0.0 if v_new == 0.0 else math.copysign(1.0, fric), v))


def _stepper(kern: tuple, start: float, record: list | None = None, general: bool = False):
    """The ``substeps`` of one sample for one loop axis: ``step(x, v, cmd) -> (x, v)``
    (``general``: the loop for any state space, also where one is written out; tests).

    ``record`` (a list, or None): per substep, appended ``(force, slip, v)`` -- the force
    the ripple and friction took off the command (input units: the state advanced on ``cmd
    - force``), the sign by which the friction force grows with its Coulomb level (the
    force's sign while sliding, 0 while stuck: there it is whatever holds the axis) and the
    velocity the substep started from (the Stribeck term's).
    What :mod:`primlib.greybox._refit` linearises the run about.

    Plain floats in closures (numpy's call overhead on a 2-vector is ten times the
    arithmetic); the usual rigid axes (two states, or three with a lag; no resonance) are
    written out (:func:`_stepper3`: 3x faster than the general loop). The ripple
    is taken where the carriage is half-way through the substep (``p + v h / 2``, the
    midpoint rule): at the substep's start it would lag the continuous force by ``w v h / 2``
    rad, 4 % of the ripple for a 5 mm pitch at 50 mm/s and 4 substeps of 5 ms."""
    Ad, Bd, Cp, CvAd, vf, _, fr, (c_r, w0, phi, half), nsub, m = kern
    if len(Bd) == 3 and m == 3 and not general:
        return _stepper3(kern, start, record)
    if len(Bd) != 2 or general:

        def step(x, v, cmd):
            for _ in range(nsub):
                w = cmd
                if c_r != 0.0:
                    p = start + sum(c * xi for c, xi in zip(Cp, x, strict=True)) + v * half
                    w -= c_r * math.sin(w0 * p + phi)
                v_free = sum(c * xi for c, xi in zip(CvAd, x, strict=True)) + vf * w
                fric, v_new = _friction(v, v_free, vf, fr)
                w -= fric
                if record is not None:
                    _note(record, cmd - w, fric, v_new, v)
                x_new = [
                    sum(a * xi for a, xi in zip(row, x, strict=True)) + b * w
                    for row, b in zip(Ad, Bd, strict=True)
                ]
                if v == 0.0 and v_new == 0.0 and fric != 0.0:
                    # stuck through the substep: the carriage is at rest, exactly (rounding
                    # would otherwise let it creep by 1e-22 and flip the sign of v)
                    x_new[:m] = x[:m]
                x, v = x_new, v_new
            return x, v

        return step
    (a00, a01), (a10, a11) = Ad
    (b0, b1), (p0, p1), (q0, q1) = Bd, Cp, CvAd

    def step2(x, v, cmd):
        x0, x1 = x
        for _ in range(nsub):
            w = cmd
            if c_r != 0.0:
                w -= c_r * math.sin(w0 * (start + p0 * x0 + p1 * x1 + v * half) + phi)
            v_free = q0 * x0 + q1 * x1 + vf * w
            fric, v_new = _friction(v, v_free, vf, fr)
            if record is not None:
                _note(record, cmd - w + fric, fric, v_new, v)
            if not (v == 0.0 and v_new == 0.0 and fric != 0.0):  # else stuck: at rest
                w -= fric
                x0, x1 = a00 * x0 + a01 * x1 + b0 * w, a10 * x0 + a11 * x1 + b1 * w
            v = v_new
        return (x0, x1), v

    return step2


def _stepper3(kern: tuple, start: float, record: list | None):
    """:func:`_stepper` written out for a rigid axis of three states (a lag, no resonance)."""
    Ad, Bd, Cp, CvAd, vf, _, fr, (c_r, w0, phi, half), nsub, _ = kern
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = Ad
    (b0, b1, b2), (p0, p1, p2), (q0, q1, q2) = Bd, Cp, CvAd

    def step3(x, v, cmd):
        x0, x1, x2 = x
        for _ in range(nsub):
            w = cmd
            if c_r != 0.0:
                w -= c_r * math.sin(w0 * (start + p0 * x0 + p1 * x1 + p2 * x2 + v * half) + phi)
            v_free = q0 * x0 + q1 * x1 + q2 * x2 + vf * w
            fric, v_new = _friction(v, v_free, vf, fr)
            if record is not None:
                _note(record, cmd - w + fric, fric, v_new, v)
            if not (v == 0.0 and v_new == 0.0 and fric != 0.0):  # else stuck: at rest
                w -= fric
                x0, x1, x2 = (
                    a00 * x0 + a01 * x1 + a02 * x2 + b0 * w,
                    a10 * x0 + a11 * x1 + a12 * x2 + b1 * w,
                    a20 * x0 + a21 * x1 + a22 * x2 + b2 * w,
                )
            v = v_new
        return (x0, x1, x2), v

    return step3


def run_axis(
    kern: tuple, u: list, r: list, noise: list, start: float, pid, record: list | None = None
) -> list:
    """One loop axis over all samples (plain floats): the noise-free output, relative;
    ``record``: each substep's force and slip sign appended (:func:`_stepper`)."""
    Cy = kern[5]
    step = _stepper(kern, start, record)
    x = [0.0] * len(Cy)
    v = 0.0
    kp, ki, kd, tf, dt = pid if pid is not None else (0.0,) * 5
    integ = deriv = e_prev = 0.0
    out = [0.0] * len(u)
    for k in range(len(u)):
        y = sum(c * xi for c, xi in zip(Cy, x, strict=True))
        out[k] = y
        cmd = u[k]
        if pid is not None:
            # backward-Euler PID on the measurement, as Machine's (primlib.plant._pid)
            e = r[k] - (y + noise[k])
            integ += ki * dt * e
            deriv = (tf * deriv + kd * (e - e_prev)) / (tf + dt)
            e_prev = e
            cmd += kp * e + integ + deriv
        x, v = step(x, v, cmd)
    return out
