"""The grey-box model's regressors: what a machine's input does beyond its linear model.

Per axis the machine is taken as its linear model G driven by the input plus forces that
act at the input (in input units): friction, a force ripple that depends on the absolute
position, a constant disturbance. The input that makes the machine follow a path y is then

    u = G^-1 y + c_v v + c_a a + c_l (d/dt G^-1 y)                  (linear-model error)
          + c_c s(v) + c_s sgn(v) exp(-|v| / v_s)     (Coulomb, Stribeck; s a sign, below)
          + c_1 sin(w x) + c_2 cos(w x)                             (ripple, x absolute)
          + c_0                                                     (constant disturbance)

with v and a the path's velocity and acceleration. For a rigid axis K / (M s^2 + B s) the
first line is exact for a wrong M (c_a) and B (c_v); c_l is the first-order term of an
unmodelled lag (u(t + tau) = u + tau u'). Every term is linear in its coefficient, so given
the ripple's spatial frequency w the fit is one least-squares problem (:mod:`._fit`).

Velocity is the mean over the sample interval, ``(y[k+1] - y[k]) / dt``: the input held
over [k, k+1] (ZOH) moves the axis against the friction of that interval, and the inverse
``G^-1 y`` puts ``u[k]`` where ``y[k+1]`` responds to it. The Coulomb term comes in two
shapes, chosen per axis by the fit (:mod:`._fit`):

- smooth, ``tanh(v / v_c)`` with ``v_c`` 1 % of the axis's speed, the Stribeck term
  ``sgn(v) exp(-|v| / v_s)``: what a machine whose friction rises smoothly through zero
  velocity needs (the example stage, static friction 1.5x the Coulomb level: the moved
  glyph 0.046 mm with it, 0.084 with the hard sign);
- hard, ``sgn(v)`` and 0 where the axis rests (``|v|`` below :data:`~._robust.REST` of
  its speed: rounding, not motion; at rest the friction is whatever the other forces need,
  up to the static level, which no regressor can say), the Stribeck term likewise: what a
  plain Coulomb machine needs once the stored rows their paths do not determine are
  replaced (:mod:`._robust`). On issue 9's friction 2 % benchmark (scratch comparison of
  the model-only input, 3 rotated and time-scaled paths, mm): smooth 0.018 median, 0.031
  worst; hard with those rows kept 0.0065, 0.035; hard with them replaced 0.001-0.003, the
  fitted Coulomb levels within 0.6 % (smooth: 5-11 % low).

The ripple is likewise its mean over the interval, the motion from ``x[k]`` to ``x[k+1]``
taken uniform: ``sin(w x)`` averages to ``sinc(w dx / 2) sin(w (x[k] + dx / 2))`` with
``dx = x[k+1] - x[k]`` (:func:`ripple_columns`). Taken at ``x[k]`` it would lag by half a
step, ``w dx / 2`` rad -- 0.16 rad for a 5 mm pitch at 0.25 mm per sample, a 16 % error of
the ripple that does not cancel when the path is run elsewhere.
"""

from __future__ import annotations

import numpy as np

from primlib.greybox._robust import moving

__all__ = [
    "LINEAR",
    "NONLINEAR",
    "POSITION",
    "TERMS",
    "axis_features",
    "hard_friction",
    "ripple_columns",
    "speed_scale",
]

# column names, in order
LINEAR = ("velocity", "acceleration", "lag")
NONLINEAR = ("coulomb", "stribeck", "bias")
POSITION = ("ripple_sin", "ripple_cos")
TERMS = LINEAR + NONLINEAR + POSITION

COULOMB_FRACTION = 0.01  # v_c of the smooth sign: this fraction of the axis's typical speed
STRIBECK_FRACTION = 0.1  # v_s: this fraction of the axis's typical speed


def speed_scale(velocities: np.ndarray) -> float:
    """The axis's typical speed: the 90th percentile of |v| (0 when it did not move)."""
    v = np.abs(np.asarray(velocities, dtype=float))
    return float(np.percentile(v, 90)) if v.size else 0.0


