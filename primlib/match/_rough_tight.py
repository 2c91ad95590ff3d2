"""A tighter R_j (:mod:`._rough`) for a window's roughness ‖(I − P) W‖, from each support's
least-squares quintic: the shortest probes of an unmatched noisy stretch fail unsearched.

:mod:`._rough` bounds ‖(I − P) W‖ by ‖Φ‖₂·‖r‖ + |a|·g·√K, r the residual of the support's
least-squares cubic: the curve's quartic content sits in ‖r‖ whole, summed over the L samples
of the support, and the bound is 2.6-4.8x the roughest window (bundled library). Here the
support's samples (index m, centred: t = m − c, c = (L − 1)/2) are split as p̃ = Q + r₅, Q
the least-squares polynomial Σ_j q_j t^j of degree ≤ 5 (any Q would do), and

    Φ Q(x) = Σ_j q_j Σ_i C(j, i) τ^(j−i) (−1)^i M_i(x),  τ = x − c,
    M_i(x) = Σ_m (x − m)^i φ(x − m),

periodic in x, M_0 = 1, M_1 = M_2 = 0 (Catmull-Rom holds quadratics; M_3 = −g). The i = 0
terms give Q(τ_k), and with τ_k = τ_m + κ_k·h (κ_k = k − (K − 1)/2, τ_m the window's midpoint)
I − P removes all of Q(τ_k) but

    (q₄ + 5 q₅ τ_m)·h⁴·(I − P)κ⁴ + q₅·h⁵·(I − P)κ⁵,

exactly; the rest is at most √K·Σ_j |q_j| Σ_{i≥1} C(j, i)·T^(j−i)·max|M_i| (T = c − 1 bounds
|τ_k| of every point read inside the support), and Φ r₅ at most ‖Φ‖₂·‖r₅‖ as before. The
quartic term is taken at the largest h of each eighth of the bin, with τ_m over the windows
starting in the support's cell there (the whole support for a primitive's last one, which
holds every later window). The smaller of this and :mod:`._rough`'s bound is kept per
support, so R_j only falls: on the bundled library (K = 8) 1.6-2.4x below the cubic's at
the top octave of h, 2.3-5.7x at the others. All of it costs ~50 ms a K, so it is taken per
primitive and octave where a probe needs it (:meth:`._rough.Roughness.bound`).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

__all__ = ["tight_bin", "moment_max"]

_DEG = 5  # degree of the support's polynomial
_PARTS = 8  # pieces of a bin of h the quartic term is maximised on
_G = math.sqrt(3.0) / 18.0  # max |M_3| = max |g|
_U = 1e-9  # round-off margin, relative to the coordinates' magnitude (as ._rough)


@functools.cache
def moment_max(i: int) -> float:
    """max |M_i(f)| over f in [0, 1] (module notes), from the polynomial on [0, 1] (each
    of the 4 kernel pieces is one cubic there): its critical points and ends, plus 1e-12."""
    poly = np.polynomial.Polynomial
    f = poly([0.0, 1.0])
    near = lambda t: 1.5 * t**3 - 2.5 * t**2 + 1.0  # noqa: E731  φ on |t| <= 1
    far = lambda t: -0.5 * t**3 + 2.5 * t**2 - 4.0 * t + 2.0  # noqa: E731  on 1 <= |t| <= 2
    # n = -1, 0, 1, 2: (f - n) in [1, 2], [0, 1], [-1, 0], [-2, -1]
    m = (f + 1) ** i * far(f + 1) + f**i * near(f) + (f - 1) ** i * near(1 - f)
    m = m + (f - 2) ** i * far(2 - f)
    crit = [r.real for r in m.deriv().roots() if abs(r.imag) < 1e-12 and 0 <= r.real <= 1]
    return float(np.abs(m(np.array([0.0, 1.0, *crit]))).max()) + 1e-12


@functools.lru_cache(maxsize=64)
def _kappa_norms(k: int) -> tuple[float, float]:
    """‖(I − P)κ⁴‖, ‖(I − P)κ⁵‖ for κ = k − (K − 1)/2, P the cubics (k points)."""
    kap = np.arange(k, dtype=float) - 0.5 * (k - 1)
    basis = np.linalg.qr(np.vander(kap / max(k - 1, 1), 4, increasing=True))[0]
    res = [v - basis @ (basis.T @ v) for v in (kap**4, kap**5)]
    return float(np.linalg.norm(res[0])), float(np.linalg.norm(res[1]))


def _rest_factors(k: int, size: int) -> np.ndarray:
    """√K·Σ_{i≥1} C(j, i)·T^(j−i)·max|M_i| for j = 0 ... 5 (module notes), T = c − 1."""
    t = max(0.5 * (size - 1) - 1.0, 0.0)
    out = [sum(math.comb(j, i) * t ** (j - i) * moment_max(i) for i in range(1, j + 1))
           for j in range(_DEG + 1)]  # fmt: skip
    return math.sqrt(k) * np.array(out)


def tight_bin(ext: np.ndarray, ext_off: np.ndarray, k: int, h0: float, h1: float,
              phi: float, scale: float, prims: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
    """R_j for K = ``k`` points and h in [h0, h1] of the primitives ``prims`` (default all),
    in their order: over every support, the smaller of :mod:`._rough`'s bound (‖Φ‖₂ ≤
    ``phi``) and this module's, each with its round-off margin; ``ext``, ``ext_off`` the
    extended samples (:class:`._rough.Roughness`)."""
    ell = math.floor(1.0 + (k - 1) * h1 * (1.0 + 1e-9)) + 4
    prims = np.arange(ext_off.size - 1) if prims is None else np.asarray(prims)
    sizes = np.minimum(np.diff(ext_off)[prims], ell)
    out = np.zeros(prims.size)
    for size in np.unique(sizes):
        at = np.flatnonzero(sizes == size)
        out[at] = _supports(ext, ext_off, prims[at], int(size), k, (h0, h1), phi, scale)
    return out


def _supports(ext, ext_off, prims, size: int, k: int, bin_h: tuple[float, float],
              phi: float, scale: float) -> np.ndarray:  # fmt: skip
    """Largest per-support min(cubic bound, quintic bound) of each primitive of ``prims``."""
    if size <= 4:
        return np.zeros(prims.size)  # every sequence of 4 samples is a cubic
    d = ext.shape[1]
    t = np.arange(size, dtype=float) - 0.5 * (size - 1)
    # the quintics' orthonormal basis B (V = B R, V the Vandermonde matrix in t): its first
    # 4 columns span the cubics, so one product gives both fits and both residuals
    basis, tri = np.linalg.qr(np.vander(t, _DEG + 1, increasing=True))
    to3, to5 = np.linalg.inv(tri[:4, :4]), np.linalg.inv(tri)  # basis -> monomial coefficients
    fit5 = to5 @ basis.T  # (6, size): the monomial coefficients' rows, for the margin
    windows = sliding_window_view(ext, size, axis=0)  # (rows − size + 1, d, size)
    first = ext_off[prims]
    count = ext_off[prims + 1] - first - size + 1
    starts = np.repeat(first - np.cumsum(count) + count, count) + np.arange(count.sum())
    ids = np.repeat(np.arange(prims.size), count)
    last = np.zeros(starts.size, dtype=bool)
    last[np.cumsum(count) - 1] = True  # a primitive's last support holds every later window
    rest = _rest_factors(k, size)
    margin = _U * scale * (phi * math.sqrt(size * d) + math.sqrt(k))
    # each |q_j| is off by at most _U·scale·‖its pinv row‖₁ (per coordinate), times what
    # multiplies it: its rest factor, and h⁴·‖(I − P)κ⁴‖ (1 + 5|τ_m|, |τ_m| <= c), h⁵·‖(I − P)κ⁵‖
    v4, v5 = _kappa_norms(k)
    h1, c = bin_h[1] * (1.0 + 1e-9), 0.5 * (size - 1)
    mult = rest.copy()
    mult[4] += h1**4 * v4
    mult[5] += 5.0 * c * h1**4 * v4 + h1**5 * v5
    margin5 = margin + _U * scale * math.sqrt(d) * float(mult @ np.abs(fit5).sum(axis=1))
    out = np.zeros(prims.size)
    for g0 in range(0, starts.size, 1 << 13):  # blocks of supports: bounded temporaries
        block = slice(g0, g0 + (1 << 13))
        w = windows[starts[block]].reshape(-1, size)  # (m·d, size): each product one BLAS call
        coef = w @ basis  # (m·d, 6)
        res = w - coef @ basis.T
        res *= res
        r5sq = res.reshape(-1, d * size).sum(axis=1)  # ‖r₅‖², then ‖r₃‖² adds the rest
        r5 = np.sqrt(r5sq)
        r3 = np.sqrt(r5sq + (coef[:, 4:] ** 2).reshape(-1, 2 * d).sum(axis=1))
        q5 = (coef @ to5.T).reshape(-1, d, _DEG + 1).transpose(0, 2, 1)  # (m, 6, d)
        a3 = (coef[:, :4] @ to3[3]).reshape(-1, d)  # the cubic fit's t³ coefficient
        cubic = phi * r3 + _G * math.sqrt(k) * np.linalg.norm(a3, axis=1)
        quintic = _quartic(q5, size, k, bin_h, last[block]) + phi * r5
        quintic += np.linalg.norm(q5, axis=2) @ rest
        np.maximum.at(out, ids[block], np.minimum(cubic + margin, quintic + margin5))
    return out


def _quartic(q5: np.ndarray, size: int, k: int, bin_h: tuple[float, float],
             last: np.ndarray) -> np.ndarray:  # fmt: skip
    """max over h in the bin and the windows' midpoints τ_m of
    |q₄ + 5 q₅ τ_m|·h⁴·‖(I − P)κ⁴‖ + |q₅|·h⁵·‖(I − P)κ⁵‖ (module notes), per support."""
    v4, v5 = _kappa_norms(k)
    c, half = 0.5 * (size - 1), 0.5 * (k - 1)
    hs = np.linspace(bin_h[0] * (1.0 - 1e-9), bin_h[1] * (1.0 + 1e-9), _PARTS + 1)
    q4, q5n = q5[:, 4], np.linalg.norm(q5[:, 5], axis=1)
    out = np.zeros(q5.shape[0])
    for ha, hb in zip(hs[:-1], hs[1:], strict=True):
        # windows starting in [1, 2) of support coordinates; a last support: any that fits
        far = max(c - 1.0 - half * ha, 0.0)
        lo = np.where(last, -far, 1.0 + half * ha - c)
        hi = np.where(last, far, 2.0 + half * hb - c)
        lead = np.maximum(np.linalg.norm(q4 + 5.0 * lo[:, None] * q5[:, 5], axis=1),
                          np.linalg.norm(q4 + 5.0 * hi[:, None] * q5[:, 5], axis=1))  # fmt: skip
        np.maximum(out, lead * hb**4 * v4 + q5n * hb**5 * v5, out=out)
    return out
