"""Nominal-model inverse feedforward: the input that makes the model follow a given output.

Per axis, with the ZOH plant G = b / a of relative degree r (``b[:r] == 0``) and, where the
axis has feedback, the discrete PID C, the input u with y = T_u u + T_r r equal to the
desired y_d solves T_u u = w, w = y_d - T_r r. Because T_u = G / (1 + G C),

    u = G^-1 w + C w,

so only the open-loop plant is inverted (the PID part is a causal, bounded filter). G^-1 is
the shifted rational function a / b_r, b_r = b[r:] (the output at k + r determines the input at
k); the last r inputs do not act inside the horizon and hold the previous value. Three ways:

- ``"causal"`` — filter w[r:] by a / b_r forward in time: exact on the whole horizon, used by
  ``"auto"`` when every discrete zero (root of b_r) lies inside or on the unit circle. ZOH of
  a plant with continuous relative degree 2 has a sampling zero near -1 (-0.991 on the XYZ
  machine at 5 ms): the inverse is exact but any Nyquist-frequency content of w rings slowly;
  smooth desired outputs excite almost none of it.
- ``"stable"`` — stable non-causal inversion (used by ``"auto"`` when some zero is outside
  the unit circle, a non-minimum-phase axis, e.g. both axes of eq. (33), master-slave
  PDCCILC paper): b_r = b_s b_u with b_s's zeros inside and b_u's outside; a / b_s is run
  forward and 1 / b_u backward in time (stable that way). The ideal inverse acts before
  t = 0 (pre-actuation, decaying backwards like |z_u|^-k); it is truncated at t = 0, so the
  output error is confined to the start and is small when the desired output starts at rest.
- ``"lifted"`` — regularised least squares on the lifted closed-loop matrix T (n x n, dense):
  minimise ||T u - w||^2 + lam ||u||^2 with lam = reg * ||T||_F^2 / n (so ``reg`` is
  relative and scale-free). Bounded for any zeros; O(n^3), so n <= 6000.
"""

from __future__ import annotations

import numpy as np
from scipy import linalg, signal

from primlib._errors import InputError

__all__ = ["invert"]

_UNIT_TOL = 1e-9
_LIFTED_MAX_N = 6000
_METHODS = ("auto", "causal", "stable", "lifted")


def _causal(a: np.ndarray, b_r: np.ndarray, w_shift: np.ndarray) -> np.ndarray:
    return signal.lfilter(a, b_r, w_shift)


def _stable(a: np.ndarray, b_r: np.ndarray, w_shift: np.ndarray) -> np.ndarray:
    zeros = np.roots(b_r)
    outside = np.abs(zeros) > 1.0 + _UNIT_TOL
    b_s = b_r[0] * np.real(np.poly(zeros[~outside]))
    b_u = np.real(np.poly(zeros[outside]))
    x = signal.lfilter(a, b_s, w_shift)
    m = len(b_u) - 1
    if m == 0:
        return x
    # b_u(q^-1) v = x solved backwards: with reversed time the reversed coefficients have
    # their roots at 1 / z_u, inside the unit circle
    lead = np.zeros(m + 1)
    lead[m] = 1.0
    return signal.lfilter(lead, b_u[::-1], x[::-1])[::-1]


def _start_correction(h: np.ndarray, e: np.ndarray, k: int, reg: float) -> np.ndarray:
    """Input over the first ``k`` samples, least squares (relative weight ``reg``) of the
    output error ``e`` through the impulse response ``h`` (module notes)."""
    n = len(e)
    k = min(k, n)
    lags = np.arange(n)[:, None] - np.arange(k)[None, :]
    cols = np.where(lags >= 0, h[np.clip(lags, 0, None)], 0.0)
    gram = cols.T @ cols
    gram[np.diag_indices(k)] += reg * np.trace(gram) / k + 1e-300
    return linalg.solve(gram, cols.T @ e, assume_a="pos")


def _correction_length(b: np.ndarray, r: int) -> int:
    """Samples the start correction spans: until the slowest unstable zero's pre-actuation
    has decayed to 1e-8 (at least 8, at most 256)."""
    b_r = np.trim_zeros(b[r:], "b")
    zeros = np.abs(np.roots(b_r)) if len(b_r) > 1 else np.zeros(0)
    outside = zeros[zeros > 1.0 + _UNIT_TOL]
    if outside.size == 0:
        return 0
    return int(np.clip(np.ceil(np.log(1e8) / np.log(np.min(outside))), 8, 256))


