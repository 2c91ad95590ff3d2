"""Closed-loop contouring on a nonlinear machine: per-axis controller + cross-coupling."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError
from primlib.mfac._law import CFDLMFAC, PID, cross_coupled

__all__ = ["ContourRun", "run_contouring"]


@dataclass(frozen=True)
class ContourRun:
    """One closed-loop run.

    Attributes
    ----------
    t : array, shape (n,)
        Sample times, s.
    reference : array, shape (n, d)
        Reference positions (user units, absolute).
    actual : array, shape (n, d)
        Measured positions (user units, absolute).
    applied : array, shape (n, d)
        Input the machine received (controller plus cross-coupling).
    estimate : array, shape (n,)
        Contour error as the loop's estimator saw it (user units).
    phi : array, shape (n, d) or None
        Pseudo partial derivatives (MFAC only).
    """

    t: np.ndarray
    reference: np.ndarray
    actual: np.ndarray
    applied: np.ndarray
    estimate: np.ndarray
    phi: np.ndarray | None


def run_contouring(
    machine,
    reference,
    controller,
    estimator=None,
    *,
    ccc_gain: float = 0.0,
    scale: float = 1.0,
    blowup: float = 1e3,
) -> ContourRun:
    """Run a contouring loop: per-axis controller, contour estimator, cross-coupled control.

    At sample k the position ``p(k)`` is measured, the estimator gives the contour error
    ``eps(k)`` and the left normal, the controller gives ``u(k)``, and the machine receives
    ``U(k) = u(k) - ccc_gain eps(k) normal(k)`` (eq. (6)) held over the sample.

    Parameters
    ----------
    machine : LinearMotor
        Anything with ``dt``, ``dim``, ``initial_state(start)``, ``advance(state, u)`` and
        ``position(state)`` (user units).
    reference : array, shape (n + 1, d)
        Reference positions on the grid ``k dt`` (user units, absolute); the machine starts
        at rest at ``reference[0]``; the extra last sample is the MFAC's ``y*(k+1)``.
    controller : CFDLMFAC or PID
        Per-axis law, working in controller units ``scale * (p - reference[0])``.
    estimator : callable ``(k, p) -> (eps, normal)``, optional
        E.g. :class:`primlib.contour.OnlineContourEstimator`; required when ``ccc_gain``
        is non-zero, else only recorded.
    ccc_gain : float
        Cross-coupling gain K_p, input units per user length unit.
    scale : float
        Controller units per user length unit (1e-3: an MFAC working in metres on mm).
    blowup : float
        The run stops with an error when the tracking error exceeds ``blowup`` times the
        reference's extent (a diverging loop).

    Returns
    -------
    ContourRun

    Raises
    ------
    InputError
        Reference of the wrong shape, a missing estimator, or a diverging loop.
    """
    ref = _check_run(machine, reference, controller, estimator, ccc_gain)
    n = ref.shape[0] - 1
    d = machine.dim
    start = ref[0]
    ref_c = scale * (ref - start)
    limit = blowup * max(float(np.ptp(ref, axis=0).max()), 1e-12)
    state = machine.initial_state(start)
    actual = np.empty((n, d))
    applied = np.empty((n, d))
    est = np.zeros(n)
    mfac = isinstance(controller, CFDLMFAC)
    phi = np.empty((n, d)) if mfac else None
    prev = None
    for k in range(n):
        p = machine.position(state)
        actual[k] = p
        _check_bounded(p - ref[k], limit, k * machine.dt, blowup)
        y = scale * (p - start)
        if mfac:
            u = controller.step(y, ref_c[k + 1], prev)
            phi[k] = controller.phi
        else:
            u = controller.step(ref_c[k] - y)
        if estimator is not None:
            eps, nrm = estimator(k, p)
            est[k] = eps
            if ccc_gain != 0.0:
                u = cross_coupled(u, eps, nrm, ccc_gain)  # eq. (6)
        applied[k] = u
        prev = u
        state = machine.advance(state, u)
    t = np.arange(n) * machine.dt
    return ContourRun(t, ref[:n].copy(), actual, applied, est, phi)


def _check_bounded(error: np.ndarray, limit: float, t: float, blowup: float) -> None:
    if not np.all(np.abs(error) < limit):
        raise InputError(
            f"gains: the closed loop diverged at t = {t:.4g} s "
            f"(tracking error above {blowup:g} x the path extent)"
        )


def _check_run(machine, reference, controller, estimator, ccc_gain) -> np.ndarray:
    """The reference as a float array (n + 1, d), after checking the run's arguments."""
    ref = np.asarray(reference, dtype=float)
    if ref.ndim != 2 or ref.shape[1] != machine.dim or ref.shape[0] < 3:
        raise InputError(
            f"reference: expected an array of shape (n + 1, {machine.dim}) with n >= 2, "
            f"got {ref.shape}"
        )
    if not np.all(np.isfinite(ref)):
        raise InputError("reference: expected finite values, got NaN or inf")
    if ccc_gain != 0.0 and estimator is None:
        raise InputError("estimator: expected a contour estimator with ccc_gain != 0, got None")
    if not isinstance(controller, (CFDLMFAC, PID)):
        raise InputError(f"controller: expected a CFDLMFAC or PID, got {type(controller).__name__}")
    return ref
