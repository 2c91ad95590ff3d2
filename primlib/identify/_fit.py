"""Output-error fit of one axis in one structure, initialised from an equation-error fit.

Notation: the record has n samples at step dt; u is the input (the feedforward added to the
PID output when the axis runs in a known PID loop C, with reference r), y the measured
position relative to the first sample; the first n_e samples estimate, the rest is held out.
For a structure's coefficients theta (:mod:`primlib.identify._structures`), y_hat(theta) is
the output of the ZOH-discretised candidate simulated by :class:`primlib.plant.Machine`
itself (in the loop with C when there is one), from rest. The fit minimises

    V(theta, c) = sum_{k < n_e} (y[k] - y_hat(theta)[k] - c)^2

over the box of stable theta with ``scipy.optimize.least_squares`` (trust-region
reflective). The constant c is the measurement error of the first sample, which every
deviation y inherits (without it, that one sample's noise biases every coefficient).

The start is the equation-error (ARX) fit: the least-squares solution of
y[k] = -a_1 y[k-1] - ... - a_p y[k-p] + b_1 v[k-1] + ... + b_p v[k-p], v the plant input
(u, plus C (r - y) in a loop), whose discrete poles z are moved into the stable set and
mapped to s = ln(z) / dt; given those poles the numerator is linear in the output, so it
is the least-squares fit of the simulated responses. A second start with generic poles
guards against a poor ARX fit (noise biases it) when the first leaves more than 3 % of the
output unexplained; the lower final V wins.

Uncertainty: with J the Jacobian of the residual at the optimum and
sigma^2 = V / (n_e - p - 1), the covariance of theta is sigma^2 (J^T J)^+ (the usual
asymptotic formula; it assumes white residuals, so with coloured disturbances it is
optimistic).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy import optimize, signal

from primlib._errors import InputError
from primlib.identify._structures import Structure
from primlib.plant import Machine, pid_polynomials

__all__ = ["AxisRecord", "AxisFit", "fit_axis"]

# Real discrete ARX poles are kept in [exp(-_S_MAX), 1] (|s| dt <= _S_MAX): a pole the
# ARX fit puts near or below 0 is noise, and its log would be meaningless.
_S_MAX = 3.0
_TOL = 1e-12  # least_squares ftol / xtol / gtol: noise-free data are matched to rounding
_MAX_NFEV = 100  # per coefficient
# The generic second start runs only when the first leaves a normalised RMS error above this
# on the estimation samples (a good first fit is not improved by it, and costs as much again).
_SECOND_START = 0.03


@dataclass(frozen=True)
class AxisRecord:
    """One axis's experiment.

    Attributes
    ----------
    u : array, shape (n,)
        Input (feedforward when there is a PID).
    y : array, shape (n,)
        Measured output relative to the first sample.
    dt : float
        Sample time of the record, s.
    n_est : int
        Samples used for the estimate (the rest is held out).
    pid : dict or None
        PID gains ``{"kp", "ki", "kd", "tf"}`` of the loop the axis ran in, or None.
    r : array, shape (n,) or None
        Reference of the PID loop (None: zero).
    """

    u: np.ndarray
    y: np.ndarray
    dt: float
    n_est: int
    pid: dict | None = None
    r: np.ndarray | None = None

    def simulate(self, num: np.ndarray, den: np.ndarray, n: int | None = None):
        """Output of the candidate over the first ``n`` samples (all by default), or None
        when the candidate is not a valid machine (an unstable loop)."""
        n = len(self.u) if n is None else n
        with warnings.catch_warnings():
            # a vanishing leading numerator coefficient is stripped by scipy with a warning
            warnings.simplefilter("ignore", signal.BadCoefficients)
            try:
                m = Machine(
                    "identify", self.dt, ("a",), {"a": (num, den)},
                    None if self.pid is None else {"a": self.pid},
                )  # fmt: skip
            except InputError:
                return None
        ref = None if self.r is None or self.pid is None else self.r[:n, None]
        return m.simulate(self.u[:n, None], ref)[:, 0]

    def plant_input(self) -> np.ndarray:
        """The plant's input v = u + C (r - y) (just u without a loop), from the measured y."""
        if self.pid is None:
            return self.u
        p = self.pid
        c, g = pid_polynomials(
            p["kp"], p.get("ki", 0.0), p.get("kd", 0.0), p.get("tf", 0.0), self.dt
        )
        r = np.zeros_like(self.y) if self.r is None else self.r
        return self.u + signal.lfilter(c, g, r - self.y)


@dataclass(frozen=True)
class AxisFit:
    """Result of fitting one axis in one structure.

    Attributes
    ----------
    structure : str
    num, den : array
        Continuous transfer function, descending powers of s, ``den[0] == 1``.
    num_std, den_std : array
        Standard uncertainty of each coefficient (0 for the fixed ones).
    nrmse : float
        Held-out normalised RMS error, rms(y - y_hat) / std(y) over the held-out samples
        (y_hat simulated over the whole record, so the held-out part starts from the state
        the model reached).
    nrmse_fit : float
        The same over the estimation samples.
    y_model : array, shape (n,)
        The model's output over the whole record (plus the offset).
    offset, offset_std : float
        The fitted offset c of the measured deviation (minus the first sample's error) and
        its standard uncertainty.
    """

    structure: str
    num: np.ndarray
    den: np.ndarray
    num_std: np.ndarray
    den_std: np.ndarray
    nrmse: float
    nrmse_fit: float
    y_model: np.ndarray
    offset: float = 0.0
    offset_std: float = 0.0