def _shifted_inverse(b, a, w, r, method):
    n = len(w)
    v = np.zeros(n)
    if n <= r:
        return v, "causal" if method == "auto" else method
    b_r = np.trim_zeros(b[r:], "b")
    zeros = np.roots(b_r) if len(b_r) > 1 else np.zeros(0)
    nmp = bool(zeros.size) and bool(np.max(np.abs(zeros)) > 1.0 + _UNIT_TOL)
    used = ("stable" if nmp else "causal") if method == "auto" else method
    if used == "causal":
        v[: n - r] = _causal(a, b_r, w[r:])
    else:
        v[: n - r] = _stable(a, b_r, w[r:])
    if r:
        v[n - r :] = v[n - r - 1]
    return v, used


def invert(
    machine,
    y_desired,
    reference=None,
    reg: float = 1e-8,
    method: str = "auto",
    correct_start: bool = False,
):
    """Feedforward input for which the nominal model's output is ``y_desired``.

    Parameters
    ----------
    machine : Machine
        The nominal model (any kind with ``discrete()``, ``controllers()``,
        ``relative_degree`` and ``lifted()``).
    y_desired : array, shape (n, d)
        Desired output relative to the start, on the machine's dt grid.
    reference : array, shape (n, d), optional
        PID reference (on axes with feedback); its response is subtracted first.
    reg : float
        Relative Tikhonov weight of ``method="lifted"`` (> 0).
    method : {"auto", "causal", "stable", "lifted"}
        See the module docstring; ``"auto"`` picks "causal" for minimum-phase axes and
        "stable" for non-minimum-phase ones, per axis.
    correct_start : bool
        Where "stable" is used, take out what its truncated pre-actuation leaves, over the
        first samples (module notes).

    Returns
    -------
    u : array, shape (n, d)

    Raises
    ------
    InputError
        For a wrong shape, non-finite values, an unknown method, reg <= 0, or
        ``method="lifted"`` with n > 6000.

    Examples
    --------
    >>> m = Machine("x", 0.005, ["x"], {"x": ([1.0], [0.2, 1.0, 0.0])})
    >>> t = np.arange(200) * 0.005
    >>> yd = (t**3)[:, None]
    >>> np.allclose(m.simulate(invert(m, yd)), yd)
    True
    """
    if method not in _METHODS:
        raise InputError(f"method: expected one of {', '.join(_METHODS)}, got {method!r}")
    if not (isinstance(reg, (int, float)) and np.isfinite(reg) and reg > 0):
        raise InputError(f"reg: expected a finite regularisation weight > 0, got {reg!r}")
    y = machine.check_signal(y_desired, "y_desired")
    w = y - machine.reference_response(reference) if reference is not None else y.copy()
    n, d = w.shape
    if method == "lifted":
        if n > _LIFTED_MAX_N:
            raise InputError(
                f"y_desired: method 'lifted' solves a dense n x n system, expected n <= "
                f"{_LIFTED_MAX_N}, got n = {n}; use method 'auto'"
            )
        T = machine.lifted(n)
        u = np.empty_like(w)
        for i in range(d):
            TtT = T[i].T @ T[i]
            lam = reg * np.trace(TtT) / n
            TtT[np.diag_indices(n)] += lam
            u[:, i] = linalg.solve(TtT, T[i].T @ w[:, i], assume_a="pos")
        return u
    rel = machine.relative_degree
    u = np.empty_like(w)
    stable = []
    for i, ((b, a), cg) in enumerate(zip(machine.discrete(), machine.controllers(), strict=True)):
        v, used = _shifted_inverse(b, a, w[:, i], int(rel[i]), method)
        if cg is not None:
            v = v + signal.lfilter(cg[0], cg[1], w[:, i])
        u[:, i] = v
        if correct_start and used == "stable" and (k := _correction_length(b, int(rel[i]))):
            stable.append((i, k))
    if stable:
        _correct_starts(machine, w, u, stable, reg)
    return u


def _correct_starts(machine, w: np.ndarray, u: np.ndarray, axes, reg: float) -> None:
    """What the truncated pre-actuation leaves, taken out of ``u`` (in place) over the first
    samples of each ``(axis, k)`` of ``axes`` (module notes)."""
    e = w - machine.simulate(u)
    h = machine.impulse_response(w.shape[0])
    for i, k in axes:
        u[:k, i] += _start_correction(h[:, i], e[:, i], k, reg)
