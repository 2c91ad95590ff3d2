"""Default learning gains derived from the model (notation: :mod:`primlib.ilc._learn`).

With G_r(w) the frequency response of q^r G on a log grid from pi / n_r to pi rad/sample and
the learning band w <= w_b (w_b = 2 pi q_cutoff dt with a Q-filter, else
``primlib.defaults.ILC_BAND``, a tenth, of the Nyquist frequency):

- Arimoto laws: (kp, kd, ki) is the least-squares fit of L to the model inverse over the
  band, min sum |1 - L(w) G_r(w)|^2 (log-spaced, so each decade counts alike; linear in the
  gains), with every gain of the sign of h[r] (bounded least squares). On an integrating
  axis this drives kp and ki to ~0 and kd to ~1/K: D-type, the only monotonically
  convergent Arimoto law there (P-type is not, whatever the gain; with no useful gain of
  the right sign, P-type gets kp = 1 / (2 h[r])). The fit is then scaled by the largest
  alpha in 1, 1/2, ..., 1/32 with max_w |Q(w) (1 - alpha L G_r)| < 1 over the whole grid
  (the frequency-domain monotonic-convergence condition); if none qualifies, the alpha with
  the smallest maximum (the check will warn).
- Norm-optimal: w = |G_r(w_b)|^2, so the learning gain |G|^2 / (|G|^2 + w) is >= 1/2 inside
  the band and rolls off above it (robustness to unmodelled high-frequency dynamics).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import optimize

from primlib._errors import InputError
from primlib.defaults import ILC_BAND
from primlib.ilc._laws import MasterSlave, law_from_name
from primlib.ilc._qfilter import QFilter

__all__ = [
    "GAIN_KEYS",
    "design",
    "design_gains",
    "frequency_responses",
    "q_filter",
    "relative_degrees",
    "single_axis_law",
]

GAIN_KEYS = {"p": ("kp",), "pd": ("kp", "kd"), "pid": ("kp", "ki", "kd"), "norm-optimal": ("w",)}
_ALPHAS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125)


def single_axis_law(law: Any):
    """The law object of a P / PD / PID / norm-optimal law (or its name)."""
    spec = law_from_name(law)
    if isinstance(spec, MasterSlave):
        raise InputError(
            f"law: expected one of {', '.join(GAIN_KEYS)} here, got the master-slave law "
            f"{spec.name!r} (see primlib.ilc.learn_master_slave)"
        )
    return spec


def q_filter(spec, dt: float) -> QFilter | None:
    """The law's Q-filter at the machine's dt, or None."""
    return QFilter(spec.q_cutoff, dt, spec.q_order) if spec.q_cutoff is not None else None


def relative_degrees(model, h: np.ndarray) -> np.ndarray:
    rel = getattr(model, "relative_degree", None)
    if rel is not None:
        return np.asarray(rel, dtype=int)
    scale = np.max(np.abs(h), axis=0)
    out = np.empty(h.shape[1], dtype=int)
    for i in range(h.shape[1]):
        nz = np.flatnonzero(np.abs(h[:, i]) > 1e-12 * scale[i])
        out[i] = nz[0] if nz.size else 0
    return out


def frequency_responses(model, h: np.ndarray, rel: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """q^r G(e^{i omega}) per axis, shape (len(omega), d)."""
    zi = np.exp(-1j * omega)
    out = np.empty((len(omega), h.shape[1]), dtype=complex)
    loops = model.closed_loop() if hasattr(model, "closed_loop") else None
    for i in range(h.shape[1]):
        if loops is not None:
            num, _, den = loops[i]
            g = np.polyval(num[::-1], zi) / np.polyval(den[::-1], zi)
        else:  # truncated DTFT of the impulse response
            k = np.arange(h.shape[0])
            g = np.exp(-1j * np.outer(omega, k)) @ h[:, i]
        out[:, i] = g / zi ** rel[i]
    return out


def _arimoto_basis(law: str, omega: np.ndarray, dt: float) -> np.ndarray:
    zi = np.exp(-1j * omega)
    cols = {"kp": np.ones_like(zi), "kd": (1 - zi) / dt, "ki": dt / (1 - zi)}
    return np.column_stack([cols[k] for k in GAIN_KEYS[law]])


def _omega_grid(n_r: int) -> np.ndarray:
    lo = np.pi / max(n_r, 2)
    return np.unique(np.r_[np.geomspace(lo, np.pi, 600), np.linspace(lo, np.pi, 600)])


def _band(q: QFilter | None, dt: float) -> float:
    return 2 * np.pi * q.cutoff_hz * dt if q is not None else ILC_BAND * np.pi


def design_gains(model, n: int, law: Any = "pd") -> dict:
    """Default learning gains from the model (see the module docstring).

    Parameters
    ----------
    model : Machine
    n : int
        Samples per trial.
    law : str or PLaw, PDLaw, PIDLaw, NormOptimal
        The law (its name, or an object whose Q-filter sets the learning band; its own
        gains are ignored).

    Returns
    -------
    dict
        ``{"kp": (d,), "kd": (d,), ...}`` or ``{"w": (d,)}``.
    """
    spec = single_axis_law(law)
    q = q_filter(spec, model.dt)
    h = model.impulse_response(n)
    rel = relative_degrees(model, h)
    return design(model, h, rel, n, spec.name, q)


def design(model, h, rel, n, law: str, q) -> dict:
    d = h.shape[1]
    band = _band(q, model.dt)
    out = {k: np.zeros(d) for k in GAIN_KEYS[law]}
    for i in range(d):
        if law == "norm-optimal":
            g_b = frequency_responses(model, h, rel, np.array([band]))[0, i]
            out["w"][i] = max(abs(g_b) ** 2, np.finfo(float).tiny)
            continue
        for k, value in _arimoto_gains(model, h, rel, n, law, q, band, i).items():
            out[k][i] = value
    return out


def _arimoto_gains(model, h, rel, n, law: str, q, band: float, i: int) -> dict[str, float]:
    """Axis i's Arimoto gains: the band-limited least-squares fit of L to the model inverse,
    scaled into the monotonic-convergence region (see the module docstring)."""
    dt = model.dt
    keys = GAIN_KEYS[law]
    omega = _omega_grid(n - int(rel[i]))
    gr = frequency_responses(model, h, rel, omega)[:, i]
    basis = _arimoto_basis(law, omega, dt) * gr[:, None]
    a = basis[omega <= band]
    A = np.vstack([a.real, a.imag])
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    rhs = np.r_[np.ones(a.shape[0]), np.zeros(a.shape[0])]
    # gains share the sign of the first Markov parameter h[r], so that the diagonal
    # of I - L G, 1 - L_0 h[r], starts below 1 (the condition for convergence at all)
    h_r = h[rel[i], i]
    sign = 1.0 if h_r >= 0 else -1.0
    fit = optimize.lsq_linear(sign * A / scale, rhs, bounds=(0.0, np.inf))
    theta = sign * fit.x / scale
    named = dict(zip(keys, theta, strict=True))
    # L_0, the first coefficient of L's impulse response, sits on the diagonal
    diag = named["kp"] + named.get("kd", 0.0) / dt + named.get("ki", 0.0) * dt
    if diag * h_r < 1e-3:
        # no gain of the right sign helps in the band (P-type on an integrating axis):
        # half the deadbeat gain on the diagonal, 1 - L_0 h[r] = 1/2 (the check warns)
        return {k: (0.5 / h_r if j == 0 else 0.0) for j, k in enumerate(keys)}
    qmag = q.response(omega) if q is not None else 1.0
    alpha = _largest_contracting_alpha(qmag, basis @ theta)
    return {k: alpha * v for k, v in named.items()}


def _largest_contracting_alpha(qmag, lg: np.ndarray) -> float:
    """The largest alpha in 1, 1/2, ..., 1/32 with max |Q (1 - alpha L G)| < 1, else the
    alpha with the smallest maximum."""
    best = None
    for alpha in _ALPHAS:
        sup = np.max(np.abs(qmag * (1 - alpha * lg)))
        if best is None or sup < best[0] - 1e-12:
            best = (sup, alpha)
        if sup < 1.0:
            return alpha
    return best[1]
