"""The basic ILC loop: Arimoto-type P / PD / PID laws and the lifted norm-optimal law.

Notation (per axis): trial j applies u_j (n samples), the plant returns y_j, the error is
e_j = y_d - y_j. The model's impulse response h has relative degree r (h[0..r-1] = 0): the
output at k first responds to the input at k - r. So a law learns the first n_r = n - r
inputs from the error shifted r samples ahead, e_s[k] = e[k + r]; the last r inputs do not
act inside the trial and hold the last learned value.

- ``"p"``, ``"pd"``, ``"pid"`` (Arimoto type):
  u_{j+1}[k] = Q( u_j[k] + kp e_s[k] + kd (e_s[k] - e_s[k-1]) / dt + ki dt sum_{m<=k} e_s[m] )
  (backward-difference derivative, backward-Euler sum, e_s[-1] = 0: the trial starts at
  rest), i.e. the filter L(q^-1) = kp + kd (1 - q^-1) / dt + ki dt / (1 - q^-1) on e_s.
- ``"norm-optimal"``: u_{j+1} = Q( u_j + (G^T G + w I)^-1 G^T e_s ), G the n_r x n_r lifted
  model (minimises ||e_{j+1}||^2 + w ||u_{j+1} - u_j||^2 for the model). Two solvers
  (``NormOptimal(solver=...)``): ``"dense"`` Cholesky-factors G^T G + w I once per axis
  (n_r <= 5,000); ``"cg"`` never forms an n x n matrix: conjugate gradients on the FFT
  Toeplitz operator G^T G + w I, preconditioned by the model's exact banded factorisation,
  warm-started from the previous step (:class:`primlib.plant.NormalSolver`: the stopping
  rule bounds each solve's effect on the next error by 1e-6 of the current one), 1-3 CG
  steps and ~10 ms per axis and trial at n = 20,000.
  ``"auto"``: dense up to n_r = 1,000, else CG.

Q is the optional zero-phase Butterworth filter (:class:`primlib.ilc._qfilter.QFilter`).

Default gains are derived from the model (:mod:`primlib.ilc._design`). A law is an object
(:class:`~primlib.ilc.PLaw`, ``PDLaw``, ``PIDLaw``, ``NormOptimal``, or ``MasterSlave`` for
the laws of :func:`~primlib.ilc.learn_master_slave`) or its name.

Stops: ``"tol"`` when the RMS error (Euclidean over axes) is <= tol, ``"diverged"`` when it
grows from one trial to the next (the growing trial is kept in the history), else
``"iterations"``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import linalg, signal

from primlib._errors import InputError
from primlib.contour import contour_error
from primlib.ilc._check import (
    ConvergenceWarning,
    LearningCheck,
    arimoto_column,
    check_arimoto,
    check_norm_optimal,
)
from primlib.ilc._design import GAIN_KEYS, design, q_filter, relative_degrees, single_axis_law
from primlib.ilc._laws import LearnOptions, MasterSlave, NormOptimal, law_from_name
from primlib.ilc._master_slave import MasterSlaveResult, learn_master_slave
from primlib.ilc._qfilter import QFilter
from primlib.plant import NormalSolver, pid_polynomials

__all__ = ["learn", "ILCResult", "check_learning", "NORM_OPTIMAL_MAX_N", "AUTO_DENSE_MAX_N"]

NORM_OPTIMAL_MAX_N = 5000  # dense Cholesky of an n x n matrix per axis
AUTO_DENSE_MAX_N = 1000  # solver "auto": dense Cholesky up to here, CG beyond


@dataclass(frozen=True)
class ILCResult:
    """History of an ILC run.

    Attributes
    ----------
    u : array, shape (n, d)
        Input of the last trial run.
    inputs, outputs, errors : list of array, shape (n, d)
        Per trial (trial 0 is ``u0``), so each has ``iterations + 1`` entries.
    rms : array, shape (iterations + 1, d)
        RMS tracking error per axis and trial.
    rms_total : array, shape (iterations + 1,)
        RMS of the Euclidean tracking error, sqrt(sum over axes of rms^2).
    check : LearningCheck
        The lifted check of the law on the model, done before the first trial.
    stopped : str
        ``"tol"``, ``"diverged"`` or ``"iterations"``.
    law : str
    gains : dict
        The gains used, per axis arrays (``kp``, ``kd``, ``ki`` or ``w``).
    rms_contour : array, shape (iterations + 1,) or None
        RMS contour error per trial (``primlib.contour.contour_error``), when computed.
    solver : str
        How the norm-optimal step was solved (empty for the Arimoto laws).
    cg : tuple of tuple of CGInfo
        Norm-optimal CG path: per learning update, one ``CGInfo`` (iterations, relative
        residual, converged) per axis; empty otherwise.
    """

    u: np.ndarray
    inputs: list
    outputs: list
    errors: list
    rms: np.ndarray
    rms_total: np.ndarray
    check: LearningCheck
    stopped: str
    law: str
    gains: dict = field(default_factory=dict)
    rms_contour: np.ndarray | None = None
    solver: str = ""
    cg: tuple = ()

    @property
    def iterations(self) -> int:
        """Number of learning updates run (trials - 1)."""
        return len(self.inputs) - 1

    def plot(self, ax=None):
        """RMS tracking error per trial and axis (log scale), and the contour error when
        recorded; see :func:`primlib.plot.plot_ilc_result`.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Drawn into; None: a new figure.

        Returns
        -------
        matplotlib Axes
        """
        # imported here: primlib.plot loads matplotlib, which learning never needs
        from primlib.plot import plot_ilc_result

        return plot_ilc_result(self, ax=ax)


def _resolve_gains(gains: dict, law: str, d: int) -> dict:
    keys = GAIN_KEYS[law]
    out = {}
    for k in keys:
        value = np.asarray(gains.get(k, 0.0), dtype=float)
        if value.ndim == 0:
            value = np.full(d, float(value))
        if value.shape != (d,) or not np.all(np.isfinite(value)):
            raise InputError(
                f"gains {k}: expected a finite number or one per axis ({d}), got {gains.get(k)!r}"
            )
        out[k] = value
    if law == "norm-optimal" and np.any(out["w"] <= 0):
        raise InputError(f"gains w: expected weights > 0, got {out['w'].tolist()}")
    return out


@dataclass
class _Axis:
    r: int
    n_r: int
    c: np.ndarray | None = None  # Arimoto filter L = c / den
    den: np.ndarray | None = None
    G: np.ndarray | None = None  # norm-optimal, dense
    w: float = 0.0
    cho: Any = None
    normal: Any = None  # norm-optimal, CG (NormalSolver)
    polys: Any = None  # (num, den) of q^r G, when the model has them
    prev: np.ndarray | None = None  # last CG step (warm start)


def _shifted_polys(model, i: int, r: int):
    """(num, den) in q^-1 of q^r G for axis i, or None when the model has none."""
    loops = model.closed_loop() if hasattr(model, "closed_loop") else None
    if loops is None:
        return None
    num, _, den = (np.asarray(p, dtype=float) for p in loops[i])
    if num.size <= r or np.any(num[:r] != 0.0) or num[r] == 0.0:
        return None
    return num[r:], den


def _norm_optimal_axis(ax: _Axis, model, g: np.ndarray, i: int, w: float, solver: str, n: int):
    """Factor (dense) or prepare the CG solver of axis i's norm-optimal step."""
    dense = solver == "dense" or (solver == "auto" and ax.n_r <= AUTO_DENSE_MAX_N)
    if dense and ax.n_r > NORM_OPTIMAL_MAX_N:
        raise InputError(
            f"reference: solver 'dense' factors an n x n matrix per axis, expected "
            f"n <= {NORM_OPTIMAL_MAX_N}, got {n}; use solver 'cg' or 'auto'"
        )
    if g[0] == 0.0:
        raise InputError(f"model: axis {i} has no response inside the trial")
    ax.w = w
    ax.polys = _shifted_polys(model, i, ax.r)
    if dense:
        ax.G = linalg.toeplitz(g, np.r_[g[0], np.zeros(ax.n_r - 1)])
        H = ax.G.T @ ax.G
        H[np.diag_indices(ax.n_r)] += ax.w
        ax.cho = linalg.cho_factor(H, lower=True)
    else:
        num, den = ax.polys if ax.polys is not None else (None, None)
        ax.normal = NormalSolver(g.copy(), ax.w, num, den)


