r"""Excitation signals for an identification experiment: multisine and PRBS.

Multisine (Schroeder 1970): harmonics f_k = k / P of its period P = T / periods inside the band,
equal amplitudes, phases

.. math:: \phi_k = -\pi k (k - 1) / K, \quad k = 1 \dots K,

which keep the crest factor (peak / RMS) near sqrt(2) instead of growing like sqrt(K) for
aligned phases. Axis i is the same signal delayed circularly by i P / d, so each axis has the
same spectrum and the axes are nearly uncorrelated. A raised-cosine fade over
``FADE`` of the record at each end starts and ends the experiment at rest.

PRBS: a maximum-length binary sequence (``scipy.signal.max_len_seq``) of +-amplitude, each
bit held for as many samples as put the band's upper edge near its first spectral null
(clock f_c = 2.5 f_max, so the spectrum is within 3 dB up to f_max), each axis starting
from its own random register state. Switching is slew limited when a rate limit is given:
each jump becomes a ramp (a moving average of the bit sequence, no loop over samples).

Limits, applied by scaling the whole signal (the spectrum's shape is kept): the amplitude
bounds max |u|; ``max_rate`` bounds max |du/dt| (the backward difference); ``max_velocity``
with a nominal ``machine`` bounds the predicted velocity max |dy/dt| of its simulation
(linear, so the scale is exact).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import signal

from primlib._errors import InputError

__all__ = ["excite", "KINDS", "FADE", "PERIODS"]

KINDS = ("multisine", "prbs")
FADE = 0.05
"""Fraction of the record faded in (and out) at each end of a multisine."""
PERIODS = 4
"""Default number of multisine periods in a record."""
_F_MAX_NYQUIST = 0.2  # default upper band edge, as a fraction of the Nyquist frequency


def _positive(value: Any, what: str, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected a number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"{what}: expected a finite number > 0, got {value!r}")
    return v


def _multisine(n: int, dt: float, axes: int, band: tuple[float, float], periods: int) -> np.ndarray:
    P = n * dt / periods
    k = np.arange(max(1, math.ceil(band[0] * P)), math.floor(band[1] * P) + 1)
    if len(k) == 0:
        raise InputError(
            f"band: expected at least one harmonic of 1/period = {1 / P:.4g} Hz between "
            f"{band[0]:.4g} and {band[1]:.4g} Hz, got none (lengthen the record or widen the band)"
        )
    K = len(k)
    phase = -np.pi * np.arange(1, K + 1) * np.arange(K) / K  # Schroeder
    t = np.arange(n) * dt
    out = np.empty((n, axes))
    for i in range(axes):
        shift = i * P / axes
        out[:, i] = np.cos(2 * np.pi * np.outer(t + shift, k / P) + phase).sum(axis=1)
    m = max(1, int(round(FADE * n)))
    fade = np.ones(n)
    fade[:m] = 0.5 - 0.5 * np.cos(np.pi * np.arange(m) / m)
    fade[n - m :] = fade[:m][::-1]
    out *= fade[:, None]
    return out / np.max(np.abs(out))


def _prbs(n: int, dt: float, axes: int, f_max: float, ramp: int, rng) -> np.ndarray:
    hold = max(1, int(round(1.0 / (2.5 * f_max * dt))), ramp)
    bits = math.ceil(n / hold)
    nbits = max(2, math.ceil(math.log2(bits + 1)))
    out = np.empty((n, axes))
    for i in range(axes):
        state = rng.integers(0, 2, nbits)
        state[rng.integers(nbits)] = 1  # never the all-zero register
        seq = signal.max_len_seq(nbits, state=state, length=bits)[0] * 2.0 - 1.0
        u = np.repeat(seq, hold)[:n]
        if ramp > 1:  # causal moving average from rest: each switch becomes a ramp
            u = np.convolve(u, np.ones(ramp) / ramp)[:n]
        out[:, i] = u
    return out


def excite(
    duration: float,
    amplitude: float,
    axes: int,
    dt: float,
    *,
    kind: str = "multisine",
    band: tuple[float, float] | None = None,
    max_rate: float | None = None,
    max_velocity: float | None = None,
    machine=None,
    periods: int = PERIODS,
    seed: int | None = 0,
) -> np.ndarray:
    """An excitation input for an identification experiment, within the given limits.

    Parameters
    ----------
    duration : float
        Record length T in seconds; the signal has round(T / dt) samples.
    amplitude : float
        Largest |u| per axis, in the input's units.
    axes : int
        Number of axes (columns), >= 1.
    dt : float
        Sample time, s.
    kind : {"multisine", "prbs"}
    band : (float, float), optional
        Excited band in Hz (default: periods / T to a fifth of the Nyquist frequency); PRBS uses
        only the upper edge.
    max_rate : float, optional
        Largest |du/dt| (input units per second).
    max_velocity : float, optional
        Largest predicted |dy/dt| of ``machine``'s simulated response (output units per s);
        needs ``machine``.
    machine : Machine, optional
        Nominal model (same number of axes, its dt = ``dt``) for ``max_velocity``.
    periods : int
        Periods of the multisine in the record (its harmonics are multiples of
        periods / T). Schroeder phases sweep the band once per period, so with several
        periods every stretch of the record, the held-out end too, sees the whole band.
    seed : int, optional
        Seed of the PRBS register states.

    Returns
    -------
    u : array, shape (n, axes)
        Starts at rest for a multisine (faded in and out); n = round(duration / dt).

    Raises
    ------
    InputError
        A non-positive or non-finite number, an unknown kind, a band outside (0, Nyquist)
        or with no harmonic, ``max_velocity`` without a machine or a machine that does not
        fit.

    Examples
    --------
    >>> u = excite(10.0, 1.0, 2, 0.005)
    >>> u.shape, float(np.max(np.abs(u))) <= 1.0
    ((2000, 2), True)
    """
    n, lo, hi = _check_options(duration, amplitude, axes, dt, kind, band, periods)
    amplitude, dt = float(amplitude), float(dt)
    max_rate = _positive(max_rate, "max_rate", allow_none=True)
    max_velocity = _positive(max_velocity, "max_velocity", allow_none=True)
    if max_velocity is not None:
        _check_machine(machine, axes, dt)
    if kind == "multisine":
        u = amplitude * _multisine(n, dt, axes, (lo, hi), periods)
    else:
        # a switch of 2 amplitude within the rate limit takes this many samples
        ramp = 1 if max_rate is None else math.ceil(2 * amplitude / (max_rate * dt))
        u = amplitude * _prbs(n, dt, axes, hi, ramp, np.random.default_rng(seed))
    return u * _limit_scale(u, dt, max_rate, max_velocity, machine)


def _limit_scale(u, dt, max_rate, max_velocity, machine) -> float:
    """The largest scale <= 1 of u within the rate and predicted-velocity limits."""
    scale = 1.0
    if max_rate is not None:
        rate = np.max(np.abs(np.diff(u, axis=0, prepend=0.0))) / dt
        scale = min(scale, max_rate / rate)
    if max_velocity is not None:
        y = machine.simulate(u)
        vel = np.max(np.abs(np.diff(y, axis=0, prepend=0.0))) / dt
        scale = min(scale, max_velocity / vel) if vel > 0 else scale
    return scale


def _check_options(duration, amplitude, axes, dt, kind, band, periods):
    """Check :func:`excite`'s signal options; return the sample count and the band."""
    duration = _positive(duration, "duration")
    _positive(amplitude, "amplitude")
    dt = _positive(dt, "dt")
    if isinstance(axes, bool) or not isinstance(axes, (int, np.integer)) or axes < 1:
        raise InputError(f"axes: expected a number of axes >= 1, got {axes!r}")
    if isinstance(periods, bool) or not isinstance(periods, (int, np.integer)) or periods < 1:
        raise InputError(f"periods: expected an integer >= 1, got {periods!r}")
    if kind not in KINDS:
        raise InputError(f"kind: expected one of {', '.join(KINDS)}, got {kind!r}")
    n = int(round(duration / dt))
    if n < 8:
        raise InputError(f"duration: expected at least 8 samples of dt = {dt:g} s, got {n}")
    nyquist = 0.5 / dt
    if band is None:
        lo, hi = periods / (n * dt), _F_MAX_NYQUIST * nyquist
    else:
        try:
            lo, hi = (float(f) for f in band)
        except (TypeError, ValueError):
            raise InputError(f"band: expected (low, high) in Hz, got {band!r}") from None
    if not (0 <= lo < hi <= nyquist):
        raise InputError(
            f"band: expected 0 <= low < high <= the Nyquist frequency {nyquist:g} Hz, "
            f"got ({lo!r}, {hi!r})"
        )
    return n, lo, hi


def _check_machine(machine, axes: int, dt: float) -> None:
    if machine is None:
        raise InputError(
            "max_velocity: expected a nominal machine to predict the velocity, got none "
            "(limit the input's rate with max_rate instead)"
        )
    if machine.dim != axes or abs(machine.dt - dt) > 1e-9 * dt:
        raise InputError(
            f"machine: expected {axes} axes and dt = {dt:g} s, got {machine.dim} axes and "
            f"dt = {machine.dt:g} s"
        )
