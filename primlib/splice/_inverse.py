"""The model inverse the splice uses: exact at the samples, bounded for any sampled zeros."""

from __future__ import annotations

import numpy as np
from scipy import signal

from primlib.plant import invert

__all__ = [
    "model_inverse",
    "band_limited_inverse",
    "band_limit",
    "sampling_zero_band",
]


def model_inverse(machine, y, reference=None) -> np.ndarray:
    """The model's input for output ``y`` from rest (:func:`primlib.plant.invert`).

    Where a sampled plant has a zero outside the unit circle — every axis of relative
    degree 3 or more, e.g. the XYZ model once refinement has found a lag — the stable
    filter inverse needs input before t = 0; truncated there, it leaves a state error that
    an integrating axis keeps as a drift (measured: 0.12 mm on a time-scaled piece whose
    stored path has a NURBS-fit ripple at its start; 63 mm on a 12 s novel path that is
    already moving at t = 0). So the start is corrected (``correct_start``: the first
    samples' input fitted to what the truncation leaves; 0.0064 mm on that novel path).

    Until stop 44 pieces of up to 2,000 samples took the regularised lifted solve instead
    (``method="lifted"``, chosen before the start correction existed). On the 34 pieces of
    a novel path's warm start (the friction 2 % library of ``bench_realism.py``, a median
    618 samples) its Tikhonov weight left a median 2.4e-6 mm (worst 2.1e-5) of the residual at
    the samples, where the corrected filter inverse leaves 6.5e-9 (worst 2.5e-7), and its
    dense O(n³) solves took 5.1 s against 0.09 s; the warm-start benchmarks' figures are
    unchanged or lower with the filter (stop 44, docs/design-log.md).

    Parameters
    ----------
    machine : Machine
    y : array, shape (n, d)
        Desired output relative to the start.
    reference : array, shape (n, d), optional
        PID reference (feedback machines).

    Returns
    -------
    u : array, shape (n, d)
    """
    return invert(machine, y, reference=reference, correct_start=True)


# the band starts where the sampling zeros attenuate the sampled model to this fraction of its
# DC gain: above it the exact inverse amplifies by more than 2 what the continuous plant needs
_SAMPLING_GAIN = 0.5
# order of the Butterworth low-pass run forward and backward (zero phase, |H|^2 rolls off with
# order 2 N): 1 - |H|^2 < 1e-5 below half the cutoff
_ORDER = 6
# samples of true history (rest before t = 0, the last input held after the end) padded on
# each side, far longer than the filter's memory (its slowest pole decays within ~20 samples)
_PAD = 64
# samples over which the band limit fades in from t = 0 (see band_limit)
_RAMP = 32


def _sampling_zeros(b) -> np.ndarray:
    """Zeros of a sampled numerator on the negative real half-plane (where ZOH puts them)."""
    b = np.trim_zeros(np.trim_zeros(np.asarray(b, dtype=float), "f"), "b")
    if b.size < 2:
        return np.zeros(0, dtype=complex)
    z = np.roots(b)
    return z[z.real < 0]


def sampling_zero_band(machine) -> np.ndarray:
    """Per axis, where the near-Nyquist band of the sampling zeros starts (fraction of Nyquist).

    Zero-order hold puts zeros of the sampled plant on the negative real axis that the
    continuous plant does not have (-0.991 on the XYZ axes at 5 ms; -3.7 and -0.27 once a
    lag is added). Together they scale the sampled model's gain by
    ``g(ω) = Π |1 - z_i e^{-jω}| / |1 - z_i|`` (1 at DC); the band starts at the lowest ω
    with ``g(ω) = 1/2`` (2π/3 for one zero near -1). Above it the exact inverse multiplies by
    ``1 / g`` what the path asks there — near -1 up to 1/g(π) = 220 — input the plant's
    samples barely see (the output there is g times smaller) and the machine only sees as
    ripple between them.

    Returns
    -------
    array, shape (d,)
        In (0, 1]; 1 where an axis has no sampling zero (no band).
    """
    w = np.linspace(0.0, np.pi, 4097)
    out = np.ones(machine.dim)
    for i, (b, _) in enumerate(machine.discrete()):
        z = _sampling_zeros(b)
        if z.size == 0:
            continue
        e = np.exp(-1j * w)[:, None]
        g = np.prod(np.abs(1.0 - z[None, :] * e) / np.abs(1.0 - z[None, :]), axis=1)
        below = np.flatnonzero(g < _SAMPLING_GAIN)
        if below.size:
            out[i] = w[below[0]] / np.pi
    return out


def band_limit(machine, u) -> np.ndarray:
    """``u`` without its content in each axis's sampling-zero band (:func:`sampling_zero_band`).

    ``u - w (1 - L) u``: L a zero-phase low-pass (Butterworth, run forward and backward) over
    the true history — at rest (0) before t = 0, the last input held after the end — and w a
    raised-cosine ramp from 0 at t = 0 to 1 after ``_RAMP`` samples. L is linear and time
    invariant, so for ``u = G^-1 y`` the model's output becomes ``G L G^-1 y = L y``: the
    samples move by ``(1 - L) y``, the path's own content in the band (nil for a smooth path,
    ~1e-5 mm where pieces with different curvature meet), while the ringing of the inverse's
    near-Nyquist pole, which every acceleration step starts (its continuous inverse has an
    impulse, which no held input has) and which decays like (-0.991)^k, is removed whole. The
    ramp keeps the start's own band content: L spreads it before t = 0, where no input acts,
    and an integrating axis would keep the impulse lost there as an offset (measured 2e-4 mm
    on the example path without the ramp, 8e-6 mm = max |(1 - L) y| with it).

    Parameters
    ----------
    machine : Machine
    u : array, shape (n, d)

    Returns
    -------
    array, shape (n, d)
    """
    u = np.asarray(u, dtype=float)
    out = u.copy()
    n = u.shape[0]
    k = np.arange(n)
    w = np.where(k < _RAMP, 0.5 - 0.5 * np.cos(np.pi * k / _RAMP), 1.0)
    for i, cut in enumerate(sampling_zero_band(machine)):
        if cut >= 1.0 or n < 2:
            continue
        sos = signal.butter(_ORDER, cut, output="sos")
        x = np.concatenate([np.zeros(_PAD), u[:, i], np.full(_PAD, u[-1, i])])
        low = signal.sosfiltfilt(sos, x, padtype=None)[_PAD : _PAD + n]
        out[:, i] = u[:, i] - w * (u[:, i] - low)
    return out


def band_limited_inverse(machine, y, reference=None) -> np.ndarray:
    """:func:`model_inverse` without the sampling zeros' near-Nyquist band (:func:`band_limit`).

    Parameters
    ----------
    machine : Machine
    y : array, shape (n, d)
        Desired output relative to the start.
    reference : array, shape (n, d), optional
        PID reference (feedback machines).

    Returns
    -------
    u : array, shape (n, d)
    """
    return band_limit(machine, model_inverse(machine, y, reference))
