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
  (``solver=``): ``"dense"`` Cholesky-factors G^T G + w I once per axis (n_r <= 5,000);
  ``"cg"`` never forms an n x n matrix: conjugate gradients on the FFT Toeplitz operator
  G^T G + w I, preconditioned by the model's exact banded factorisation, warm-started from
  the previous step (:mod:`primlib.plant._normal`: the stopping rule bounds each solve's
  effect on the next error by 1e-6 of the current one), 1-3 CG steps and ~10 ms per axis
  and trial at n = 20,000.
  ``"auto"``: dense up to n_r = 1,000, else CG.

Q is the optional zero-phase Butterworth filter (:class:`primlib.ilc._qfilter.QFilter`).

Default gains, derived from the model (``design_gains``): with G_r(w) the frequency response
of q^r G on a log grid from pi / n_r to pi rad/sample and the learning band w <= w_b
(w_b = 2 pi q_cutoff dt with a Q-filter, else a tenth of the Nyquist frequency):

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

Stops: ``"tol"`` when the RMS error (Euclidean over axes) is <= tol, ``"diverged"`` when it
grows from one trial to the next (the growing trial is kept in the history), else
``"iterations"``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import linalg, optimize, signal

from primlib._errors import InputError
from primlib.ilc._check import (
    ConvergenceWarning,
    LearningCheck,
    arimoto_column,
    check_arimoto,
    check_norm_optimal,
)
from primlib.ilc._qfilter import QFilter
from primlib.plant._normal import NormalSolver
from primlib.plant._pid import pid_polynomials

__all__ = ["learn", "ILCResult", "design_gains", "check_learning", "LAWS"]

