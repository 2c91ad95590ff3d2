"""The master–slave cross-coupled learning laws (TDILC, TDCCILC, PDILC, PDCCILC) as data.

Notation (master–slave PDCCILC paper, Ling et al. 2017): axis 0 of the two-axis signal is the
master x, axis 1 the slave y (``master=1`` swaps the roles). ``r`` (n, 2) is the reference
relative to the start point, ``e = r - y`` the tracking error of one trial, ``t`` the unit
tangent of the reference, ``n = (-t_y, t_x)`` its unit normal (eq. 3) and

    eps = <e, n> = -C_x e_x + C_y e_y,   C_x = t_y, C_y = t_x                  (eqs. 1-4)

the estimated contour error (the error vector projected on the normal of the reference's
tangent, Yeh & Hsu 2002). A law updates the feedforward input of the next trial as

    u_{j+1} = Q [ u_j + S ( L_e e_j + n L_eps eps_j ) ]                         (eqs. 5, 9)

with PID-type learning functions on a per-sample domain increment dw (eq. 10),

    (L f)[k] = kp f[k] + ki dw[k]/2 (f[k] + f[k-1]) + kd (f[k] - f[k-1]) / dw[k]
             = a[k] f[k] + b[k] f[k-1]                                     (eqs. 11-14, 16-19)

and ``S`` the lead shift of the paper's lifting (eq. 21: u(k) acts first on y(k + 1), so u(k)
learns from the error at k + lead). ``n L_eps eps`` is the paper's ``[-C_x; C_y] L_eps eps``
written frame-free: the contour error is learned and given back along the normal.

Domains. Time-domain (TD) learning uses dw = dt. Position-domain (PD) learning (the slave
axis, and the contour term of PDCCILC) uses the master's increment dw = dx (eqs. 13-14),
which vanishes wherever the master is at rest (the start, a semicircle's ends) and changes
sign where it reverses (a spiral). primlib uses the *regularised master travel*

    ds[k] = hypot(dx[k], delta),   delta = floor * (total master travel) / (n - 1)

as the domain increment: the position-domain variable s is monotonic, equals the master's
travel where the master moves, and its learning gains kd/ds are capped at kd/delta where it
stops, so the law never divides by zero and never flips the sign of its derivative gain.
A path along which the master never moves has no position domain: the PD laws then fall back
to their TD counterparts (dw = dt). ``dx`` is taken from the reference, not the measured
master position, so the law is the same in every trial (the lifted analysis, eqs. 20-32,
needs it iteration-invariant).

Differences from the paper, and why:
- eq. (16) multiplies gamma_x by e_x; it must multiply e_y (gamma_x = -C_x C_y k_p,eps is
  the cross term of -C_x L_eps eps). We difference eps itself, which is the exact discrete
  product rule of eq. (15); the paper's expansion (2 C_x - C~_x terms in eqs. 17, 19) does
  not follow from it.
- Table 1 gives the CCC an integral gain (0.5) that eq. (10)'s PD-type L_eps has no room
  for: L_eps here is PID-type like L_x, L_y, so Table 1 applies as printed.
- The "integral" of eq. (10) is over one sample (t - dt to t, discretised by eq. 11), as in
  the paper, not a running integral.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from primlib._errors import InputError

__all__ = [
    "LAWS",
    "MasterSlaveGains",
    "MasterSlaveLaw",
    "coupling_gains",
    "contour_error_estimate",
    "gaussian_q_kernel",
    "master_slave_law",
]

LAWS = ("tdilc", "tdccilc", "pdilc", "pdccilc")


def _triple(value, what: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape == (3,):
        arr = np.stack([arr, arr])
    if arr.shape != (2, 3) or not np.all(np.isfinite(arr)):
        raise InputError(
            f"{what}: expected finite (kp, ki, kd) or one (kp, ki, kd) per axis, "
            f"got {np.asarray(value).tolist()!r}"
        )
    return arr


@dataclass(frozen=True)
class MasterSlaveGains:
    """PID-type learning gains (eq. 10); defaults are Table 1 of the paper.

    Parameters
    ----------
    ilc : (kp, ki, kd) or array, shape (2, 3)
        Gains of L_x and L_y (one triple for both axes, or one per axis, in axis order).
    ccc : (kp, ki, kd)
        Gains of the contour-error learning function L_eps.
    """

    ilc: tuple = (0.3, 0.1, 0.1)
    ccc: tuple = (1.0, 0.5, 0.0)

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(ilc (2, 3), ccc (3,))`` as checked float arrays."""
        ilc = _triple(self.ilc, "gains.ilc")
        ccc = np.asarray(self.ccc, dtype=float)
        if ccc.shape != (3,) or not np.all(np.isfinite(ccc)):
            raise InputError(
                f"gains.ccc: expected finite (kp, ki, kd), got {np.asarray(self.ccc).tolist()!r}"
            )
        return ilc, ccc