def _prepare(model, n: int, spec, q: QFilter | None):
    """Per-axis learning operators of the law on the model, its gains, and the impulse
    response h (n, d)."""
    law = spec.name
    h = model.impulse_response(n)
    d = h.shape[1]
    rel = relative_degrees(model, h)
    given = spec.gains()
    gains = design(model, h, rel, n, law, q) if given is None else _resolve_gains(given, law, d)
    axes = []
    for i in range(d):
        r = int(rel[i])
        min_n = q.min_samples() if q is not None else 2
        if n - r < min_n:
            raise InputError(
                f"reference: expected at least {min_n + r} samples for axis {i} "
                f"(relative degree {r}), got {n}"
            )
        ax = _Axis(r=r, n_r=n - r)
        if law == "norm-optimal":
            _norm_optimal_axis(ax, model, h[r:, i], i, float(gains["w"][i]), spec.solver, n)
        else:
            zero = np.zeros(d)
            ax.c, ax.den = pid_polynomials(
                gains["kp"][i], gains.get("ki", zero)[i], gains.get("kd", zero)[i], 0.0, model.dt
            )
        axes.append(ax)
    return axes, gains, h


def _run_check(axes, law, q, n, dense_limit, h) -> LearningCheck:
    rhos, sigmas, methods = [], [], []
    for i, ax in enumerate(axes):
        if law == "norm-optimal":
            rho, sigma, how = check_norm_optimal(
                h[ax.r : ax.r + ax.n_r, i], ax.w, ax.cho, q, dense_limit, ax.polys
            )
        else:
            col = arimoto_column(h[ax.r :, i], ax.c, ax.den)
            rho, sigma, how = check_arimoto(col, q, dense_limit)
        rhos.append(rho)
        sigmas.append(sigma)
        methods.append(how)
    method = "; ".join(dict.fromkeys(methods))
    return LearningCheck(
        spectral_radius=max(rhos),
        max_singular_value=max(sigmas),
        # norm-optimal without Q contracts by construction (w > 0, h[r] != 0)
        monotonic=max(sigmas) < 1.0 or (law == "norm-optimal" and q is None),
        spectral_radius_axes=tuple(rhos),
        max_singular_value_axes=tuple(sigmas),
        method=method,
        n=n,
    )


