"""One learning loop for the master–slave family: TDILC, TDCCILC, PDILC and PDCCILC.

Each trial runs the reference through the machine's PID loops with the current feedforward
input added to the PID output (eq. 22, Fig. 3), measures the tracking error and the estimated
contour error (eqs. 1-4), and updates the input by the chosen law (eq. 9 with eqs. 10-19,
see :mod:`primlib.ilc._ms_law` for the notation and where primlib departs from the paper).
Before the first trial the law is checked on the model with the lifted analysis
(eqs. 28-30, :mod:`primlib.ilc._lifted`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError
from primlib.ilc._check import ConvergenceWarning
from primlib.ilc._laws import MasterSlave
from primlib.ilc._lifted import lifted_master_slave
from primlib.ilc._ms_law import _check_reference, master_slave_law

__all__ = ["MasterSlaveCheck", "MasterSlaveResult", "check_master_slave", "learn_master_slave"]


@dataclass(frozen=True)
class MasterSlaveCheck:
    """Lifted check of a law before learning (eqs. 29-30).

    Attributes
    ----------
    spectral_radius : float
        rho(M): exact when ``spectral_radius_exact``, else a certified upper bound.
    spectral_radius_exact : bool
    max_singular_value : float
        sigma_max of the composite M (eq. 30).
    monotonic : bool
        ``max_singular_value < 1``: the 2-norm of the input error shrinks every trial.
    """

    spectral_radius: float
    spectral_radius_exact: bool
    max_singular_value: float
    monotonic: bool


@dataclass(frozen=True)
class MasterSlaveResult:
    """Outcome of :func:`learn_master_slave`.

    Attributes
    ----------
    law : str
    u : array, shape (n, 2)
        Input of the last trial.
    inputs, outputs, errors : list of array, shape (n, 2)
        Per trial (iterations + 1 of them, or fewer when stopped early).
    contour : list of array, shape (n,)
        Estimated contour error per trial (eq. 1).
    rms : array, shape (trials, 2)
        RMS tracking error per axis.
    rms_total : array, shape (trials,)
        RMS of the error vector's length.
    rms_contour : array, shape (trials,)
        RMS estimated contour error.
    max_contour : array, shape (trials,)
        Largest |estimated contour error|.
    check : MasterSlaveCheck or None
    stopped : str
        ``"iterations"``, ``"tol"`` or ``"diverged"``.
    """

    law: str
    u: np.ndarray
    inputs: list
    outputs: list
    errors: list
    contour: list
    rms: np.ndarray
    rms_total: np.ndarray
    rms_contour: np.ndarray
    max_contour: np.ndarray
    check: MasterSlaveCheck | None
    stopped: str


def check_master_slave(law, model, reference, powers=(1, 4, 16)) -> MasterSlaveCheck:
    """Lifted check of ``law`` on ``model`` (eqs. 29-30); see :mod:`primlib.ilc._lifted`."""
    lifted = lifted_master_slave(law, model, reference)
    sigma = lifted.max_singular_value()
    rho, exact = lifted.spectral_radius(powers=powers)
    return MasterSlaveCheck(
        spectral_radius=rho,
        spectral_radius_exact=exact,
        max_singular_value=sigma,
        monotonic=bool(sigma < 1.0),
    )


def learn_master_slave(
    plant,
    reference,
    u0=None,
    *,
    law: str | MasterSlave = "pdccilc",
    model=None,
    iterations: int = 50,
    tol: float | None = None,
    check: bool = True,
) -> MasterSlaveResult:
    """Learn a two-axis feedforward input with a master–slave (cross-coupled) ILC law.

    Parameters
    ----------
    plant : Machine
        Two-axis machine that runs the trials (its PID loops track the reference; the
        input is feedforward added to the PID output).
    reference : array, shape (n, 2), or Trajectory
        The path sampled on the machine's dt grid (a two-axis ``Trajectory`` is sampled at
        the machine's dt); taken relative to its first point, like the outputs.
    u0 : array, shape (n, 2), optional
        First trial's input (a warm start); zeros by default.
    law : {"tdilc", "tdccilc", "pdilc", "pdccilc"} or MasterSlave
        Time- or position-domain learning, without or with cross-coupling; a
        :class:`MasterSlave` sets the gains (default Table 1 of the paper), the Q-filter
        (default 1 Hz), the master axis, the lead and the position-domain floor.
    model : Machine, optional
        Nominal model for the lifted check (default: ``plant``).
    iterations : int
        Number of updates (>= 0); iterations + 1 trials are run.
    tol : float, optional
        Stop once the RMS estimated contour error is at most ``tol`` (> 0).
    check : bool
        Run the lifted check first (a ConvergenceWarning when monotonic convergence is not
        certified, sigma_max >= 1).

    Returns
    -------
    MasterSlaveResult

    Raises
    ------
    InputError
        For a machine that is not two-axis, a reference or u0 of the wrong shape or with
        NaN, an unknown law, iterations < 0, tol <= 0, or a bad option of the law.

    References
    ----------
    Ling J, Ming M, Feng Z, Xiao X. A master-slave cross-coupled iterative learning control
    for repetitive tracking of nonlinear contours in multi-axis precision motion systems.
    Acta Automatica Sinica, 2017, 43(12): 2127-2140.

    Examples
    --------
    >>> m2 = Machine.from_json("data/machines/xy-pdccilc.json")
    >>> res = learn_master_slave(m2, points, law="pdccilc", iterations=10)
    >>> bool(res.rms_contour[-1] < 0.5 * res.rms_contour[0])   # the coupling learns the contour
    True
    """
    spec = law if isinstance(law, MasterSlave) else MasterSlave(law)
    model = _check_machines(plant, model)
    if hasattr(reference, "sample") and hasattr(reference, "duration"):
        reference = reference.sample(plant.dt)  # a primlib Trajectory
    points = _check_reference(reference)
    r = points - points[0]
    if not isinstance(iterations, int | np.integer) or iterations < 0:
        raise InputError(f"iterations: expected an integer >= 0, got {iterations!r}")
    if tol is not None and not (np.isfinite(tol) and tol > 0):
        raise InputError(f"tol: expected an RMS contour error > 0, got {tol!r}")
    u = np.zeros_like(r) if u0 is None else _check_u0(u0, r.shape)
    ms = master_slave_law(r, plant.dt, **spec.options())
    result_check = _check_and_warn(ms, model, r) if check else None
    return _run(plant, ms, r, u, iterations, tol, result_check)


def _check_machines(plant, model):
    if getattr(plant, "dim", None) != 2:
        raise InputError(
            f"plant: expected a two-axis machine (master and slave), "
            f"got {getattr(plant, 'dim', None)} axes"
        )
    model = plant if model is None else model
    if getattr(model, "dim", None) != 2 or not np.isclose(model.dt, plant.dt):
        raise InputError(
            f"model: expected a two-axis machine with dt = {plant.dt:g} s like the plant, "
            f"got {getattr(model, 'dim', None)} axes at dt = {getattr(model, 'dt', None)}"
        )
    return model


def _check_u0(u0, shape) -> np.ndarray:
    u = np.asarray(u0, dtype=float)
    if u.shape != shape or not np.all(np.isfinite(u)):
        raise InputError(f"u0: expected a finite array of shape {shape}, got {u.shape}")
    return u.copy()


def _check_and_warn(ms, model, r) -> MasterSlaveCheck:
    result_check = check_master_slave(ms, model, r)
    if not result_check.monotonic:
        rho = result_check.spectral_radius
        verdict = (
            f"it converges (rho <= {rho:.4f} < 1, eq. 29)"
            if rho < 1
            else f"and rho <= {rho:.4f} does not certify convergence either (eq. 29)"
        )
        warnings.warn(
            f"{ms.law}: monotonic convergence is not certified on the model "
            f"(sigma_max = {result_check.max_singular_value:.4f} >= 1, eq. 30); {verdict}",
            ConvergenceWarning,
            stacklevel=3,
        )
    return result_check


def _run(plant, ms, r, u, iterations, tol, result_check) -> MasterSlaveResult:
    """The trials: simulate, estimate the contour error (eq. 1), update by eq. (9)."""
    inputs, outputs, errors, contour = [], [], [], []
    stopped = "iterations"
    for j in range(iterations + 1):
        y = plant.simulate(u, reference=r)
        e = r - y
        eps = np.sum(ms.normal * e, axis=1)  # eq. (1)
        inputs.append(u)
        outputs.append(y)
        errors.append(e)
        contour.append(eps)
        rms_eps = float(np.sqrt(np.mean(eps**2)))
        if not np.all(np.isfinite(e)) or rms_eps > 1e6 * max(
            float(np.sqrt(np.mean(contour[0] ** 2))), np.finfo(float).tiny
        ):
            stopped = "diverged"
            break
        if tol is not None and rms_eps <= tol:
            stopped = "tol"
            break
        if j < iterations:
            u = ms.update(u, e)  # eq. (9)
    err = np.stack(errors)
    eps_all = np.stack(contour)
    return MasterSlaveResult(
        law=ms.law,
        u=inputs[-1],
        inputs=inputs,
        outputs=outputs,
        errors=errors,
        contour=contour,
        rms=np.sqrt(np.mean(err**2, axis=1)),
        rms_total=np.sqrt(np.mean(np.sum(err**2, axis=2), axis=1)),
        rms_contour=np.sqrt(np.mean(eps_all**2, axis=1)),
        max_contour=np.max(np.abs(eps_all), axis=1),
        check=result_check,
        stopped=stopped,
    )
