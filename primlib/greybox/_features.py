"""The grey-box model's regressors: what a machine's input does beyond its linear model.

Per axis the machine is taken as its linear model G driven by the input plus forces that
act at the input (in input units): friction, a force ripple that depends on the absolute
position, a constant disturbance. The input that makes the machine follow a path y is then

    u = G^-1 y + c_v v + c_a a + c_l (d/dt G^-1 y)                  (linear-model error)
          + c_c sgn(v) + c_s sgn(v) exp(-|v| / v_s)                 (Coulomb, Stribeck)
          + c_1 sin(w x) + c_2 cos(w x)                             (ripple, x absolute)
          + c_0                                                     (constant disturbance)

with v and a the path's velocity and acceleration. For a rigid axis K / (M s^2 + B s) the
first line is exact for a wrong M (c_a) and B (c_v); c_l is the first-order term of an
unmodelled lag (u(t + tau) = u + tau u'). Every term is linear in its coefficient, so given
the ripple's spatial frequency w the fit is one least-squares problem (:mod:`._fit`).

Each term is its mean over the sample interval: the input held over [k, k+1] (ZOH) meets
the forces of that interval, and the inverse ``G^-1 y`` puts ``u[k]`` where ``y[k+1]``
responds to it. Velocity is the interval's mean, ``(y[k+1] - y[k]) / dt``. The Coulomb
term is the mean of ``sgn(v)`` with the velocity linear between its values at the samples
(:func:`coulomb_column`): the whole force wherever the axis moves, however slowly, and the
share of each sign in the interval where it reverses. (A ``tanh(v / v_c)`` smooth sign
took less than the whole force below ``v_c``, and the fit made up for it with an invented
Stribeck term.) At rest it is 0: the friction is then whatever the other forces need,
which no regressor can say.

The ripple is likewise its mean over the interval, the motion from ``x[k]`` to ``x[k+1]``
taken uniform: ``sin(w x)`` averages to ``sinc(w dx / 2) sin(w (x[k] + dx / 2))`` with
``dx = x[k+1] - x[k]`` (:func:`ripple_columns`). Taken at ``x[k]`` it would lag by half a
step, ``w dx / 2`` rad -- 0.16 rad for a 5 mm pitch at 0.25 mm per sample, a 16 % error of
the ripple that does not cancel when the path is run elsewhere.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "LINEAR",
    "NONLINEAR",
    "POSITION",
    "TERMS",
    "axis_features",
    "ripple_columns",
    "speed_scale",
]

# column names, in order
LINEAR = ("velocity", "acceleration", "lag")
NONLINEAR = ("coulomb", "stribeck", "bias")
POSITION = ("ripple_sin", "ripple_cos")
TERMS = LINEAR + NONLINEAR + POSITION

REST_FRACTION = 1e-6  # below this fraction of the axis's typical speed an axis is at rest
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
        smoothing velocities of the friction terms.
    position : array, shape (n,) or None
        Absolute position of the axis (``y`` plus where the path started on the machine);
        None where unknown: the ripple columns are then zero.
    w : float
        Spatial angular frequency of the ripple (rad per user unit); 0 = no ripple.
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
    if speed > 0:
        out[:, 3] = coulomb_column(y, dt, speed)
        out[:, 4] = np.sign(v) * np.exp(-np.abs(v) / (STRIBECK_FRACTION * speed))
    out[:, 5] = 1.0
    if position is not None and w > 0:
        out[:, 6:8] = ripple_columns(position, np.diff(position, append=position[-1]), w)
    return out


def coulomb_column(y: np.ndarray, dt: float, speed: float) -> np.ndarray:
    """The mean of ``sgn(v)`` over each sample interval, shape (n,).

    With the velocity taken linear over the interval between its values at the samples
    (central differences, ``v0`` and ``v1``), the mean is ``(v0 + v1) / (|v0| + |v1|)``:
    the sign where both agree, the share of the interval on each side where the motion
    reverses. Velocities below ``REST_FRACTION`` of the axis's speed count as rest (0: at
    rest the friction is whatever the other forces need, which no regressor can say; a
    nearly still axis would otherwise flip a full Coulomb force on its rounding noise).
    """
    v = np.gradient(y, dt) if y.shape[0] > 1 else np.zeros_like(y)
    v = np.where(np.abs(v) > REST_FRACTION * speed, v, 0.0)
    v0, v1 = v, np.append(v[1:], v[-1])
    den = np.abs(v0) + np.abs(v1)
    return np.divide(v0 + v1, den, out=np.zeros_like(v0), where=den > 0)


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