def check_learning(model, n: int, law: Any = "pd", *, dense_limit: int = 400) -> LearningCheck:
    """Check a learning law on the lifted model before running it (see ``_check``).

    Parameters
    ----------
    model : Machine
    n : int
        Samples per trial.
    law : str or PLaw, PDLaw, PIDLaw, NormOptimal
        As for :func:`learn` (gains None: the model-derived defaults; the law's Q-filter
        and, for NormOptimal, its solver: "dense" allows n - r <= 5,000).
    dense_limit : int
        Largest n - r handled with dense matrices; beyond, FFT operators and Lanczos.

    Returns
    -------
    LearningCheck
    """
    spec = single_axis_law(law)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InputError(f"n: expected a number of samples >= 2, got {n!r}")
    q = q_filter(spec, model.dt)
    axes, _, h = _prepare(model, int(n), spec, q)
    return _run_check(axes, spec.name, q, int(n), dense_limit, h)


def learn(
    plant,
    reference,
    u0=None,
    *,
    law: Any = "pd",
    model=None,
    iterations: int = 10,
    tol: float | None = None,
    contour: bool | None = None,
    options: LearnOptions | None = None,
) -> ILCResult | MasterSlaveResult:
    """Iterative learning control of a reference on a machine, all axes in parallel.

    Parameters
    ----------
    plant : Machine
        Runs the trials (``simulate``; with feedback the PID tracks ``reference``).
    reference : array, shape (n, d)
        Desired output relative to the start point, on the machine's dt grid.
    u0 : array, shape (n, d), optional
        First-trial input (a warm start); zeros when None.
    law : str or PLaw, PDLaw, PIDLaw, NormOptimal, MasterSlave
        The law with its gains and Q-filter, or its name (``"p"``, ``"pd"``, ``"pid"``,
        ``"norm-optimal"``: gains designed from the model, no Q-filter; ``"tdilc"``,
        ``"tdccilc"``, ``"pdilc"``, ``"pdccilc"``: :func:`learn_master_slave`, Table 1).
    model : Machine, optional
        Designs the law and its check (default: ``plant``); the plant's dt and axes.
    iterations : int
        Largest number of learning updates (trials: iterations + 1).
    tol : float, optional
        Stop when the RMS (Euclidean) tracking error is <= tol, in the reference's units
        (master–slave laws: the RMS estimated contour error).
    contour : bool, optional
        Record the RMS contour error per trial (``primlib.contour.contour_error``; needs
        d >= 2). None: when d >= 2.
    options : LearnOptions, optional
        Convergence-check size, per-trial callback, master-slave check.

    Returns
    -------
    ILCResult (MasterSlaveResult for a MasterSlave law)

    Warns
    -----
    ConvergenceWarning
        sigma_max >= 1, or a norm-optimal CG solve stopped short (``result.cg``).

    Raises
    ------
    InputError
        Unknown law, bad gains, a wrong shape, NaN, mismatched model, iterations < 0,
        tol <= 0, a cut-off outside (0, Nyquist), too few samples.

    Examples
    --------
    >>> m = Machine.from_json("data/machines/xyz.json")
    >>> res = learn(m, reference, law="norm-optimal", iterations=5)
    >>> len(res.rms_total)        # one entry per trial, trial 0 first
    6
    >>> bool(res.rms_total[-1] < 1e-2 * res.rms_total[0])
    True
    """
    spec = law_from_name(law)
    options = LearnOptions() if options is None else options
    if isinstance(spec, MasterSlave):
        run = {"model": model, "iterations": iterations, "tol": tol, "check": options.check}
        return learn_master_slave(plant, reference, u0, law=spec, **run)
    _check_run(iterations, tol)
    model = _check_model(plant, model)
    ref = plant.check_signal(reference, "reference")
    u = _first_input(plant, u0, ref)
    q = q_filter(spec, plant.dt)
    axes, used_gains, h = _prepare(model, ref.shape[0], spec, q)
    check = _run_check(axes, spec.name, q, ref.shape[0], options.dense_limit, h)
    _warn_not_monotonic(check, spec.name)
    trials = _Trials(plant, ref, _contour_enabled(contour, ref.shape[1]), options.callback)
    stopped = trials.run(u, lambda u_j, e_j, log: _update(u_j, e_j, axes, q, log), iterations, tol)
    _warn_short_cg(trials.cg_log)
    return trials.result(check, stopped, spec, used_gains, _solver_name(axes, spec))


