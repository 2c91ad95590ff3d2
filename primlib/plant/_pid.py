"""Discrete PID controller as a rational function of the delay operator q^-1.

The continuous controller is

    C(s) = kp + ki / s + kd s / (tf s + 1)

(``tf`` is the derivative filter time constant, 0 = pure derivative). It is discretised with
the backward-Euler map s -> (1 - q^-1) / dt for both the integral and the derivative:

    C(q^-1) = kp + ki dt / (1 - q^-1) + kd (1 - q^-1) / ((tf + dt) - tf q^-1)

which is causal with direct feedthrough kp + ki dt + kd / (tf + dt): the control at sample k
uses the error at sample k (the error is measured, then the command is applied and held).
Only the terms that are present contribute a denominator factor, so ki = 0 leaves no pole
at q = 1 to cancel against.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pid_polynomials"]


def pid_polynomials(kp: float, ki: float, kd: float, tf: float, dt: float):
    """Numerator and denominator of the discrete PID in ascending powers of q^-1.

    Parameters
    ----------
    kp, ki, kd : float
        Proportional, integral (per second) and derivative (seconds) gains.
    tf : float
        Derivative filter time constant in seconds (0: backward difference).
    dt : float
        Sample time in seconds.

    Returns
    -------
    num, den : ndarray, shape (m,)
        ``C(q^-1) = num(q^-1) / den(q^-1)`` with ``den[0] == 1``.
    """
    # sum of fractions n_i / d_i, kept as polynomials in q^-1
    terms = [(np.array([float(kp)]), np.array([1.0]))]
    if ki != 0.0:
        terms.append((np.array([ki * dt]), np.array([1.0, -1.0])))
    if kd != 0.0:
        terms.append((kd * np.array([1.0, -1.0]), np.array([tf + dt, -tf])))
    num = np.array([0.0])
    den = np.array([1.0])
    for n_i, d_i in terms:
        num = _polyadd(np.convolve(num, d_i), np.convolve(n_i, den))
        den = np.convolve(den, d_i)
    num = _pad(num, len(den))
    scale = den[0]
    return num / scale, den / scale


def _polyadd(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    # ascending powers of q^-1: align on the constant term
    n = max(len(p), len(q))
    return _pad(p, n) + _pad(q, n)


def _pad(p: np.ndarray, n: int) -> np.ndarray:
    out = np.zeros(max(n, len(p)))
    out[: len(p)] = p
    return out