def _bounds(st: Structure) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of (theta, c): the structure's, and none on the offset."""
    lo, hi = st.bounds()
    return np.append(lo, -np.inf), np.append(hi, np.inf)


def _nrmse(y: np.ndarray, y_hat: np.ndarray) -> float:
    spread = np.std(y)
    return float(np.sqrt(np.mean((y - y_hat) ** 2)) / spread) if spread > 0 else np.inf


def _lagged(x: np.ndarray, p: int) -> np.ndarray:
    """Columns x[k-1], ..., x[k-p] for k = p .. n-1 (no loop over samples)."""
    n = len(x)
    return np.stack([x[p - i : n - i] for i in range(1, p + 1)], axis=1)


def _arx_poles(v: np.ndarray, y: np.ndarray, p: int, dt: float) -> np.ndarray:
    """Continuous poles of the order-p ARX fit, moved into the closed left half plane."""
    phi = np.hstack([-_lagged(y, p), _lagged(v, p)])
    coef = np.linalg.lstsq(phi, y[p:], rcond=None)[0]
    z = np.roots(np.concatenate([[1.0], coef[:p]])).astype(complex)
    real = np.abs(z.imag) <= 1e-12 * np.maximum(1.0, np.abs(z))
    z[real] = np.clip(z[real].real, np.exp(-_S_MAX), 1.0)
    big = np.abs(z) > 1.0
    z[big] /= np.abs(z[big])
    return np.log(z) / dt


def _numerator(st: Structure, rec: AxisRecord, den: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Least-squares numerator for a fixed denominator: the output is linear in it."""
    open_loop = AxisRecord(v, rec.y, rec.dt, rec.n_est)
    n = rec.n_est
    cols = []
    for i in range(st.n_num - 1, -1, -1):
        basis = open_loop.simulate(np.concatenate([[1.0], np.zeros(i)]), den, n)
        cols.append(np.zeros(n) if basis is None else basis)
    cols.append(np.ones(n))  # the offset c
    return np.linalg.lstsq(np.stack(cols, axis=1), rec.y[:n], rcond=None)[0]


def _starts(st: Structure, rec: AxisRecord) -> list[np.ndarray]:
    """Start points: the ARX fit's, and generic poles (0 and the geometric mean of the
    record's lowest and the Nyquist frequency)."""
    v = rec.plant_input()
    n = rec.n_est
    if st.free_den == 0:
        dens = [st.tf(np.ones(st.size))[1]]
    else:
        w_mid = np.sqrt(2 * np.pi / (n * rec.dt) * np.pi / rec.dt)
        generic = np.array([0.0, -w_mid])[: st.poles] if st.poles > 1 else np.array([-w_mid])
        dens = [np.real(np.poly(_arx_poles(v[:n], rec.y[:n], st.poles, rec.dt))),
                np.real(np.poly(generic))]  # fmt: skip
    lo, hi = _bounds(st)
    out = []
    for den in dens:
        den = np.maximum(den, 0.0)
        den[0] = 1.0
        b = _numerator(st, rec, den, v)
        theta = np.concatenate([b[:-1], den[1 : 1 + st.free_den], b[-1:]])
        out.append(np.clip(theta, lo, hi))
    return out


def fit_axis(st: Structure, rec: AxisRecord) -> AxisFit:
    """Output-error least-squares fit of one axis in one structure.

    Parameters
    ----------
    st : Structure
    rec : AxisRecord

    Returns
    -------
    AxisFit
    """
    n = rec.n_est
    y_est = rec.y[:n]
    scale = float(np.std(y_est)) or 1.0

    def residual(theta):  # theta = (structure's coefficients, offset c)
        y_hat = rec.simulate(*st.tf(theta[:-1]), n)
        if y_hat is None:  # an unstable loop: far worse than predicting nothing
            return -10.0 * y_est / scale
        return (y_hat + theta[-1] - y_est) / scale

    lo, hi = _bounds(st)
    best = None
    for theta0 in _starts(st, rec):
        if best is not None and 2.0 * best.cost <= _SECOND_START**2 * n:
            break  # the first start explains all but a few % of the output: no second
        res = optimize.least_squares(
            residual, theta0, bounds=(lo, hi), x_scale="jac", ftol=_TOL, xtol=_TOL,
            gtol=_TOL, max_nfev=_MAX_NFEV * (st.size + 1),
        )  # fmt: skip
        if best is None or res.cost < best.cost:
            best = res
    theta, offset = best.x[:-1], float(best.x[-1])
    dof = max(n - st.size - 1, 1)
    sigma2 = 2.0 * best.cost / dof  # scaled residuals: the scale cancels in sigma2 (J^T J)^+
    cov = sigma2 * np.linalg.pinv(best.jac.T @ best.jac)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    num, den = st.tf(theta)
    y_model = rec.simulate(num, den) + offset
    num_std = std[: st.n_num]
    den_std = np.concatenate([[0.0], std[st.n_num : st.size], np.zeros(st.poles - st.free_den)])
    return AxisFit(
        structure=st.name,
        num=num,
        den=den,
        num_std=num_std,
        den_std=den_std,
        nrmse=_nrmse(rec.y[n:], y_model[n:]),
        nrmse_fit=_nrmse(y_est, y_model[:n]),
        y_model=y_model,
        offset=offset,
        offset_std=float(std[-1]),
    )
