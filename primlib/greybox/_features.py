"""The grey-box model's regressors: what a machine's input does beyond its linear model.

Per axis the machine is taken as its linear model G driven by the input plus forces that
act at the input (in input units): friction, a force ripple that depends on the absolute
position, a constant disturbance. The input that makes the machine follow a path y is then

    u = G^-1 y + c_v v + c_a a + c_l (d/dt G^-1 y)                  (linear-model error)
          + c_c tanh(v / v_c) + c_s sgn(v) exp(-|v| / v_s)         (Coulomb, Stribeck)
          + c_1 sin(w x) + c_2 cos(w x)                             (ripple, x absolute)
          + c_0                                                     (constant disturbance)

with v and a the path's velocity and acceleration. For a rigid axis K / (M s^2 + B s) the
first line is exact for a wrong M (c_a) and B (c_v); c_l is the first-order term of an
unmodelled lag (u(t + tau) = u + tau u'). Every term is linear in its coefficient, so given
the ripple's spatial frequency w the fit is one least-squares problem (:mod:`._fit`).

Velocity is the mean over the sample interval, ``(y[k+1] - y[k]) / dt``: the input held
over [k, k+1] (ZOH) moves the axis against the friction of that interval, and the inverse
``G^-1 y`` puts ``u[k]`` where ``y[k+1]`` responds to it. The Coulomb term is ``tanh`` of
``v / v_c`` with ``v_c`` a small fraction of the axis's speed (a smooth sign: at rest the
friction is whatever the other forces need, which no regressor can say, and a hard sign
would put a step in the input wherever the sampled velocity changes sign). The exact mean of
the sign over the interval, ``(v0 + v1) / (|v0| + |v1|)`` with the velocity linear between
the samples, was tried (issue 9): it found a Coulomb force within 0.5 % where ``tanh`` needs
a Stribeck term beside it, and the model-only input on rotated paths of the friction
benchmark improved (median 0.018 -> 0.012 mm), but in place it got worse (0.0075 -> 0.012)
and on the example stage's walk-through (static friction 1.5x, measurement noise) the
rotated glyph's first trial went from 0.049 to 0.089 mm: not kept.

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

COULOMB_FRACTION = 0.01  # v_c: this fraction of the axis's typical speed
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
        out[:, 3] = np.tanh(v / (COULOMB_FRACTION * speed))
        out[:, 4] = np.sign(v) * np.exp(-np.abs(v) / (STRIBECK_FRACTION * speed))
    out[:, 5] = 1.0
    if position is not None and w > 0:
        out[:, 6:8] = ripple_columns(position, np.diff(position, append=position[-1]), w)
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