def axis_features(
    y: np.ndarray,
    u_lin: np.ndarray,
    dt: float,
    speed: float,
    position: np.ndarray | None,
    w: float,
    hard: bool = False,
    from_rest: bool = False,
) -> np.ndarray:
    """Regressors of one axis, shape (n, 8) in the order of :data:`TERMS`.

    Parameters
    ----------
    y : array, shape (n,)
        The path on this axis, relative to its start (user units).
    u_lin : array, shape (n,)
        The linear model's inverse of ``y`` on this axis.
    dt : float
    speed : float
        The axis's typical speed (:func:`speed_scale` of the fitted data); sets the
        Stribeck velocity and what counts as rest.
    position : array, shape (n,) or None
        Absolute position of the axis (``y`` plus where the path started on the machine);
        None where unknown: the ripple columns are then zero.
    w : float
        Spatial angular frequency of the ripple (rad per user unit); 0 = no ripple.
    hard : bool
        The Coulomb and Stribeck columns with a hard sign, 0 at rest
        (:func:`hard_friction`); else the smooth sign.
    from_rest : bool
        The lag column's first value with the input's rise from rest at t = 0 (an input to
        run from rest: :meth:`GreyBox.terms`). The fit's columns keep the one-sided
        difference its coefficients were measured with: taken from rest there too, the
        stored pairs' fits moved (on issue 9's ripple 2 % library the translated warm start
        went from 0.77x to 1.15x the model-only input) for no gain on paths at rest.
    """
    n = y.shape[0]
    out = np.zeros((n, len(TERMS)))
    if n < 2:
        return out
    v = np.empty(n)
    v[:-1] = np.diff(y) / dt
    v[-1] = v[-2]
    out[:, 0] = v
    out[:, 1] = np.gradient(v, dt)
    out[:, 2] = np.gradient(u_lin, dt)
    if from_rest:
        # the axis rests before t = 0 (u = 0): the rise to u_lin[0] is part of the
        # derivative, and half of it, which a central difference puts at t = -dt where no
        # input acts, is taken at t = 0. The column's area is then u_lin's last value, as
        # the lag's shift of the input leaves it; the one-sided difference dropped the rise,
        # and on a path already moving at t = 0 (u_lin[0] the impulse that starts it) the
        # lag term took that impulse's share away, which an integrating axis kept as an
        # offset (127 mm on a 12 s novel path)
        out[0, 2] = (u_lin[1] + u_lin[0]) / (2.0 * dt)
    if speed > 0:
        out[:, 3] = np.tanh(v / (COULOMB_FRACTION * speed))
        out[:, 4] = np.sign(v) * np.exp(-np.abs(v) / (STRIBECK_FRACTION * speed))
    out[:, 5] = 1.0
    if position is not None and w > 0:
        out[:, 6:8] = ripple_columns(position, np.diff(position, append=position[-1]), w)
    return hard_friction(out, speed) if hard else out


def hard_friction(F: np.ndarray, speed: float) -> np.ndarray:
    """``F`` (regressors of one axis, column 0 the velocity) with its Coulomb and
    Stribeck columns in the hard shape: ``sgn(v)``, 0 where the axis rests."""
    out = F.copy()
    if speed > 0:
        v = F[:, 0]
        sign = np.where(moving(v, speed), np.sign(v), 0.0)
        out[:, 3] = sign
        out[:, 4] = sign * np.exp(-np.abs(v) / (STRIBECK_FRACTION * speed))
    return out


def ripple_columns(position: np.ndarray, step: np.ndarray, w: float) -> np.ndarray:
    """``sin(w x)`` and ``cos(w x)`` averaged over each sample interval, shape (n, 2).

    ``position[k]`` is where interval k starts and ``step[k]`` how far it moves (the next
    sample's position less this one's; 0 at the end): the mean of ``sin(w x)`` over
    ``[x, x + dx]`` is ``sinc(w dx / 2) sin(w (x + dx / 2))``, and likewise for cos.
    """
    half = 0.5 * w * step
    damp = np.sinc(half / np.pi)  # numpy's sinc is sin(pi t) / (pi t)
    mid = w * position + half
    return np.stack([damp * np.sin(mid), damp * np.cos(mid)], axis=1)


def ripple_grid(
    position: np.ndarray, step: np.ndarray, ws: np.ndarray, weight: np.ndarray | None = None
) -> np.ndarray:
    """:func:`ripple_columns` at each of the evenly spaced frequencies ``ws``, shape
    (len(ws), 2, n): sin rows, then cos rows; each row times ``weight`` where given.

    The sines and cosines of ``w x`` and of ``w dx / 2`` are taken once at the first
    frequency and at the spacing, and rotated to each next frequency by the angle-sum
    identities -- four products a row instead of three transcendental functions and a
    division (the ripple search scores thousands of frequencies, and the sin, cos and sinc
    of each were most of a grey-box fit's time). The rotation's round-off grows by about an
    ulp a step; against the direct formula, 5e-12 at 64 steps and phases of 3e4 rad, where
    the direct formula's own round-off is of that order.
    """
    ws = np.asarray(ws, dtype=float)
    half = 0.5 * step
    mid = position + half
    count = ws.size
    dw = (ws[-1] - ws[0]) / (count - 1) if count > 1 else 0.0
    s, c = np.sin(ws[0] * mid), np.cos(ws[0] * mid)
    sd, cd = np.sin(dw * mid), np.cos(dw * mid)
    hs, hc = np.sin(ws[0] * half), np.cos(ws[0] * half)
    hsd, hcd = np.sin(dw * half), np.cos(dw * half)
    moves = half != 0  # not the module's ``moving`` (a speed threshold): an exact zero here
    wt = np.ones_like(half) if weight is None else np.asarray(weight, dtype=float)
    # sinc(w dx / 2) = sin(w h) / (w h), 1 where the sample does not move (h = 0, where the
    # rotated sin(w h) stays exactly 0): hs * inv / w + rest, the weight folded into both
    inv = np.divide(wt, half, out=np.zeros_like(half), where=moves)
    rest = np.where(moves, 0.0, wt)
    out = np.empty((count, 2, position.size))
    damp = np.empty_like(half)
    for k in range(count):
        if k:
            s, c = s * cd + c * sd, c * cd - s * sd
            hs, hc = hs * hcd + hc * hsd, hc * hcd - hs * hsd
        if ws[k] != 0:
            np.multiply(hs, inv, out=damp)
            damp *= 1.0 / ws[k]
            damp += rest
        else:
            damp[:] = wt
        np.multiply(damp, s, out=out[k, 0])
        np.multiply(damp, c, out=out[k, 1])
    return out