def _check_reference(reference) -> np.ndarray:
    r = np.asarray(reference, dtype=float)
    if r.ndim != 2 or r.shape[1] != 2:
        raise InputError(
            f"reference: expected an array of shape (n, 2) for a master and a slave axis, "
            f"got shape {r.shape}"
        )
    if r.shape[0] < 3:
        raise InputError(f"reference: expected at least 3 samples, got {r.shape[0]}")
    if not np.all(np.isfinite(r)):
        raise InputError("reference: expected finite values, got NaN or inf")
    return r


def coupling_gains(reference) -> np.ndarray:
    """Unit normal of the reference (eq. 3), i.e. the coupling gains ``(-C_x, C_y)``.

    The tangent is the central difference of the reference; where the reference is at rest
    (no tangent) the nearest sample's tangent is used, so the gains are defined on any
    path that moves at all. A path that never moves has no contour: the gains are zero.

    Parameters
    ----------
    reference : array, shape (n, 2)

    Returns
    -------
    normal : array, shape (n, 2)
        ``normal[k] = (-t_y, t_x) / |t|`` at sample k, so eps = sum(normal * e, axis=1)
        (eq. 1 with C_x = t_y / |t|, C_y = t_x / |t|).
    """
    r = _check_reference(reference)
    tangent = np.gradient(r, axis=0)
    speed = np.hypot(tangent[:, 0], tangent[:, 1])
    scale = max(float(np.max(np.abs(r - r[0]))), np.finfo(float).tiny)
    valid = speed > 1e-12 * scale
    if not np.any(valid):
        return np.zeros_like(r)
    # nearest valid sample for each sample: forward fill, then back fill the head
    idx = np.where(valid, np.arange(len(r)), -1)
    idx = np.maximum.accumulate(idx)
    first = int(np.argmax(valid))
    idx[idx < 0] = first
    t = tangent[idx] / speed[idx, None]
    return np.column_stack([-t[:, 1], t[:, 0]])  # eq. (3)


def contour_error_estimate(reference, actual) -> tuple[np.ndarray, np.ndarray]:
    """Estimated contour error of ``actual`` against ``reference`` (eqs. 1-4).

    Parameters
    ----------
    reference, actual : array, shape (n, 2)

    Returns
    -------
    eps : array, shape (n,)
        Signed estimate <e, n>, e = reference - actual.
    vector : array, shape (n, 2)
        The contour-error vector <e, n> n (eq. 4).
    """
    r = _check_reference(reference)
    a = np.asarray(actual, dtype=float)
    if a.shape != r.shape:
        raise InputError(f"actual: expected the shape of reference {r.shape}, got {a.shape}")
    normal = coupling_gains(r)
    eps = np.sum(normal * (r - a), axis=1)  # eq. (1)
    return eps, eps[:, None] * normal  # eq. (4)


def gaussian_q_kernel(cutoff: float, dt: float) -> np.ndarray:
    """Zero-phase Gaussian FIR Q-filter with its -3 dB point at ``cutoff`` Hz.

    A Gaussian is used (not a windowed sinc or a Butterworth run forwards and backwards)
    because it is non-negative with a positive frequency response at most 1: the lifted
    Q-filter built from it (see :meth:`MasterSlaveLaw.q`) is symmetric with norm exactly 1,
    and the learning loop and the lifted analysis apply the same linear map.

    Parameters
    ----------
    cutoff : float
        -3 dB frequency in Hz, > 0 and at most 0.1325 / dt (a kernel a sample wide).
    dt : float
        Sample time in seconds.

    Returns
    -------
    kernel : array, shape (2 m + 1,)
        Symmetric, sums to 1.
    """
    cutoff = float(cutoff)
    limit = np.sqrt(np.log(2.0)) / (2 * np.pi * dt)
    if not np.isfinite(cutoff) or cutoff <= 0 or cutoff > limit:
        raise InputError(
            f"q_cutoff: expected a frequency in (0, {limit:.4g}] Hz for dt = {dt:g} s, "
            f"got {cutoff!r}"
        )
    sigma = np.sqrt(np.log(2.0)) / (2 * np.pi * cutoff * dt)  # samples; |Q| = 1/sqrt(2) at fc
    half = int(np.ceil(5 * sigma))
    k = np.arange(-half, half + 1)
    g = np.exp(-0.5 * (k / sigma) ** 2)
    return g / g.sum()


