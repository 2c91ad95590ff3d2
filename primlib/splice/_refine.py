"""The machine as the library's own signals describe it: a refined model for the transforms.

Every stored primitive is a pair measured on the real machine: the converged input u_l and
the path y_l it produced (ILC made the output equal to the path). The nominal model G
predicts ``G u_l``; where that differs from ``y_l`` the machine differs from its model, and
the time-scale filter G(s/k)/G(s) and the axis ratios P_j/P_i inherit the difference
(the warm start's error is ``(Δ(s) - Δ(s/k)) G(s/k) W``, see :mod:`._transform`). So before
transforming, the model is refined on the library's pairs, per axis, within the family

    G_θ(s) = g · num(s) / den(c s) · 1 / (τ s + 1),     θ = (g, c, τ)

— a gain, a common scale of the model's time constants, and one unmodelled first-order lag
— by least squares on the output error ``G_θ u_l - y_l`` over the primitives the match uses.
θ = (1, 1, 0) is the nominal model itself, which the fit returns (to the ILC residual) when
the machine is its model. Open-loop axes only: under PID feedback the stored feedforward
does not see the plant alone, and those axes keep their nominal model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy import optimize

from primlib.plant import Machine

__all__ = ["RefinedModel", "refine_machine"]

_BOUNDS = ((0.5, 0.5, 0.0), (2.0, 2.0, 0.2))  # g, c, tau [s]


@dataclass(frozen=True)
class RefinedModel:
    """Result of :func:`refine_machine`.

    Attributes
    ----------
    machine : Machine
        The refined model (same name, dt, axes; nominal where not refined).
    theta : array, shape (d, 3)
        (gain, time-constant scale, extra lag in s) per axis; (1, 1, 0) = nominal.
    rms_nominal, rms_refined : array, shape (d,)
        RMS output error of the nominal and refined models on the pairs.
    """

    machine: object
    theta: np.ndarray
    rms_nominal: np.ndarray
    rms_refined: np.ndarray


def _axis_tf(num, den, theta):
    g, c, tau = theta
    deg = len(den) - 1
    den_c = np.asarray(den, float) * c ** np.arange(deg, -1, -1)  # den(c s)
    den_t = np.convolve(den_c, [tau, 1.0]) if tau > 1e-9 else den_c
    return g * np.asarray(num, float), den_t


def _axis_residual(theta, num, den, dt: float, inputs, outputs, scale: float) -> np.ndarray:
    """Output error of one axis's G_θ on all pairs, relative to ``scale``, concatenated."""
    n_, d_ = _axis_tf(num, den, theta)
    m = Machine("fit", dt, ("a",), {"a": (n_, d_)})
    return np.concatenate(
        [(m.simulate(u[:, None])[:, 0] - y) / scale for u, y in zip(inputs, outputs, strict=True)]
    )


def _fit_axis(resid, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """θ for one axis, or (1, 1, 0) when the fit does not lower the error: (θ, r0, r1)."""
    nominal = np.array([1.0, 1.0, 0.0])
    r0 = resid(nominal)
    try:
        sol = optimize.least_squares(
            resid,
            x0=[1.0, 1.0, 0.002],
            bounds=_BOUNDS,
            x_scale=[0.1, 0.1, 0.01],
            xtol=1e-10,
            ftol=1e-12,
            max_nfev=200,
        )
        th = sol.x
        r1 = resid(th)
    except (ValueError, np.linalg.LinAlgError):
        th, r1 = nominal, r0
    if th[2] < 0.1 * dt:
        # a lag far below the sample time is not resolvable at this rate (and would put a
        # sampling zero outside the unit circle for nothing): leave it out
        th = np.array([th[0], th[1], 0.0])
        r1 = resid(th)
    if np.sum(r1**2) < np.sum(r0**2):
        return th, r0, r1
    return nominal, r0, r0


def refine_machine(machine, pairs: Sequence[tuple[np.ndarray, np.ndarray]]) -> RefinedModel:
    """Fit (gain, time-constant scale, extra lag) per open-loop axis to stored pairs.

    A pure function of the model and the pairs (the pipeline's ``WarmStarter`` keeps its
    results).

    Parameters
    ----------
    machine : Machine
        The nominal model.
    pairs : sequence of (u, y)
        Stored inputs, shape (n_i, d), and the outputs they produced on the machine, shape
        (n_i, d) (a primitive's path minus its first point).

    Returns
    -------
    RefinedModel
    """
    d = machine.dim
    theta = np.tile([1.0, 1.0, 0.0], (d, 1))
    rms0 = np.zeros(d)
    rms1 = np.zeros(d)
    if machine.feedback or not pairs:
        return RefinedModel(machine, theta, rms0, rms1)
    new_plants = {}
    for i, axis in enumerate(machine.axes):
        num, den = machine.plants[axis]
        inputs = [np.asarray(u, float)[:, i] for u, _ in pairs]
        outputs = [np.asarray(y, float)[:, i] for _, y in pairs]
        scale = max(float(np.max(np.abs(np.concatenate(outputs)))), 1e-12)
        resid = partial(
            _axis_residual,
            num=num,
            den=den,
            dt=machine.dt,
            inputs=inputs,
            outputs=outputs,
            scale=scale,
        )
        theta[i], r0, r1 = _fit_axis(resid, machine.dt)
        rms0[i] = np.sqrt(np.mean(r0**2)) * scale
        rms1[i] = np.sqrt(np.mean(r1**2)) * scale
        new_plants[axis] = _axis_tf(num, den, theta[i])
    refined = Machine(machine.name, machine.dt, machine.axes, new_plants)
    return RefinedModel(refined, theta, rms0, rms1)