LAWS = ("p", "pd", "pid", "norm-optimal")
_GAIN_KEYS = {"p": ("kp",), "pd": ("kp", "kd"), "pid": ("kp", "ki", "kd"), "norm-optimal": ("w",)}
DEFAULT_BAND = 0.1  # learning band without a Q-filter, as a fraction of the Nyquist frequency
NORM_OPTIMAL_MAX_N = 5000  # dense Cholesky of an n x n matrix per axis
AUTO_DENSE_MAX_N = 1000  # solver "auto": dense Cholesky up to here, CG beyond
SOLVERS = ("auto", "dense", "cg")
_ALPHAS = (1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125)


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
        recorded; see :func:`primlib.plot._ilc.plot_ilc_result`.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Drawn into; None: a new figure.

        Returns
        -------
        matplotlib Axes
        """
        from primlib.plot._ilc import plot_ilc_result

        return plot_ilc_result(self, ax=ax)


# ----------------------------------------------------------------------------- helpers


def _relative_degrees(model, h: np.ndarray) -> np.ndarray:
    rel = getattr(model, "relative_degree", None)
    if rel is not None:
        return np.asarray(rel, dtype=int)
    scale = np.max(np.abs(h), axis=0)
    out = np.empty(h.shape[1], dtype=int)
    for i in range(h.shape[1]):
        nz = np.flatnonzero(np.abs(h[:, i]) > 1e-12 * scale[i])
        out[i] = nz[0] if nz.size else 0
    return out


def _frequency_responses(model, h: np.ndarray, rel: np.ndarray, omega: np.ndarray) -> np.ndarray:
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
    return np.column_stack([cols[k] for k in _GAIN_KEYS[law]])


def _omega_grid(n_r: int) -> np.ndarray:
    lo = np.pi / max(n_r, 2)
    return np.unique(np.r_[np.geomspace(lo, np.pi, 600), np.linspace(lo, np.pi, 600)])


def _band(q: QFilter | None, dt: float) -> float:
    return 2 * np.pi * q.cutoff_hz * dt if q is not None else DEFAULT_BAND * np.pi


def design_gains(model, n: int, law: str = "pd", q_cutoff: float | None = None, q_order: int = 2):
    """Default learning gains from the model (see the module docstring).

    Parameters
    ----------
    model : Machine
    n : int
        Samples per trial.
    law : {"p", "pd", "pid", "norm-optimal"}
    q_cutoff : float, optional
        Q-filter cut-off in Hz (sets the learning band).
    q_order : int
        Q-filter Butterworth order.

    Returns
    -------
    dict
        ``{"kp": (d,), "kd": (d,), ...}`` or ``{"w": (d,)}``.
    """
    law = _check_law(law)
    q = QFilter(q_cutoff, model.dt, q_order) if q_cutoff is not None else None
    h = model.impulse_response(n)
    rel = _relative_degrees(model, h)
    return _design(model, h, rel, n, law, q)


def _design(model, h, rel, n, law, q) -> dict:
    d = h.shape[1]
    dt = model.dt
    band = _band(q, dt)
    keys = _GAIN_KEYS[law]
    out = {k: np.zeros(d) for k in keys}
    for i in range(d):
        n_r = n - int(rel[i])
        omega = _omega_grid(n_r)
        gr = _frequency_responses(model, h, rel, omega)[:, i]
        if law == "norm-optimal":
            g_b = _frequency_responses(model, h, rel, np.array([band]))[0, i]
            out["w"][i] = max(abs(g_b) ** 2, np.finfo(float).tiny)
            continue
        basis = _arimoto_basis(law, omega, dt) * gr[:, None]
        in_band = omega <= band
        a = basis[in_band]
        A = np.vstack([a.real, a.imag])
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        rhs = np.r_[np.ones(a.shape[0]), np.zeros(a.shape[0])]
        # gains share the sign of the first Markov parameter h[r], so that the diagonal
        # of I - L G, 1 - L_0 h[r], starts below 1 (the condition for convergence at all)
        sign = 1.0 if h[rel[i], i] >= 0 else -1.0
        fit = optimize.lsq_linear(sign * A / scale, rhs, bounds=(0.0, np.inf))
        theta = sign * fit.x / scale
        qmag = q.response(omega) if q is not None else 1.0
        best = None
        for alpha in _ALPHAS:
            sup = np.max(np.abs(qmag * (1 - alpha * basis @ theta)))
            if best is None or sup < best[0] - 1e-12:
                best = (sup, alpha)
            if sup < 1.0:
                best = (sup, alpha)
                break
        named = dict(zip(keys, theta, strict=True))
        # L_0, the first coefficient of L's impulse response, sits on the diagonal
        diag = named["kp"] + named.get("kd", 0.0) / dt + named.get("ki", 0.0) * dt
        if diag * h[rel[i], i] < 1e-3:
            # no gain of the right sign helps in the band (P-type on an integrating axis):
            # half the deadbeat gain on the diagonal, 1 - L_0 h[r] = 1/2 (the check warns)
            theta = np.zeros(len(keys))
            theta[0] = 0.5 / h[rel[i], i]
            best = (None, 1.0)
        for k, value in zip(keys, best[1] * theta, strict=True):
            out[k][i] = value
    return out


def _check_law(law: Any) -> str:
    if law not in LAWS:
        raise InputError(f"law: expected one of {', '.join(LAWS)}, got {law!r}")
    return law


def _resolve_gains(gains, law: str, d: int) -> dict:
    keys = _GAIN_KEYS[law]
    if not isinstance(gains, dict):
        raise InputError(f"gains: expected a dict with keys {', '.join(keys)}, got {gains!r}")
    unknown = sorted(set(gains) - set(keys))
    if unknown:
        raise InputError(
            f"gains: law {law!r} takes {', '.join(keys)}, got unknown key {unknown[0]!r}"
        )
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


def _check_solver(solver: Any) -> str:
    if solver not in SOLVERS:
        raise InputError(f"solver: expected one of {', '.join(SOLVERS)}, got {solver!r}")
    return solver


def _prepare(model, n: int, law: str, gains, q: QFilter | None, solver: str = "auto"):
    h = model.impulse_response(n)
    d = h.shape[1]
    rel = _relative_degrees(model, h)
    if gains is None:
        gains = _design(model, h, rel, n, law, q)
    else:
        gains = _resolve_gains(gains, law, d)
    axes = []
    for i in range(d):
        r = int(rel[i])
        n_r = n - r
        min_n = q.min_samples() if q is not None else 2
        if n_r < min_n:
            raise InputError(
                f"reference: expected at least {min_n + r} samples for axis {i} "
                f"(relative degree {r}), got {n}"
            )
        ax = _Axis(r=r, n_r=n_r)
        g = h[r:, i]
        if law == "norm-optimal":
            dense = solver == "dense" or (solver == "auto" and n_r <= AUTO_DENSE_MAX_N)
            if dense and n_r > NORM_OPTIMAL_MAX_N:
                raise InputError(
                    f"reference: solver 'dense' factors an n x n matrix per axis, expected "
                    f"n <= {NORM_OPTIMAL_MAX_N}, got {n}; use solver 'cg' or 'auto'"
                )
            if g[0] == 0.0:
                raise InputError(f"model: axis {i} has no response inside the trial")
            ax.w = float(gains["w"][i])
            ax.polys = _shifted_polys(model, i, r)
            if dense:
                ax.G = linalg.toeplitz(g, np.r_[g[0], np.zeros(n_r - 1)])
                H = ax.G.T @ ax.G
                H[np.diag_indices(n_r)] += ax.w
                ax.cho = linalg.cho_factor(H, lower=True)
            else:
                num, den = ax.polys if ax.polys is not None else (None, None)
                ax.normal = NormalSolver(g.copy(), ax.w, num, den)
        else:
            ax.c, ax.den = pid_polynomials(
                gains["kp"][i],
                gains.get("ki", np.zeros(d))[i],
                gains.get("kd", np.zeros(d))[i],
                0.0,
                model.dt,
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


def check_learning(
    model,
    n: int,
    law: str = "pd",
    gains=None,
    q_cutoff: float | None = None,
    *,
    q_order: int = 2,
    dense_limit: int = 400,
    solver: str = "auto",
) -> LearningCheck:
    """Check a learning law on the lifted model before running it (see ``_check``).

    Parameters
    ----------
    model : Machine
    n : int
        Samples per trial.
    law, gains, q_cutoff, q_order
        As for :func:`learn` (gains None: the model-derived defaults).
    dense_limit : int
        Largest n - r handled with dense matrices; beyond, FFT operators and Lanczos.
    solver : {"auto", "dense", "cg"}
        Norm-optimal solver (see :func:`learn`); "dense" allows n - r <= 5,000.

    Returns
    -------
    LearningCheck
    """
    law = _check_law(law)
    solver = _check_solver(solver)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InputError(f"n: expected a number of samples >= 2, got {n!r}")
    q = QFilter(q_cutoff, model.dt, q_order) if q_cutoff is not None else None
    axes, _, h = _prepare(model, int(n), law, gains, q, solver)
    return _run_check(axes, law, q, int(n), dense_limit, h)


def learn(
    plant,
    reference,
    u0=None,
    *,
    model=None,
    law: str = "pd",
    gains=None,
    q_cutoff: float | None = None,
    iterations: int = 10,
    tol: float | None = None,
    q_order: int = 2,
    dense_limit: int = 400,
    contour: bool | None = None,
    callback=None,
    solver: str = "auto",
) -> ILCResult:
    """Iterative learning control of a reference on a machine, all axes in parallel.

    Parameters
    ----------
    plant : Machine
        Runs the trials (``simulate``; with feedback the PID tracks ``reference``).
    reference : array, shape (n, d)
        Desired output relative to the start (the path minus its first point), on the
        machine's dt grid.
    u0 : array, shape (n, d), optional
        First-trial input (a warm start); zeros when None.
    model : Machine, optional
        Designs the law and its check (default: ``plant``). Same dt and axes as the plant.
    law : {"p", "pd", "pid", "norm-optimal"}
        See the module docstring.
    gains : dict, optional
        ``kp``, ``kd``, ``ki`` (Arimoto; scalars or one per axis; missing keys are 0) or
        ``w`` (norm-optimal). None: derived from the model (``design_gains``).
    q_cutoff : float, optional
        Cut-off in Hz of the zero-phase Butterworth Q-filter; None: no Q-filter.
    iterations : int
        Largest number of learning updates (trials run: iterations + 1).
    tol : float, optional
        Stop when the RMS (Euclidean) tracking error is <= tol, in the reference's units.
    q_order : int
        Butterworth order of one pass of the Q-filter.
    dense_limit : int
        See :func:`check_learning`.
    contour : bool, optional
        Record the RMS contour error per trial (``primlib.contour.contour_error`` on the
        reference samples; needs d >= 2). None: when that package is installed and d >= 2.
    callback : callable, optional
        Called after every trial as ``callback(trial, rms)`` with the trial number (0 for
        ``u0``) and the per-axis RMS error, shape (d,) (e.g. to print progress).
    solver : {"auto", "dense", "cg"}
        Norm-optimal step: "dense" Cholesky (n - r <= 5,000), "cg" conjugate gradients on
        FFT operators (any length; see the module docstring), "auto" dense up to
        n - r = 1,000. Both give the same inputs to the CG tolerance.

    Returns
    -------
    ILCResult

    Warns
    -----
    ConvergenceWarning
        When the check finds sigma_max >= 1 (monotonic convergence not assured), or when
        a norm-optimal CG solve stopped short of its tolerance (``result.cg`` says which).

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
    law = _check_law(law)
    solver = _check_solver(solver)
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)):
        raise InputError(f"iterations: expected an integer >= 0, got {iterations!r}")
    if iterations < 0:
        raise InputError(f"iterations: expected an integer >= 0, got {iterations}")
    if tol is not None and not (
        isinstance(tol, (int, float)) and not isinstance(tol, bool) and np.isfinite(tol) and tol > 0
    ):
        raise InputError(f"tol: expected a finite tolerance > 0, got {tol!r}")
    model = plant if model is None else model
    if model.dt != plant.dt or tuple(model.axes) != tuple(plant.axes):
        raise InputError(
            f"model: expected the plant's dt {plant.dt} and axes {list(plant.axes)}, "
            f"got dt {model.dt} and axes {list(model.axes)}"
        )
    ref = plant._check_signal(reference, "reference")
    n, d = ref.shape
    if u0 is None:
        u = np.zeros_like(ref)
    else:
        u = plant._check_signal(u0, "u0")
        if u.shape != ref.shape:
            raise InputError(f"u0: expected the reference's shape {ref.shape}, got {u.shape}")
        u = u.copy()
    q = QFilter(q_cutoff, plant.dt, q_order) if q_cutoff is not None else None
    axes, used_gains, h = _prepare(model, n, law, gains, q, solver)
    check = _run_check(axes, law, q, n, dense_limit, h)
    if not check.monotonic:
        warnings.warn(
            f"ILC law {law!r}: largest singular value of the learning matrix is "
            f"{check.max_singular_value:.4g} >= 1 (spectral radius "
            f"{check.spectral_radius:.4g}): monotonic convergence is not assured",
            ConvergenceWarning,
            stacklevel=2,
        )

    contour_fn = None
    if contour or contour is None:
        if d >= 2:
            try:
                from primlib.contour import contour_error as contour_fn
            except ImportError:
                if contour:
                    raise InputError(
                        "contour: expected the primlib.contour package, got none installed"
                    ) from None
        elif contour:
            raise InputError(f"contour: expected a path with 2 or 3 axes, got {d}")
    t = np.arange(n) * plant.dt
    uses_reference = bool(getattr(plant, "feedback", None))

    def trial(u_in):
        y_out = plant.simulate(u_in, reference=ref) if uses_reference else plant.simulate(u_in)
        return y_out, ref - y_out

    inputs, outputs, errors, rms, contours, cg_log = [], [], [], [], [], []

    def record(u_in, y_out, e_out):
        inputs.append(u_in)
        outputs.append(y_out)
        errors.append(e_out)
        rms.append(np.sqrt(np.mean(e_out**2, axis=0)))
        if contour_fn is not None:
            ce = contour_fn(ref, t, y_out)
            contours.append(float(np.sqrt(np.mean(ce**2))))
        if callback is not None:
            callback(len(inputs) - 1, rms[-1].copy())

    y, e = trial(u)
    record(u, y, e)
    total = [float(np.sqrt(np.sum(rms[-1] ** 2)))]
    stopped = "iterations"
    for _ in range(int(iterations)):
        if tol is not None and total[-1] <= tol:
            stopped = "tol"
            break
        u = _update(u, e, axes, law, q, cg_log)
        y, e = trial(u)
        record(u, y, e)
        total.append(float(np.sqrt(np.sum(rms[-1] ** 2))))
        if total[-1] > total[-2]:
            stopped = "diverged"
            break
    else:
        if tol is not None and total[-1] <= tol:
            stopped = "tol"
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
            stacklevel=2,
        )
    return ILCResult(
        u=inputs[-1],
        inputs=inputs,
        outputs=outputs,
        errors=errors,
        rms=np.array(rms),
        rms_total=np.array(total),
        check=check,
        stopped=stopped,
        law=law,
        gains={k: v.copy() for k, v in used_gains.items()},
        rms_contour=np.array(contours) if contour_fn is not None else None,
        solver=_solver_name(axes, law),
        cg=tuple(cg_log),
    )


def _solver_name(axes, law: str) -> str:
    if law != "norm-optimal":
        return ""
    names = [ax.normal.method if ax.normal is not None else "dense Cholesky" for ax in axes]
    return "; ".join(dict.fromkeys(names))


def _update(u: np.ndarray, e: np.ndarray, axes, law: str, q: QFilter | None, log) -> np.ndarray:
    new = np.empty_like(u)
    infos = []
    for i, ax in enumerate(axes):
        e_s = e[ax.r : ax.r + ax.n_r, i]  # eq. shift by the relative degree
        if law == "norm-optimal" and ax.normal is not None:
            step, info = ax.normal.solve(ax.normal.rhs(e_s), ax.prev)
            ax.prev = step
            infos.append(info)
        elif law == "norm-optimal":
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