def _check_model(plant, model):
    model = plant if model is None else model
    if model.dt != plant.dt or tuple(model.axes) != tuple(plant.axes):
        raise InputError(
            f"model: expected the plant's dt {plant.dt} and axes {list(plant.axes)}, "
            f"got dt {model.dt} and axes {list(model.axes)}"
        )
    return model


def _check_run(iterations: Any, tol: Any) -> None:
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)):
        raise InputError(f"iterations: expected an integer >= 0, got {iterations!r}")
    if iterations < 0:
        raise InputError(f"iterations: expected an integer >= 0, got {iterations}")
    if tol is not None and not (
        isinstance(tol, (int, float)) and not isinstance(tol, bool) and np.isfinite(tol) and tol > 0
    ):
        raise InputError(f"tol: expected a finite tolerance > 0, got {tol!r}")


def _first_input(plant, u0, ref: np.ndarray) -> np.ndarray:
    if u0 is None:
        return np.zeros_like(ref)
    u = plant.check_signal(u0, "u0")
    if u.shape != ref.shape:
        raise InputError(f"u0: expected the reference's shape {ref.shape}, got {u.shape}")
    return u.copy()


def _contour_enabled(contour: bool | None, d: int) -> bool:
    if contour and d < 2:
        raise InputError(f"contour: expected a path with 2 or 3 axes, got {d}")
    return d >= 2 and (contour is None or bool(contour))