@dataclass(frozen=True)
class MasterSlaveLaw:
    """One learning law on one reference, as per-sample coefficients.

    Attributes
    ----------
    law : str
        One of ``LAWS``.
    master : int
        Index of the master axis (0 or 1).
    a, b : array, shape (n, 3)
        Coefficients of e[k] and e[k-1] in the learning functions of axis 0, axis 1 and the
        contour error (column 2; zero for the uncoupled laws), eqs. (16)-(19).
    normal : array, shape (n, 2)
        Coupling gains (unit normal of the reference), eq. (3).
    dw : array, shape (n, 3)
        Domain increments the three learning functions use (dt, or the regularised master
        travel ds).
    lead : int
        u(k) learns from the error at sample k + lead.
    q_kernel : array or None
        Symmetric Q-filter kernel (None: Q = I).
    q_weight : array, shape (n,), or None
        D^-1/2, the symmetric normalisation of the Q-filter (see :meth:`q`).
    dt : float
    """

    law: str
    master: int
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    dw: np.ndarray
    lead: int
    q_kernel: np.ndarray | None
    q_weight: np.ndarray | None
    dt: float

    @property
    def n(self) -> int:
        return self.a.shape[0]

    @property
    def coupled(self) -> bool:
        return self.law in ("tdccilc", "pdccilc")

    def correction(self, e: np.ndarray) -> np.ndarray:
        """The learning term ``S (L_e e + n L_eps eps)`` of eq. (9), shape (n, 2)."""
        e_prev = np.zeros_like(e)
        e_prev[1:] = e[:-1]
        corr = self.a[:, :2] * e + self.b[:, :2] * e_prev  # eqs. (16), (18), own-axis terms
        if self.coupled:
            eps = np.sum(self.normal * e, axis=1)  # eq. (1)
            eps_prev = np.zeros_like(eps)
            eps_prev[1:] = eps[:-1]
            corr += self.normal * (self.a[:, 2] * eps + self.b[:, 2] * eps_prev)[:, None]
        if self.lead:
            shifted = np.zeros_like(corr)
            shifted[: self.n - self.lead] = corr[self.lead :]
            corr = shifted
        return corr

    def q(self, u: np.ndarray) -> np.ndarray:
        """Apply the zero-phase Q-filter along axis 0 (any trailing shape).

        ``Q = D^-1/2 K D^-1/2`` with K the Gaussian Toeplitz section (zero padding) and D
        its row sums: symmetric (zero phase, Q^T = Q), exactly 1 on a constant away from
        the ends, and, being non-negative with the Perron vector D^1/2 1, of norm exactly 1.
        Plain zero padding (Q = K) would pull the input towards zero over the last
        half-width of the kernel and leave a large error there; edge padding keeps the
        end but has norm about 1.9 for a 1 Hz filter at 5 ms, which spoils eq. (30).
        """
        if self.q_kernel is None:
            return u
        w = self.q_weight.reshape((-1,) + (1,) * (u.ndim - 1))
        kern = self.q_kernel.reshape((-1,) + (1,) * (u.ndim - 1))
        return w * signal.oaconvolve(w * u, kern, mode="same", axes=0)

    def update(self, u: np.ndarray, e: np.ndarray) -> np.ndarray:
        """Next trial's input, eq. (9): ``Q (u + S (L_e e + n L_eps eps))``."""
        return self.q(u + self.correction(e))


def _check_options(r, law, dt, master, lead, floor) -> tuple[str, float, float]:
    """The law's name (lower case), dt and floor, each checked; the options too."""
    name = str(law).lower()
    if name not in LAWS:
        raise InputError(f"law: expected one of {', '.join(LAWS)}, got {law!r}")
    dt = float(dt)
    if not np.isfinite(dt) or dt <= 0:
        raise InputError(f"dt: expected a sample time > 0 s, got {dt!r}")
    if master not in (0, 1):
        raise InputError(f"master: expected axis 0 or 1, got {master!r}")
    if not isinstance(lead, int | np.integer) or not 0 <= lead < r.shape[0]:
        raise InputError(f"lead: expected an integer in [0, {r.shape[0] - 1}], got {lead!r}")
    floor = float(floor)
    if not np.isfinite(floor) or floor <= 0:
        raise InputError(f"floor: expected a fraction > 0 of the mean master step, got {floor!r}")
    return name, dt, floor


