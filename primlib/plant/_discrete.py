"""Zero-order-hold discretisation and simulation in second-order sections (see
:mod:`primlib.plant._machine` for the notation and why sections rather than polynomials)."""

from __future__ import annotations

import numpy as np
from scipy import signal

__all__ = ["apply_sections", "closed_loop_poles", "plant_zeros", "sections", "zoh"]


def zoh(num: np.ndarray, den: np.ndarray, dt: float):
    """Zero-order-hold discretisation of num / den.

    ``scipy.signal.cont2discrete`` on the state-space realisation gives (A_d, B_d, C, D).
    Its transfer-function output loses digits: the numerator (~1e-4 at 5 ms) comes out as a
    difference of O(1) polynomials, relative error ~1e-12, which poles near 1 amplify. So
    the poles are the exact exp(p dt), the denominator is built from them, and the
    numerator from the Markov parameters h_0 = D, h_k = C A_d^(k-1) B_d (each accurate
    relative to its size): b = (a * h)[:m+1].

    Returns
    -------
    b, a : ndarray, shape (m + 1,)
        Ascending powers of q^-1, ``a[0] == 1``.
    ss : tuple (A_d, B_d, C, D)
    poles : ndarray, shape (m,)
    """
    order = len(den) - 1
    if order == 0:
        ss = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[num[-1] / den[0]]]))
        return np.array([num[-1] / den[0]]), np.array([1.0]), ss, np.zeros(0)
    A, B, C, D, _ = signal.cont2discrete(signal.tf2ss(num, den), dt, method="zoh")
    poles = np.exp(np.roots(den) * dt)
    a = np.real(np.poly(poles))
    h = np.empty(order + 1)
    h[0] = D[0, 0] if len(num) == len(den) else 0.0  # exact zero when strictly proper
    x = B[:, 0]
    for k in range(1, order + 1):
        h[k] = C[0] @ x
        x = A @ x
    b = np.convolve(a, h)[: order + 1]
    return b, a, (A, B, C, D), poles


def closed_loop_poles(ss, c: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Eigenvalues of the closed-loop state matrix (plant ZOH state space, PID state space,
    algebraic loop through D and the PID feedthrough solved). Far better conditioned than
    the roots of the closed-loop polynomial when the poles cluster near 1."""
    A, B, C, D = ss
    if len(g) > 1:
        Ac, Bc, Cc, Dc = signal.tf2ss(c, g)
    else:
        Ac, Bc, Cc, Dc = np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[c[0]]])
    s = 1.0 / (1.0 + D[0, 0] * Dc[0, 0])
    # y = s (C x + D Cc xc) + ..., e = r - y, v = u + Cc xc + Dc e
    e_x, e_c = -s * C, -s * (D @ Cc)
    v_x, v_c = Dc @ e_x, Cc + Dc @ e_c
    Acl = np.block([[A + B @ v_x, B @ v_c], [Bc @ e_x, Ac + Bc @ e_c]])
    return np.linalg.eigvals(Acl) if Acl.size else np.zeros(0)


def plant_zeros(b: np.ndarray, extra: np.ndarray) -> np.ndarray:
    b_r = np.trim_zeros(np.trim_zeros(b, "f"), "b")
    zeros = np.roots(b_r) if len(b_r) > 1 else np.zeros(0)
    return np.concatenate([zeros, extra])


def sections(num: np.ndarray, zeros: np.ndarray, poles: np.ndarray) -> tuple[np.ndarray, int]:
    """Second-order sections of num / den from accurate zeros and poles, and the delay.

    In lfilter's convention (ascending powers of q^-1, den[0] = 1),
    ``num = q^-r k prod(1 - z_i q^-1)`` with k the first non-zero coefficient at index r;
    ``zpk2sos`` cannot hold the pure delay q^-r (it pads zeros at the origin, which are
    factors of 1 here), so the delay is returned separately and applied by shifting.
    """
    nz = np.flatnonzero(num)
    if len(nz) == 0:
        return np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0.0]]), 0
    r = int(nz[0])
    if len(zeros) == 0 and len(poles) == 0:
        return np.array([[num[r], 0.0, 0.0, 1.0, 0.0, 0.0]]), r
    return signal.zpk2sos(zeros, poles, num[r]), r


def apply_sections(section: tuple[np.ndarray, int], x: np.ndarray) -> np.ndarray:
    sos, r = section
    y = signal.sosfilt(sos, x)
    if r == 0:
        return y
    out = np.zeros_like(y)
    out[r:] = y[: len(y) - r]
    return out
