"""Time scaling and superposition of a stored signal (primitive-matching paper, §3.3).

Notation. A stored primitive has input ``u_l`` (n_l, d) on the machine's dt grid, learned so
that the machine's output ``y_l = G u_l`` follows the primitive's path (as a deviation from
its first point). A new piece wants ``y_d(t) = R y_l(k t) + p``: the primitive run ``k``
times faster (k = primitive duration / new duration, the matcher's ``time_scale``), rotated
by ``R`` and shifted by ``p``.

Model-based time scale (one stored version). In Laplace terms, with w(t) = u_l(k t),
``Y_d(s) = (1/k) Y_l(s/k) = G(s/k) W(s)``, so the input is

    U_d(s) = G(s/k) / G(s) · W(s)                         # the time-scale filter

e.g. ``k (T s + 1) / (T s / k + 1)`` for an XYZ axis K / (T s^2 + s) (eq. 24) — a lead-lag
between gain k (slow parts) and k^2 (fast parts). On a machine that differs from the
model G by Δ = G_true / G, the true output of U_d misses ``y_d`` by
``(Δ(s) − Δ(s/k)) G(s/k) W``: the library's signal already holds Δ, only its change over
a frequency band of ratio k enters (nothing for k = 1, nothing for a pure gain error).

The filter acts on the continuous signal u_l(k t), which a ZOH signal resampled on a new dt
grid is not (its steps fall at multiples of dt / k). So the transform is computed where it
is exact, at the samples: the stored input's continuous output ``y_l(t)`` is computed
exactly between samples (:func:`primlib.splice._continuous.continuous_output`), the target
is ``R y_l(k t_q) + p`` at the new sample times t_q, and the input that makes the nominal
model produce it is a first guess ``R u_l(k t)`` (resampled, :func:`resample_zoh`) plus the
nominal-model inverse (:func:`primlib.plant.invert`) of the guess's sample residual. On the
nominal machine the output equals the target at every sample to rounding; for a minimum-
phase model the inverse is the exact causal one, for a non-minimum-phase one (the PDCCILC
stage, eq. (33)) the stable non-causal inverse, bounded, with its error confined to the
start. Between samples the output differs from the continuous ideal by the ZOH ripple of
the new input, O(dt) in the input, which no input on the dt grid can remove.

Superposition (eq. 11 and the matrix R^u). Where axes have different models the rotated
input mixes them through ``P_j / P_i``: ``u_d,i = Σ_j R_ij P_i^{-1} P_j u_j`` — computed the
same way (target ``R y_l``, correction by the inverse); between identical axes (same plant,
same PID) the ratio is 1 and the input is exactly ``R u``, no model involved. Translation
adds the holding input of eqs. (16)-(18): the input that keeps an axis at offset p_i in
steady state — zero for integrating axes, ``p_i / P_i(0)`` (offset over DC gain) otherwise,
also under a PID with integral action (a tracking feedforward keeps the PID's error zero).
The paper's settling-time construction of u_I (its figure 3) is this DC input once
transients have died out.

Model-free time scale (eq. (20), Xu's direct learning). When the same primitive is stored
at several durations, the model coefficients are not needed, only the structure. For an
all-pole axis ``u = Σ_p c_p y^(p)`` (eq. 24: p ∈ {1, 2}), a version run at ``k_i`` times the
target speed and resampled to target time satisfies ``u_i(k_i t) = Σ_p k_i^{-p} A_p(t)`` with
``A_p = c_p y_d^(p)`` and ``u_d = Σ_p A_p``. Least squares over the versions per sample gives
``u_d = 1^T (M^T M)^{-1} M^T [u_1(k_1 t), ...]``, ``M_ip = k_i^{-p}`` — the paper's eq. (20)
after multiplying each row by k_i (its A_l = [k^{-1} I, I] is p ∈ {2, 1} scaled by k; the
paper leaves that factor implicit in u_i). It is exact in continuous time for any
Δ with the same structure; on the ZOH grid the resampling leaves O(dt^2) and the ZOH's own
dt/2 delay O(dt) (which the midpoint convention of :func:`resample_zoh` cancels to first
order). It needs as many distinct time scales as orders.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from primlib._errors import InputError
from primlib.splice._continuous import continuous_output, resample_linear, resample_zoh
from primlib.splice._inverse import model_inverse

__all__ = [
    "time_scale",
    "superpose",
    "transform",
    "time_scale_direct",
    "holding_input",
    "derivative_orders",
    "piece_path",
    "piece_error",
]


def _check_u(machine, u, what: str = "u") -> np.ndarray:
    arr = np.asarray(u, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != machine.dim or arr.shape[0] < 2:
        raise InputError(
            f"{what}: expected an array of shape (n >= 2, {machine.dim}) for axes "
            f"{','.join(machine.axes)}, got shape {np.shape(u)}"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{what}: expected finite values, got NaN or inf")
    return arr


def _check_rotation(machine, rotation) -> np.ndarray:
    d = machine.dim
    if rotation is None:
        return np.eye(d)
    r = np.asarray(rotation, dtype=float)
    if r.shape != (d, d) or not np.all(np.isfinite(r)):
        raise InputError(f"rotation: expected a finite {d} x {d} matrix, got shape {r.shape}")
    if not np.allclose(r @ r.T, np.eye(d), atol=1e-6) or np.linalg.det(r) < 0:
        raise InputError(
            f"rotation: expected a proper rotation (R R^T = I, det = +1), got det "
            f"{np.linalg.det(r):.6g}"
        )
    return r


def _check_k(k) -> float:
    try:
        k = float(k)
    except (TypeError, ValueError):
        raise InputError(f"k: expected a time scale > 0, got {k!r}") from None
    if not np.isfinite(k) or k <= 0:
        raise InputError(f"k: expected a finite time scale > 0, got {k}")
    return k


def _axis_signatures(machine) -> list[str]:
    """One string per axis; equal strings mean identical axis dynamics (plant and PID)."""
    plants = machine.plants
    fb = machine.feedback or {}
    out = []
    for a in machine.axes:
        num, den = plants[a]
        scale = den[0]
        pid = fb.get(a)
        out.append(
            repr(
                (
                    np.round(num / scale, 12).tolist(),
                    np.round(den / scale, 12).tolist(),
                    None if pid is None else sorted(pid.items()),
                )
            )
        )
    return out


def _mixing_rows(machine, rotation: np.ndarray) -> np.ndarray:
    """Rows of R that combine axes with different dynamics (need the model), shape (d,)."""
    sig = _axis_signatures(machine)
    d = machine.dim
    need = np.zeros(d, dtype=bool)
    for i in range(d):
        for j in range(d):
            if j != i and abs(rotation[i, j]) > 0.0 and sig[j] != sig[i]:
                need[i] = True
    return need


def holding_input(machine, offset) -> np.ndarray:
    """Input that holds each axis at a constant offset in steady state (eqs. (16)-(18)).

    Parameters
    ----------
    machine : Machine
    offset : array, shape (d,)
        Output offset per axis.

    Returns
    -------
    u : array, shape (d,)
        Zero on an integrating axis (the position stays where the motion left it);
        otherwise ``p_i / P_i(0)``, also under a PID with integral action: a feedforward
        that tracks keeps the PID's error and so its integral at zero, so it must hold the
        offset itself (an integrator charged by the motion is not what the stored signals
        assumed).
    """
    p = np.asarray(offset, dtype=float).reshape(-1)
    if p.shape != (machine.dim,) or not np.all(np.isfinite(p)):
        raise InputError(
            f"translation: expected {machine.dim} finite numbers, got shape {np.shape(offset)}"
        )
    out = np.zeros(machine.dim)
    for i, (b, a) in enumerate(machine.discrete()):
        a1, b1 = float(np.sum(a)), float(np.sum(b))
        if abs(a1) <= 1e-12 * float(np.sum(np.abs(a))):
            continue  # integrating axis: the position stays where the motion left it
        # a feedforward that tracks keeps the PID's error, hence its integral, at zero: the
        # feedforward alone holds the offset, also under integral action
        out[i] = p[i] * a1 / b1
    return out


def _default_n(n_l: int, dt: float, k: float, offset: float) -> int:
    """Output length that covers the whole primitive: ``round((T_l / k - offset) / dt) + 1``."""
    return int(round(((n_l - 1) * dt / k - offset) / dt)) + 1


def _onto_new_grid(
    samples: np.ndarray, dt: float, k: float, rot: np.ndarray, offset: float, n: int
) -> np.ndarray:
    """Stored samples (n_l, d) on the dt grid, read at primitive time ``k (offset + i dt)``
    for i < n and rotated: zero before the primitive starts, the last sample held after it
    ends; off the stored grid a cubic spline through the samples."""
    n_l = samples.shape[0]
    if k == 1.0 and abs(offset) <= 1e-12:
        return samples[np.minimum(np.arange(n), n_l - 1)] @ rot.T
    from scipy.interpolate import CubicSpline

    tau = k * (offset + np.arange(n) * dt)
    t_l = np.arange(n_l) * dt
    y = CubicSpline(t_l, samples, axis=0)(np.clip(tau, 0.0, t_l[-1]))
    y[tau < 0] = 0.0
    return y @ rot.T


def transform(
    machine,
    u,
    *,
    k: float = 1.0,
    rotation=None,
    offset: float = 0.0,
    n: int | None = None,
    reference=None,
) -> np.ndarray:
    """Input for ``y_d(t) = R y_l(k t)`` on the nominal machine, from rest, on a dt grid.

    The general form of :func:`time_scale` and :func:`superpose` (without the holding
    input): one residual inversion for both. See the module docstring for the derivation.

    Parameters
    ----------
    machine : Machine
        The nominal model.
    u : array, shape (n_l, d)
        The stored input (primitive time, dt grid).
    k : float
        Time scale (> 0): new time t is primitive time k t.
    rotation : array, shape (d, d), optional
        Proper rotation applied to the output (identity when None).
    offset : float
        New time of output sample 0, seconds, in (-dt, 0] to start from rest (the primitive
        starts at new time 0). A piece cut from a path places its grid with it.
    n : int, optional
        Output length; default covers the whole primitive, ``round((T_l / k - offset) / dt)
        + 1``.
    reference : array, shape (n_l, d), optional
        The PID reference the stored input was learned with (feedback machines); the new
        reference is it transformed the same way.

    Returns
    -------
    u_new : array, shape (n, d)
    """
    u = _check_u(machine, u)
    k = _check_k(k)
    rot = _check_rotation(machine, rotation)
    dt = machine.dt
    n_l = u.shape[0]
    offset = float(offset)
    if not (-dt - 1e-12 < offset <= 1e-12):
        raise InputError(f"offset: expected a start time in (-dt, 0] = (-{dt}, 0], got {offset}")
    if n is None:
        n = _default_n(n_l, dt, k, offset)
    n = int(n)
    if n < 2:
        raise InputError(f"n: expected an output length >= 2, got {n}")
    ref = None
    if reference is not None:
        ref = _check_u(machine, reference, "reference")
        if ref.shape != u.shape:
            raise InputError(f"reference: expected the shape of u {u.shape}, got {ref.shape}")
    on_grid = k == 1.0 and abs(offset) <= 1e-12
    if on_grid:
        idx = np.minimum(np.arange(n), n_l - 1)
        w = u[idx] @ rot.T
        need = _mixing_rows(machine, rot)
        if not need.any():
            return w  # identical axes and no time scale: exactly R u
    else:
        w = resample_zoh(u, k, n, offset, dt) @ rot.T
        need = np.ones(machine.dim, dtype=bool)
    t_new = offset + np.arange(n) * dt
    target = continuous_output(machine, u, k * t_new, ref) @ rot.T
    ref_new = None
    if ref is not None:
        pos = np.maximum(k * t_new, 0.0) / dt
        ref_new = resample_linear(ref, pos) @ rot.T
        ref_new[k * t_new < 0] = 0.0
    resid = target - machine.simulate(w, ref_new)
    delta = model_inverse(machine, resid)
    delta[:, ~need] = 0.0
    return w + delta


def piece_path(
    machine,
    u,
    points,
    *,
    k: float = 1.0,
    rotation=None,
    offset: float = 0.0,
    n: int | None = None,
    reference=None,
) -> np.ndarray:
    """What a transformed piece was built to track: ``R y_l(k t)`` on the new grid, from rest.

    ``y_l`` is the stored primitive's path (``points - points[0]``), i.e. what its input
    did on the machine it was learned on, not what the model says it does. Off the stored
    grid (k != 1 or an offset) the samples are interpolated by a cubic spline (error
    O(dt^4) times the path's fourth derivative; the stored path is smooth, whereas the
    stored input and its output between samples are not).

    Parameters
    ----------
    machine : Machine
        The model used for the transform.
    u : array, shape (n_l, d)
        Stored input.
    points : array, shape (n_l, d)
        Stored path on the same grid (absolute coordinates).
    k, rotation, offset, n, reference
        As :func:`transform`.

    Returns
    -------
    y : array, shape (n, d)
        Relative to the primitive's first point, rotated; after the stored end the last
        input is held.
    """
    u = _check_u(machine, u)
    pts = np.asarray(points, dtype=float)
    if pts.shape != u.shape:
        raise InputError(f"points: expected the shape of u {u.shape}, got {pts.shape}")
    k = _check_k(k)
    rot = _check_rotation(machine, rotation)
    dt = machine.dt
    n_l = u.shape[0]
    offset = float(offset)
    if n is None:
        n = _default_n(n_l, dt, k, offset)
    return _onto_new_grid(pts - pts[0], dt, k, rot, offset, int(n))


def piece_error(
    machine,
    u,
    points,
    *,
    k: float = 1.0,
    rotation=None,
    offset: float = 0.0,
    n: int | None = None,
    reference=None,
) -> np.ndarray:
    """The model's output error on a stored pair, transformed like the piece: ``R e_l(k t)``.

    ``e_l = y_l - G u`` at the stored samples, with ``y_l`` the stored path (what the input
    did on the machine it was learned on) and ``G u`` the model's output of the stored
    input; off the stored grid interpolated by a cubic spline (the samples carry the
    machine's error; the output between them also carries the stored input's ZOH ripple,
    which a new input on a new grid does not share).

    Parameters
    ----------
    machine, u, points, k, rotation, offset, n, reference
        As :func:`piece_path`.

    Returns
    -------
    e : array, shape (n, d)
        Zero before the primitive starts; held after it ends.
    """
    u = _check_u(machine, u)
    pts = np.asarray(points, dtype=float)
    if pts.shape != u.shape:
        raise InputError(f"points: expected the shape of u {u.shape}, got {pts.shape}")
    rot = _check_rotation(machine, rotation)
    k = _check_k(k)
    dt = machine.dt
    n_l = u.shape[0]
    offset = float(offset)
    if n is None:
        n = _default_n(n_l, dt, k, offset)
    n = int(n)
    ref = None if reference is None else _check_u(machine, reference, "reference")
    err = (pts - pts[0]) - machine.simulate(u, ref)
    return _onto_new_grid(err, dt, k, rot, offset, n)


def time_scale(
    machine, u, k: float, *, offset: float = 0.0, n: int | None = None, reference=None
) -> np.ndarray:
    """The stored input of a primitive run k times faster (model-based, one version).

    For ``y_d(t) = y_l(k t)`` on an LTI axis G the input is ``u_l(k t)`` filtered by
    ``G(s/k) / G(s)``; computed exactly at the samples on the nominal model (see
    :mod:`primlib.splice._transform`).

    Parameters
    ----------
    machine : Machine
    u : array, shape (n_l, d)
    k : float
        Primitive duration / new duration (> 1: faster).
    offset, n, reference
        See :func:`transform`.

    Returns
    -------
    u_new : array, shape (n, d)
        On the nominal machine ``machine.simulate(u_new)`` equals the stored output at
        times ``k t`` (to rounding; after the stored end, its last input held).

    Raises
    ------
    InputError
        For a bad shape, non-finite values, k <= 0 or an offset outside (-dt, 0].

    Examples
    --------
    >>> u2 = time_scale(m, u, 2.0)          # twice as fast, half as long
    >>> len(u2) == (len(u) - 1) // 2 + 1
    True
    >>> y, y2 = m.simulate(u), m.simulate(u2)
    >>> bool(np.allclose(y2, y[::2], atol=1e-9 * np.abs(y).max()))   # the same path, twice as fast
    True
    """
    return transform(machine, u, k=k, offset=offset, n=n, reference=reference)


def superpose(machine, u, rotation, translation=None, *, reference=None) -> np.ndarray:
    """Input for the rotated and translated output ``R y_l + p`` (eqs. (11)-(18)).

    Parameters
    ----------
    machine : Machine
    u : array, shape (n, d)
        Stored input from rest.
    rotation : array, shape (d, d)
        Proper rotation.
    translation : array, shape (d,), optional
        Output offset p; adds the holding input (:func:`holding_input`).
    reference : array, shape (n, d), optional
        PID reference the input was learned with (feedback machines).

    Returns
    -------
    u_new : array, shape (n, d)
        ``R u`` exactly where the axes mixed are identical; otherwise mixed through the
        model ratios P_j / P_i (computed at the samples), plus the holding input.
    """
    u = _check_u(machine, u)
    out = transform(machine, u, rotation=rotation, n=u.shape[0], reference=reference)
    if translation is not None:
        out = out + holding_input(machine, translation)[None, :]
    return out


def derivative_orders(machine) -> tuple[int, ...] | None:
    """Derivative orders p with ``u = Σ_p c_p y^(p)`` on every axis, or None.

    Defined for all-pole plants (constant numerator): the orders of the denominator's
    non-zero coefficients, united over the axes (eq. 24 gives (1, 2)). None when a plant
    has zeros: its inverse is not a finite sum of derivatives and eq. (20) does not apply.
    """
    orders: set[int] = set()
    for a in machine.axes:
        num, den = machine.plants[a]
        if len(np.trim_zeros(np.asarray(num, float), "f")) != 1:
            return None
        deg = len(den) - 1
        orders |= {deg - i for i, c in enumerate(den) if c != 0.0}
    return tuple(sorted(orders))


def time_scale_direct(
    versions: Sequence[tuple[np.ndarray, float]],
    n: int,
    dt: float,
    *,
    orders: Sequence[int] = (1, 2),
    offset: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Model-free time scaling from versions at several speeds (eq. (20), Xu's direct learning).

    Parameters
    ----------
    versions : sequence of (u_i, k_i)
        Stored inputs of the same primitive (same shape and pose), ``u_i`` shape (n_i, d)
        on the dt grid, with ``k_i`` = that version's duration / the target duration.
    n : int
        Output length.
    dt : float
        Sample time.
    orders : sequence of int
        Derivative orders of the axis inverse (:func:`derivative_orders`).
    offset : float
        Target time of output sample 0 (see :func:`resample_zoh`).

    Returns
    -------
    u : array, shape (n, d)
        ``Σ_i w_i u_i(k_i t)``.
    weights : array, shape (len(versions),)
        The least-squares combination ``1^T (M^T M)^{-1} M^T``, ``M_ip = k_i^{-p}``.

    Raises
    ------
    InputError
        With fewer versions than orders, or time scales too close to separate the orders.
    """
    orders = tuple(int(p) for p in orders)
    if len(versions) < len(orders):
        raise InputError(
            f"versions: eq. (20) separates {len(orders)} derivative orders {orders} and needs "
            f"as many time scales, got {len(versions)}"
        )
    ks = np.array([float(kv) for _, kv in versions])
    if not np.all(np.isfinite(ks)) or np.any(ks <= 0):
        raise InputError(f"versions: expected time scales > 0, got {ks.tolist()}")
    m = ks[:, None] ** (-np.asarray(orders, dtype=float))[None, :]  # eq. (20), A_l
    if np.linalg.cond(m) > 1e8:
        raise InputError(
            f"versions: time scales {np.round(ks, 6).tolist()} are too close to separate "
            f"derivative orders {orders} (condition number {np.linalg.cond(m):.3g})"
        )
    weights = np.linalg.pinv(m).sum(axis=0)  # [I I] (A^T A)^-1 A^T, eq. (20)
    dims = {np.asarray(v).shape[1] for v, _ in versions}
    if len(dims) != 1:
        raise InputError(f"versions: expected signals with one column count, got {sorted(dims)}")
    out = np.zeros((int(n), dims.pop()))
    for (ui, ki), wi in zip(versions, weights, strict=True):
        out += wi * resample_zoh(np.asarray(ui, dtype=float), ki, int(n), offset, dt)
    return out, weights
