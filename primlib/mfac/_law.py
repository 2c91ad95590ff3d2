"""CFDL-MFAC: pseudo-partial-derivative estimator, control law, and the PID baseline."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError

__all__ = ["MFACGains", "ppd_update", "mfac_increment", "CFDLMFAC", "PID", "cross_coupled"]


@dataclass(frozen=True)
class MFACGains:
    """Parameters of compact-form dynamic-linearisation MFAC (eqs. (16)-(20)).

    Attributes
    ----------
    rho : float
        Step factor rho > 0 of the control law (17) (paper: 100).
    lam : float
        Weight lambda > 0 on the input change in the criterion (16) (paper: 0.07).
    k1 : float
        Gain k1 >= 0 on the change of the one-step error in (20) (paper: 4000).
    eta : float
        Step eta in (0, 2) of the PPD estimator (18) (paper: in (0, 1], value not given).
    mu : float
        Penalty mu > 0 of the PPD estimator (18) (paper: "generally 1").
    reset : float
        Reset threshold epsilon > 0: the estimate returns to its initial value when
        ``|phi| <= reset``, ``|du| <= reset`` or its sign changes (Hou & Jin's reset rule).
    """

    rho: float = 100.0
    lam: float = 0.07
    k1: float = 4000.0
    eta: float = 0.5
    mu: float = 1.0
    reset: float = 1e-5

    def __post_init__(self) -> None:
        for name, lo, strict in (
            ("rho", 0.0, True),
            ("lam", 0.0, True),
            ("k1", 0.0, False),
            ("eta", 0.0, True),
            ("mu", 0.0, True),
            ("reset", 0.0, True),
        ):
            v = getattr(self, name)
            if not np.isfinite(v) or (v <= lo if strict else v < lo):
                op = ">" if strict else ">="
                raise InputError(f"{name}: expected a finite number {op} {lo:g}, got {v}")
        if self.eta >= 2.0:
            raise InputError(f"eta: expected a step in (0, 2), got {self.eta}")


def ppd_update(phi, du, dy, phi0, gains: MFACGains) -> np.ndarray:
    """One step of the pseudo-partial-derivative estimator with reset, per axis.

    ``phi(k) = phi(k-1) + eta du (dy - phi(k-1) du) / (mu + du^2)`` (eq. (18)), with
    ``du = u(k-1) - u(k-2)``, ``dy = y(k) - y(k-1)``; then ``phi(k) = phi0`` where
    ``|phi(k)| <= reset``, ``|du| <= reset`` or ``sign(phi(k)) != sign(phi0)``.

    Parameters
    ----------
    phi, du, dy, phi0 : array, shape (d,)

    Returns
    -------
    array, shape (d,)
    """
    phi = np.asarray(phi, dtype=float)
    du = np.asarray(du, dtype=float)
    new = phi + gains.eta * du / (gains.mu + du * du) * (dy - phi * du)  # eq. (18)
    reset = (np.abs(new) <= gains.reset) | (np.abs(du) <= gains.reset)
    reset |= np.sign(new) != np.sign(phi0)
    return np.where(reset, phi0, new)


def mfac_increment(phi, err_next, err_now, gains: MFACGains) -> np.ndarray:
    """Control increment of eq. (20), per axis.

    ``du(k) = rho phi / (lam + phi^2) [e(k+1) + k1 (e(k+1) - e(k))]`` with the one-step
    error ``e(k+1) = y*(k+1) - y(k)`` (eq. (19)). Summed over k this is a PI law on the
    one-step error with proportional gain ``k1 g`` and integral gain ``g`` per sample,
    ``g = rho phi / (lam + phi^2)`` adapted through ``phi``.

    Parameters
    ----------
    phi, err_next, err_now : array, shape (d,)

    Returns
    -------
    array, shape (d,)
    """
    g = gains.rho * phi / (gains.lam + phi * phi)  # eq. (17)
    return g * (err_next + gains.k1 * (err_next - err_now))  # eq. (20)


class CFDLMFAC:
    """Decentralised CFDL-MFAC, one loop per axis (Fig. 2, CEE-MFAC paper).

    Parameters
    ----------
    gains : MFACGains
    phi0 : array, shape (d,)
        Initial pseudo partial derivative per axis (output units per input unit, > 0 for a
        plant whose output grows with its input).

    Examples
    --------
    >>> c = CFDLMFAC(MFACGains(), phi0=[1e-3, 1e-3])
    >>> u = c.step(y=np.zeros(2), y_next=np.array([1e-6, 0.0]))
    """

    def __init__(self, gains: MFACGains, phi0) -> None:
        phi0 = np.asarray(phi0, dtype=float).reshape(-1)
        if not np.all(np.isfinite(phi0)) or np.any(phi0 == 0):
            raise InputError(f"phi0: expected finite non-zero initial PPDs, got {phi0.tolist()}")
        self.gains = gains
        self.phi0 = phi0
        d = phi0.size
        self.phi = phi0.copy()
        self.u = np.zeros(d)  # the MFAC's own output u(k-1)
        self._applied = np.zeros((2, d))  # the input the plant got at k-1 and k-2
        self._y_prev = None
        self._err_prev = np.zeros(d)

    def step(self, y, y_next, applied_prev=None) -> np.ndarray:
        """Control ``u(k)`` from the measured ``y(k)`` and the next reference ``y*(k+1)``.

        Parameters
        ----------
        y, y_next : array, shape (d,)
        applied_prev : array, shape (d,), optional
            The input the plant actually received at k-1 (the MFAC output plus the
            cross-coupling term); the PPD relates the plant's output change to it. Default:
            the MFAC's own previous output.

        Returns
        -------
        array, shape (d,)
        """
        y = np.asarray(y, dtype=float)
        if applied_prev is not None:
            self._applied[0] = applied_prev
        if self._y_prev is not None:
            du = self._applied[0] - self._applied[1]
            self.phi = ppd_update(self.phi, du, y - self._y_prev, self.phi0, self.gains)
        err = np.asarray(y_next, dtype=float) - y  # eq. (19)
        self.u = self.u + mfac_increment(self.phi, err, self._err_prev, self.gains)
        self._err_prev = err
        self._y_prev = y
        self._applied = np.stack([self.u, self._applied[0]])
        return self.u.copy()


class PID:
    """Discrete PID per axis, backward Euler (as :class:`primlib.plant.Machine`'s).

    ``u(k) = kp e(k) + ki dt sum e + kd (e(k) - e(k-1)) / dt``.

    Parameters
    ----------
    kp, ki, kd : float or array, shape (d,)
    dt : float
    """

    def __init__(self, kp, ki, kd, dt: float) -> None:
        self.kp, self.ki, self.kd = (np.asarray(g, dtype=float) for g in (kp, ki, kd))
        if not (np.isfinite(dt) and dt > 0):
            raise InputError(f"dt: expected a sample time > 0, got {dt}")
        self.dt = float(dt)
        self._int = 0.0
        self._prev = None

    def step(self, e) -> np.ndarray:
        e = np.asarray(e, dtype=float)
        self._int = self._int + self.ki * self.dt * e
        de = np.zeros_like(e) if self._prev is None else e - self._prev
        self._prev = e
        return self.kp * e + self._int + self.kd * de / self.dt


def cross_coupled(u, error, normal, kp: float) -> np.ndarray:
    """Cross-coupled control (eq. (6)): ``U = u + K_p C eps``.

    With the contour error signed positive to the left of travel and ``normal`` the left
    unit normal, the paper's coupling gains ``C = (-sin theta, cos theta)`` and its error
    ``eps`` (eq. (13), from the actual point toward the path) give ``C eps = -error *
    normal``: the correction pushes the axis back toward the path.

    Parameters
    ----------
    u : array, shape (d,) or (n, d)
    error : float or array, shape (n,)
    normal : array, shape (d,) or (n, d)
    kp : float

    Returns
    -------
    array, like ``u``
    """
    return np.asarray(u) - kp * np.asarray(error)[..., None] * np.asarray(normal)  # eq. (6)