class _Trials:
    """Runs trials on the plant and records each one's input, output, error and RMS."""

    def __init__(self, plant, ref: np.ndarray, contour: bool, callback) -> None:
        self.plant, self.ref, self.contour, self.callback = plant, ref, contour, callback
        self.t = np.arange(ref.shape[0]) * plant.dt
        self.uses_reference = bool(getattr(plant, "feedback", None))
        self.inputs, self.outputs, self.errors = [], [], []
        self.rms, self.total, self.contours, self.cg_log = [], [], [], []

    def trial(self, u: np.ndarray) -> np.ndarray:
        """Run one trial with input u, record it, return its error."""
        ref = self.ref
        y = self.plant.simulate(u, reference=ref) if self.uses_reference else self.plant.simulate(u)
        e = ref - y
        self.inputs.append(u)
        self.outputs.append(y)
        self.errors.append(e)
        self.rms.append(np.sqrt(np.mean(e**2, axis=0)))
        self.total.append(float(np.sqrt(np.sum(self.rms[-1] ** 2))))
        if self.contour:
            ce = contour_error(ref, self.t, y)
            self.contours.append(float(np.sqrt(np.mean(ce**2))))
        if self.callback is not None:
            self.callback(len(self.inputs) - 1, self.rms[-1].copy())
        return e

    def run(self, u: np.ndarray, update, iterations: int, tol: float | None) -> str:
        """Trials from u until ``iterations`` updates, the tolerance, or divergence."""
        e = self.trial(u)
        for _ in range(int(iterations)):
            if tol is not None and self.total[-1] <= tol:
                return "tol"
            u = update(u, e, self.cg_log)
            e = self.trial(u)
            if self.total[-1] > self.total[-2]:
                return "diverged"
        return "tol" if tol is not None and self.total[-1] <= tol else "iterations"

    def result(self, check, stopped: str, spec, gains: dict, solver: str) -> ILCResult:
        return ILCResult(
            u=self.inputs[-1],
            inputs=self.inputs,
            outputs=self.outputs,
            errors=self.errors,
            rms=np.array(self.rms),
            rms_total=np.array(self.total),
            check=check,
            stopped=stopped,
            law=spec.name,
            gains={k: v.copy() for k, v in gains.items()},
            rms_contour=np.array(self.contours) if self.contour else None,
            solver=solver,
            cg=tuple(self.cg_log),
        )


def _warn_not_monotonic(check: LearningCheck, law: str) -> None:
    if not check.monotonic:
        warnings.warn(
            f"ILC law {law!r}: largest singular value of the learning matrix is "
            f"{check.max_singular_value:.4g} >= 1 (spectral radius "
            f"{check.spectral_radius:.4g}): monotonic convergence is not assured",
            ConvergenceWarning,
            stacklevel=3,
        )


def _warn_short_cg(cg_log) -> None:
    short = [
        (j + 1, i, info.residual)
        for j, upd in enumerate(cg_log)
        for i, info in enumerate(upd)
        if not info.converged
    ]
    if short:
        j, i, res_ = max(short, key=lambda item: item[2])
        warnings.warn(
            f"ILC law 'norm-optimal': {len(short)} CG solve(s) stopped short of the "
            f"tolerance, worst relative residual {res_:.2g} (update {j}, axis {i}); the "
            "steps are inexact (see result.cg)",
            ConvergenceWarning,
            stacklevel=3,
        )


def _solver_name(axes, spec) -> str:
    if not isinstance(spec, NormOptimal):
        return ""
    names = [ax.normal.method if ax.normal is not None else "dense Cholesky" for ax in axes]
    return "; ".join(dict.fromkeys(names))


def _update(u: np.ndarray, e: np.ndarray, axes, q: QFilter | None, log) -> np.ndarray:
    new = np.empty_like(u)
    infos = []
    for i, ax in enumerate(axes):
        e_s = e[ax.r : ax.r + ax.n_r, i]  # eq. shift by the relative degree
        if ax.normal is not None:
            step, info = ax.normal.solve(ax.normal.rhs(e_s), ax.prev)
            ax.prev = step
            infos.append(info)
        elif ax.cho is not None:
            step = linalg.cho_solve(ax.cho, ax.G.T @ e_s)
        else:
            step = signal.lfilter(ax.c, ax.den, e_s)
        v = u[: ax.n_r, i] + step
        if q is not None:
            v = q(v)
        new[: ax.n_r, i] = v
        new[ax.n_r :, i] = v[-1]
    if infos:
        log.append(tuple(infos))
    return new
