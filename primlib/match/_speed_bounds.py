"""Lower bounds of the speed-profile term of the index search's score, from prefix sums of
the sample index (pure functions; the shape bounds are in :mod:`._bounds`, which re-exports
these).

The score combines the shape RMSD with ℓ·RMS(τ_w − τ_q), the normalised time at the arc
samples; :func:`speed_bound` splits the inner samples into groups G of consecutive ones,
Σ_{i∈G} (τ_w,i − τ_q,i)² ≥ |G|·(mean_G τ_w − mean_G τ_q)² (Cauchy–Schwarz), and the group
means of τ_w,i = (x_i − x_0)/(x_{K−1} − x_0) come from prefix sums of the sample index x
(:func:`strided_cumsum`), lowered by a proven round-off margin as the shape bounds are.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["strided_cumsum", "speed_bound", "speed_screen", "speed_groups"]

_U = 2.0**-53  # unit round-off of float64


def strided_cumsum(x: np.ndarray, dil: int) -> tuple[np.ndarray, float, float]:
    """Prefix sums C of ``x`` (M,) for the windows {m + i·dil}: Σ_{s<=i<e} x_{m+i·dil} =
    C[m + e·dil] − C[m + s·dil]; with max |C| and max |x| (for the round-off margins, as in
    :func:`strided_prefix_sums`)."""
    m = x.shape[0]
    rows = -(-m // dil)
    buf = np.zeros((rows + 1, dil))
    flat = buf.reshape(-1)
    flat[dil : dil + m] = x
    np.cumsum(buf, axis=0, out=buf)
    # max |v| as max(max v, −min v): the same value, without an |v| temporary of each
    return flat, _abs_max(flat), _abs_max(x)


def _abs_max(v: np.ndarray) -> float:
    """max |v| (0 for an empty v)."""
    return max(float(v.max(initial=0.0)), -float(v.min(initial=0.0)))


def speed_groups(tau_q: np.ndarray, parts: int) -> tuple[tuple[int, int, float], ...]:
    """The groups of :func:`speed_bound`: (first, end, mean τ_q over the group) for ``parts``
    groups of the K − 2 inner samples of ``tau_q`` (none when K <= 2). A query's groups
    are the same for every block of windows: compute them once and pass them on."""
    inner = tau_q.size - 2
    if inner <= 0:
        return ()
    edges = (1 + np.round(np.linspace(0.0, inner, min(parts, inner) + 1)).astype(int)).tolist()
    return tuple((s, e, float(np.mean(tau_q[s:e]))) for s, e in zip(edges[:-1], edges[1:],
                                                                    strict=True))  # fmt: skip


def _window_reader(block: tuple[int, int] | np.ndarray):
    """(n, col): the number of windows of ``block`` -- a range (c0, c1) read as slices, or
    an index array of window starts, gathered -- and ``col(a, off)``, the values of ``a``
    ``off`` samples into each of them."""
    if isinstance(block, tuple):
        c0, c1 = block
        return c1 - c0, lambda a, off: a[c0 + off : c1 + off]
    return block.size, lambda a, off: a[block + off]


def speed_bound(
    csum: tuple[np.ndarray, float, float],
    x: np.ndarray,
    starts: np.ndarray | tuple[int, int],
    dil: int,
    tau_q: np.ndarray,
    ell: float,
    parts: int = 4,
    groups: tuple[tuple[int, int, float], ...] | None = None,
) -> np.ndarray:
    """Lower bound of ℓ·RMS(τ_w − τ_q) of windows of K = ``tau_q.size`` points (module notes).

    Parameters
    ----------
    csum : (array, float, float)
        :func:`strided_cumsum` of ``x`` at stride ``dil``.
    x : array, shape (M,)
        Sample index (non-decreasing along each window) at every point.
    starts : array of int, or (int, int)
        The windows' first points, or a range (c0, c1) of them (then sliced, not gathered).
    dil : int
    tau_q : array, shape (K,)
        The query's normalised time at its arc samples, 0 first and 1 last.
    ell : float
        The query's arc length.
    parts : int
        Groups of the K − 2 inner samples (the first and last agree by construction).
    groups : tuple, optional
        :func:`speed_groups` of ``tau_q`` and ``parts``, when already computed.

    Returns
    -------
    array
        One bound per window; 0 for a window whose x does not advance (the score then has
        no speed term).
    """
    csum_, cmax, xmax = csum
    k = tau_q.size
    n, col = _window_reader(starts)

    if k - 2 <= 0 or n == 0:
        return np.zeros(n)
    x0 = col(x, 0)
    dur = col(x, (k - 1) * dil) - x0
    moving = dur > 1e-9
    inv = np.divide(1.0, dur, out=np.ones(n), where=moving)
    acc = None  # the first group's term is the sum so far (0 + t = t for t >= 0)
    for s, e, mu in speed_groups(tau_q, parts) if groups is None else groups:
        g = col(csum_, e * dil) - col(csum_, s * dil)
        g *= 1.0 / (e - s)
        g -= x0
        g *= inv
        g -= mu
        g *= g
        g *= (e - s) / k
        if acc is None:
            acc = g
        else:
            acc += g
    lb = np.sqrt(acc, out=acc)
    # round-off: a group sum errs by <= (|G| + 2)·u·max|C|, its mean by <= 3·u·max|C|, the
    # rest by a few u·max|x|; divided by the duration, doubled for the products
    inv *= 2.0 * (3.0 * cmax + 8.0 * xmax) * _U
    lb -= inv
    lb -= 16.0 * _U + 1e-12 * (1.0 + lb)
    lb *= ell
    lb[~moving] = 0.0
    return lb


def speed_screen(
    csum: tuple[np.ndarray, float, float],
    x: np.ndarray,
    block: tuple[int, int] | np.ndarray,
    dil: int,
    tau_q: np.ndarray,
    ell: float,
    limit: float,
    parts: int = 2,
    groups: tuple[tuple[int, int, float], ...] | None = None,
) -> np.ndarray:
    """Mask of the windows c0 <= m < c1 (``block``), or of the windows starting at
    ``block`` (an index array: gathered, for sparse survivors), whose :func:`speed_bound` is
    below ``limit``, without its divisions and square roots: with D the window's duration
    and h_G = D·(mean_G τ_w − mean_G τ_q), the bound is below the limit unless
    Σ_G |G|/K·h_G² >= (D·(limit/ℓ + 16u + 1e-12) + E)²·(1 + 1e-11), E the round-off
    term of :func:`speed_bound` times D; windows whose x does not advance are kept.
    ``groups``: :func:`speed_groups` of ``tau_q`` and ``parts``, when already computed (a
    screen calls this once per block of windows).
    """
    csum_, cmax, xmax = csum
    k = tau_q.size
    n, col = _window_reader(block)

    if k - 2 <= 0 or not math.isfinite(limit):
        return np.ones(n, dtype=bool)
    x0 = col(x, 0)
    xe = col(x, (k - 1) * dil)
    dur = xe - x0
    # each step as written, the products into one spare buffer; the first group's term is
    # the sum so far (0 + t = t for a t >= 0, which a square times (e − s)/k is)
    acc, tmp = None, np.empty(n)
    for s, e, mu in speed_groups(tau_q, parts) if groups is None else groups:
        h = col(csum_, e * dil) - col(csum_, s * dil)
        h *= 1.0 / (e - s)
        h -= np.multiply(x0, 1.0 - mu, out=tmp)
        h -= np.multiply(xe, mu, out=tmp)
        h *= h
        h *= (e - s) / k
        if acc is None:
            acc = h
        else:
            acc += h
    rhs = dur * (limit / ell + 16.0 * _U + 1e-12)
    rhs += 2.0 * (3.0 * cmax + 8.0 * xmax) * _U
    rhs *= rhs
    rhs *= 1.0 + 1e-11
    return (acc < rhs) | (dur <= 1e-9)