def _q_weight(q_kernel: np.ndarray, n: int) -> np.ndarray:
    return 1.0 / np.sqrt(signal.oaconvolve(np.ones(n), q_kernel, mode="same"))


def _domain_increments(r, dt: float, master: int, floor: float, position: bool) -> np.ndarray:
    """Per-sample domain increment dw (n, 3) of the master, the slave and the contour term:
    dt in the time domain, the regularised master travel ds in the position domain."""
    n = r.shape[0]
    # position domain: regularised master travel (see module docstring)
    # dx[0] = 0: the machine is at rest at the start point before the trial
    dx = np.diff(r[:, master], prepend=r[0, master])
    travel = float(np.sum(np.abs(dx)))
    if travel > 0:
        delta = floor * travel / (n - 1)
        ds = np.hypot(dx, delta)
    else:
        ds = np.full(n, dt)  # the master never moves: no position domain, TD fallback
    td = np.full(n, dt)
    dw = np.empty((n, 3))
    dw[:, master] = td  # the master always learns in time (eqs. 9, 16)
    dw[:, 1 - master] = ds if position else td  # eq. (13)-(14) for the slave
    dw[:, 2] = ds if position else td  # the contour term, eq. (15)
    return dw


def master_slave_law(
    reference,
    dt: float,
    law: str = "pdccilc",
    gains: MasterSlaveGains | None = None,
    q_cutoff: float | None = None,
    master: int = 0,
    lead: int = 1,
    floor: float = 0.25,
) -> MasterSlaveLaw:
    """Build one of the four laws for a reference.

    Parameters
    ----------
    reference : array, shape (n, 2)
        Reference relative to the start point, on the dt grid.
    dt : float
        Sample time in seconds.
    law : {"tdilc", "tdccilc", "pdilc", "pdccilc"}
        Case-insensitive.
    gains : MasterSlaveGains, optional
        Default: Table 1 of the paper.
    q_cutoff : float, optional
        -3 dB frequency (Hz) of the zero-phase Gaussian Q-filter; None: no Q-filter.
    master : {0, 1}
        Which axis is the master.
    lead : int
        Samples between an input and the error it learns from (>= 0; the paper's lifting,
        eq. 21, is 1).
    floor : float
        Regularisation of the position domain, as a fraction of the mean master step
        (> 0): ds = hypot(dx, floor * mean |dx|).

    Returns
    -------
    MasterSlaveLaw

    Raises
    ------
    InputError
        For a reference that is not (n >= 3, 2) and finite, an unknown law, or an option
        out of range (the message names it).

    Examples
    --------
    >>> th = np.pi * np.linspace(0, 1, 2401)
    >>> r = np.column_stack([10 * (1 - np.cos(th)), 10 * np.sin(th)])
    >>> law = master_slave_law(r, 0.005, "pdccilc", q_cutoff=1.0)
    >>> bool(law.dw[:, 1].min() > 0)    # the master rests at both ends: ds stays positive
    True
    """
    r = _check_reference(reference)
    name, dt, floor = _check_options(r, law, dt, master, lead, floor)
    gains = MasterSlaveGains() if gains is None else gains
    ilc, ccc = gains.arrays()
    n = r.shape[0]
    dw = _domain_increments(r, dt, master, floor, position=name in ("pdilc", "pdccilc"))
    k = np.vstack([ilc, ccc])  # rows: axis 0, axis 1, contour
    kp, ki, kd = k[:, 0], k[:, 1], k[:, 2]
    a = kp + ki * dw / 2 + kd / dw  # alpha/gamma, eqs. (17), (19)
    b = ki * dw / 2 - kd / dw  # beta/eta, eqs. (17), (19)
    normal = coupling_gains(r)
    if name in ("tdilc", "pdilc"):
        a[:, 2] = 0.0
        b[:, 2] = 0.0
    q_kernel = None if q_cutoff is None else gaussian_q_kernel(q_cutoff, dt)
    # D^-1/2: the symmetric normalisation of the kernel truncated at the ends (see q())
    q_weight = None if q_kernel is None else _q_weight(q_kernel, n)
    return MasterSlaveLaw(
        law=name,
        master=master,
        a=a,
        b=b,
        normal=normal,
        dw=dw,
        lead=int(lead),
        q_kernel=q_kernel,
        q_weight=q_weight,
        dt=dt,
    )
