"""Lower bounds of the Kabsch RMSD of sliding windows, from prefix sums (pure functions).

A *window* is K points ``p_{m + i·dil}`` (i < K) of a point sequence (one level of the
arc-length index); the query is K centred points Q̃. Every bound here is at or below the
RMSD of eq. (1) (``_kabsch``) for *every* rotation family ("full", "z", "none"): they hold
for the best orthogonal R, and the restricted families only raise the RMSD.

Two bounds, both computed from strided prefix sums of the coordinates, |p|² and the products
p_a·p_b (:func:`strided_prefix_sums`), so no window is gathered:

* :func:`half_window_bound` (every window): split P and Q into halves of k1 and k2 points.
  Under the optimal motion the error energy K·rmsd² splits into each half's centroid error
  (k_h δ_h²) and its centred part (≥ k_h (g_h(P) − g_h(Q))², the radius-of-gyration bound,
  Cauchy–Schwarz on eq. (2)); the distance D between the half centroids is rigid, so
  δ1 + δ2 ≥ |D(P) − D(Q)| and min k1δ1² + k2δ2² = k1k2/K·ΔD². Hence
  rmsd² ≥ (k1k2/K·ΔD² + Σ_h k_h Δg_h²)/K.
* :func:`principal_bound` (the survivors): the principal values of the windows' scatter
  matrices (:func:`principal_bound_points`: the same from the survivors' gathered points,
  so the prefix sums need no products for the rotation-invariant search). von Neumann's
  trace inequality, tr(R P̃ᵀQ̃) ≤ Σ s_i(P̃) s_i(Q̃) for any orthogonal R, gives
  rmsd² ≥ Σ (s_i(P̃) − s_i(Q̃))² / K.

A third bound is on the other term of the search's score, ℓ·RMS(τ_w − τ_q) (the normalised
time at the arc samples, combined with the shape RMSD in quadrature):
:func:`speed_bound` (every window, before any shape bound) splits the inner samples into
groups G of consecutive ones, Σ_{i∈G} (τ_w,i − τ_q,i)² ≥ |G|·(mean_G τ_w − mean_G τ_q)²
(Cauchy–Schwarz), and the group means of τ_w,i = (x_i − x_0)/(x_{K−1} − x_0) come from
prefix sums of the sample index x (:func:`strided_cumsum`).

All are lowered by a proven round-off margin (window sums are differences of running sums:
the error of a difference n steps apart is at most (n + 2)·u·max|P|, u = 2⁻⁵³), so they stay
below the RMSD computed exactly. :func:`gyration_bound` is the one-number bound the
time-uniform grid uses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from primlib.match._speed_bounds import speed_bound, speed_groups, speed_screen, strided_cumsum

__all__ = [
    "QueryMoments",
    "strided_prefix_sums",
    "product_pairs",
    "products_for",
    "half_window_bound",
    "half_window_bound_fixed",
    "half_bound_margin",
    "principal_bound",
    "principal_bound_points",
    "gyration_bound",
    "sym_eigvals",
    "strided_cumsum",
    "speed_bound",
    "speed_screen",
    "speed_groups",
]

_U = 2.0**-53  # unit round-off of float64
_BLOCK = 1 << 14  # windows per block of the half-window bound (cache-sized)
_SPAN = 1 << 14  # columns of the prefix sums filled and summed at a time (cache-sized)


def _pairs(d: int) -> list[tuple[int, int]]:
    """The products' rows (a, b), a ≤ b: the d squares first, then the cross products (the
    per-axis bound reads the coordinates' and the squares' rows, two slices)."""
    return [(a, a) for a in range(d)] + [(a, b) for a in range(d) for b in range(a + 1, d)]


def product_pairs(d: int, products: bool | str) -> list[tuple[int, int]]:
    """The products' rows of :func:`strided_prefix_sums` for ``products``: all of
    :func:`_pairs` (True), the d squares alone ("squares": the first d of them), none."""
    if products == "squares":
        return _pairs(d)[:d]
    return _pairs(d) if products else []


def products_for(rotation: str) -> bool | str:
    """The products' rows a rotation family's bounds read from the prefix sums: none for
    the rotation-invariant bound (``"full"``), the squares for the per-axis bound of
    ``"none"``, all of them for ``"z"`` (its principal-value bound reads the scatter)."""
    return False if rotation == "full" else "squares" if rotation == "none" else True


def strided_prefix_sums(
    pts: np.ndarray, dil: int, products: bool | str = True
) -> tuple[np.ndarray, np.ndarray, float]:
    """Prefix sums for the windows {m + i·dil, i < n}, m = 0, 1, ... of a point sequence.

    Rows: the d coordinates, |p|², then (with ``products``) the products p_a·p_b (a ≤ b;
    the squares p_a² first, then a < b in order; ``products="squares"``: the squares
    alone), so the sums, the centroid, the radius of gyration and the scatter matrix of any
    window come from two columns:
    Σ_{i<n} f(p_{m+i·dil}) = P[:, m + n·dil] − P[:, m] (P[:, m] sums the earlier points of
    m's phase m mod dil).

    Parameters
    ----------
    pts : array, shape (M, d)
    dil : int
        Stride between a window's points, >= 1.
    products : bool or "squares"
        Also the products' rows (:func:`principal_bound` needs them all, the per-axis
        bound of :func:`half_window_bound_fixed` the squares alone, :func:`half_window_bound`
        none). Each row holds the same values whichever others are built (each is filled
        and summed on its own: :func:`_running_sums`).

    Returns
    -------
    P : array, shape (c, L)
        c = d + 1 + d(d + 1)/2 rows (d + 1 without ``products``, 2d + 1 with the squares
        alone), L = (⌈M/dil⌉ + 1)·dil columns.
    pmax : array, shape (c,)
        max |P| per row (for the round-off margins).
    radius : float
        max |p| over the points.

    Filled and summed ``_SPAN`` columns at a time (in cache), the running sums carried from
    one span to the next: the same additions in the same order as one pass.
    """
    m, d = pts.shape
    rows = -(-m // dil)
    pairs = product_pairs(d, products)
    c = d + 1 + len(pairs)
    buf = np.zeros((c, rows + 1, dil))
    flat = buf.reshape(c, -1)
    top = np.zeros(c)  # max |P| per row so far
    energy_max = 0.0
    span = max(_SPAN // dil, 1)  # rows of buf (spans of dil columns) at a time
    scratch = np.empty(max(2, dil) * span)  # |p_a|² of a span; two rows interleaved
    for i0 in range(0, rows + 1, span):
        i1 = min(i0 + span, rows + 1)
        # points a0 .. a1 - 1 fill columns a + dil of these rows (the first dil are zeros)
        a0, a1 = max(i0 * dil - dil, 0), min(max(i1 * dil - dil, 0), m)
        if a1 > a0:
            energy_max = max(energy_max, _fill(flat, pts[a0:a1], a0 + dil, pairs, scratch))
        block = buf[:, i0:i1, :]
        if i0 > 0:  # the running sums so far, added to this block's first terms
            block[:, 0, :] += buf[:, i0 - 1, :]
        _running_sums(block, scratch)
        part = flat[:, i0 * dil : i1 * dil]
        np.maximum(top, np.maximum(part.max(axis=1), -part.min(axis=1)), out=top)
    return flat, top, math.sqrt(energy_max) if m else 0.0


def _fill(flat: np.ndarray, pts: np.ndarray, at: int, pairs: list[tuple[int, int]],
          scratch: np.ndarray) -> float:  # fmt: skip
    """Write the rows of :func:`strided_prefix_sums` of points ``pts`` (before summing)
    into columns ``at`` on of ``flat``; the largest |p|² among them."""
    n, d = pts.shape
    coords = flat[:d, at : at + n]
    coords[...] = pts.T  # contiguous rows: the products below read them, not pts' columns
    for i, (a, b) in enumerate(pairs):
        np.multiply(coords[a], coords[b], out=flat[d + 1 + i, at : at + n])
    energy = flat[d, at : at + n]
    if pairs:
        for i, (a, b) in enumerate(pairs):
            if a == b:
                energy += flat[d + 1 + i, at : at + n]
    else:
        sq = scratch[:n]
        for a in range(d):  # the same sum, in the same order, as from the products' rows
            np.multiply(coords[a], coords[a], out=sq)
            energy += sq
    return float(energy.max())


def _running_sums(block: np.ndarray, scratch: np.ndarray) -> None:
    """Running sums, in place, of every row of ``block`` (c, n, dil) along its second axis
    (P_{i+1} = P_i + f_{i+1}, each phase of dil apart), the same sums however they are
    laid out: two sequences at once as the real and imaginary parts of complex numbers
    (complex addition adds the parts alone; twice the sums per step of numpy's loop, whose
    each addition waits on the last), the dil = 2 phases as they lie, rows two by two when
    dil = 1 (interleaved in ``scratch``, 2n values or more)."""
    c, n, dil = block.shape
    if dil == 2:
        v = block.view(np.complex128)
        np.cumsum(v, axis=1, out=v)
        return
    if dil != 1:
        np.cumsum(block, axis=1, out=block)
        return
    pair = scratch[: 2 * n].reshape(n, 2)
    for r in range(0, c - 1, 2):
        pair[:, 0] = block[r, :, 0]
        pair[:, 1] = block[r + 1, :, 0]
        v = pair.view(np.complex128)
        np.cumsum(v, axis=0, out=v)
        block[r, :, 0] = pair[:, 0]
        block[r + 1, :, 0] = pair[:, 1]
    if c % 2:
        np.cumsum(block[c - 1], axis=0, out=block[c - 1])


@dataclass(frozen=True)
class QueryMoments:
    """What the bounds need of the centred query Q̃ (K points).

    Attributes
    ----------
    k, k1, k2 : int
        Points, and points of the first and second half.
    gyration : float
        Radius of gyration √(|Q̃|²/K).
    half_distance : float
        Distance between the two halves' centroids.
    half_gyration : (float, float)
        Radius of gyration of each half about its own centroid.
    principal : array, shape (d,)
        Principal values s_i(Q̃) (square roots of the eigenvalues of Q̃ᵀQ̃), descending.
    principal_error : float
        Bound on their error from the closed-form eigenvalues.
    half_vector : array, shape (d,)
        First half's centroid minus the second's.
    half_axis_energy : array, shape (2, d)
        Σ (q − q̄_h)² per half and axis.
    """

    k: int
    k1: int
    k2: int
    gyration: float
    half_distance: float
    half_gyration: tuple[float, float]
    principal: np.ndarray
    principal_error: float
    half_vector: np.ndarray
    half_axis_energy: np.ndarray

    @classmethod
    def of(cls, qc: np.ndarray) -> QueryMoments:
        """Moments of centred points ``qc`` (K, d), K >= 2."""
        k = qc.shape[0]
        k1 = k // 2
        h1, h2 = qc[:k1], qc[k1:]
        scat = qc.T @ qc
        sv = np.sqrt(np.maximum(sym_eigvals(scat[None]), 0.0))[0]
        d = qc.shape[1]
        # each half's centroid and centred points once (the same values as taken apart)
        m1, m2 = h1.mean(axis=0), h2.mean(axis=0)
        c1, c2 = (h1 - m1) ** 2, (h2 - m2) ** 2
        half = m1 - m2
        return cls(
            k=k,
            k1=k1,
            k2=k - k1,
            gyration=math.sqrt(float(np.sum(qc * qc)) / k),
            half_distance=float(np.linalg.norm(half)),
            half_gyration=(
                math.sqrt(float(np.sum(c1)) / k1),
                math.sqrt(float(np.sum(c2)) / (k - k1)),
            ),
            principal=sv,
            # closed-form eigenvalues: acos near ±1 and the rest cost at most 1e-7·trace
            principal_error=math.sqrt(d * 1e-7 * float(np.trace(scat)) / k),
            half_vector=half,
            half_axis_energy=np.stack([c1.sum(axis=0), c2.sum(axis=0)]),
        )


def half_bound_margin(k: int, d: int, pmax: np.ndarray, radius: float) -> float:
    """Round-off margin of :func:`half_window_bound` for windows of k points.

    Window sums of n ≤ k terms err by ≤ (k + 2)·u·max|P| (:func:`strided_prefix_sums`);
    propagated to the centroid coordinates, the energies Σ|p − p̄|² (the subtraction
    |S|²/k included) and the bound by the triangle inequality on its weighted norm.
    """
    k1 = k // 2
    k2 = k - k1
    err_c = (k + 2) * _U * float(pmax[:d].max())
    err_e = (k + 2) * _U * float(pmax[d]) + 2 * math.sqrt(d) * radius * err_c
    err_e += d * err_c * err_c + 8 * _U * k * radius * radius
    err_d = math.sqrt(d) * err_c * (1.0 / k1 + 1.0 / k2)
    return math.sqrt((k1 * k2 / k * err_d * err_d + 2.0 * err_e) / k)


def _columns(psum: np.ndarray, rows: slice, starts: np.ndarray | None, c0: int, c1: int,
             shift: int, stride: int = 1) -> np.ndarray:  # fmt: skip
    """Columns m + shift of ``psum``'s ``rows`` for the windows m: m = j·stride for the
    block c0 <= j < c1 (a slice, contiguous when ``stride`` is 1), or ``starts[c0:c1]``
    (gathered).

    Gathered row by row with ``np.take`` (a contiguous row each; 2.5x less time than the
    fancy index ``psum[rows, idx]`` on tens of thousands of windows of a million-point
    level) into the layout that fancy index gives: window-major, so each row's arithmetic
    after it takes the same operands in the same order (np.einsum sums in another order
    on another layout).
    """
    if starts is None:
        return psum[rows, c0 * stride + shift : (c1 - 1) * stride + shift + 1 : stride]
    idx = starts[c0:c1] + shift
    at = range(*rows.indices(psum.shape[0]))
    out = np.empty((idx.size, len(at)))
    for j, r in enumerate(at):
        np.take(psum[r], idx, out=out[:, j])
    return out.T


def _halves(psum: np.ndarray, rows: slice, starts: np.ndarray | None, c0: int, c1: int,
            mid: int, end: int, stride: int = 1) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Sums of ``psum``'s ``rows`` over the first and the second half of the windows
    m = j·stride, c0 <= j < c1 (or ``starts[c0:c1]``): columns m + mid minus m, and m + end
    minus m + mid."""
    p0 = _columns(psum, rows, starts, c0, c1, 0, stride)
    p1 = _columns(psum, rows, starts, c0, c1, mid, stride)
    return p1 - p0, _columns(psum, rows, starts, c0, c1, end, stride) - p1


def half_window_bound(
    psum: np.ndarray,
    n_windows: int,
    dil: int,
    query: QueryMoments,
    margin: float,
    starts: np.ndarray | None = None,
    stride: int = 1,
) -> np.ndarray:
    """The half-window lower bound of every window m = 0 .. n_windows − 1 (module notes).

    Parameters
    ----------
    psum : array, shape (c, L)
        :func:`strided_prefix_sums` of the points at stride ``dil``.
    n_windows : int
        Windows to bound; window m needs column m + K·dil of ``psum``.
    dil : int
    query : QueryMoments
    margin : float
        :func:`half_bound_margin` (subtracted, with 1e-12 of the values).
    starts : array of int, optional
        Bound only the windows starting there (``n_windows`` is then ``starts.size``).
    stride : int
        Without ``starts``: bound the windows m = j·stride, j < n_windows (strided slices of
        ``psum``, not gathered: the coarse bounds of :mod:`._cone`).

    Returns
    -------
    array, shape (n_windows,)
        Lower bounds of each window's RMSD against the query.
    """
    k, k1, k2 = query.k, query.k1, query.k2
    d = query.principal.size
    gq1, gq2 = query.half_gyration
    lb = np.empty(n_windows)
    # contiguous slices, no gathering, in cache-sized blocks (2-3x faster than whole arrays)
    for c0 in range(0, n_windows, _BLOCK):
        c1 = min(c0 + _BLOCK, n_windows)
        s1, s2 = _halves(psum, slice(0, d + 1), starts, c0, c1, k1 * dil, k * dil, stride)
        dd = s1[:d] * (1.0 / k1) - s2[:d] * (1.0 / k2)  # c1 − c2
        dd = np.sqrt(np.einsum("ij,ij->j", dd, dd))
        dd -= query.half_distance
        e1 = s1[d] - np.einsum("ij,ij->j", s1[:d], s1[:d]) * (1.0 / k1)
        e2 = s2[d] - np.einsum("ij,ij->j", s2[:d], s2[:d]) * (1.0 / k2)
        np.maximum(e1, 0.0, out=e1)
        np.maximum(e2, 0.0, out=e2)
        dg1 = np.sqrt(e1 * (1.0 / k1))
        dg1 -= gq1
        dg2 = np.sqrt(e2 * (1.0 / k2))
        dg2 -= gq2
        dd *= dd
        dd *= k1 * k2 / k / k
        dg1 *= dg1
        dg1 *= k1 / k
        dg2 *= dg2
        dg2 *= k2 / k
        dd += dg1
        dd += dg2
        out = np.sqrt(dd, out=lb[c0:c1])
        out -= margin + 1e-12 * (query.gyration + out)
    return lb


def half_window_bound_fixed(
    psum: np.ndarray,
    n_windows: int,
    dil: int,
    query: QueryMoments,
    margin: float,
    rotation: str,
    starts: np.ndarray | None = None,
    stride: int = 1,
) -> np.ndarray:
    """The half-window bound for the restricted rotation families ``"none"`` and ``"z"``.

    With R = I the centroid errors satisfy δ1 − δ2 = Δ(P) − Δ(Q) as vectors (Δ the first
    half's centroid minus the second's), and the centred error splits per axis, each axis
    bounded by its own radius of gyration (Cauchy–Schwarz per axis):
    K·rmsd² ≥ k1k2/K·|Δ(P) − Δ(Q)|² + Σ_h Σ_a k_h (g_ha(P) − g_ha(Q))². A rotation about z
    keeps the z components and the xy norms: the xy parts enter as for ``"full"`` (norms of
    the xy centroid difference, xy radii of gyration), z as for ``"none"``. Both are far
    tighter than the rotation-invariant bound when the family is restricted. ``margin`` as
    for :func:`half_window_bound`, with the per-axis energies' errors (d times the total's);
    ``starts`` and ``stride`` as there.

    Returns
    -------
    array, shape (n_windows,)
    """
    k, k1, k2 = query.k, query.k1, query.k2
    d = query.principal.size
    sq = slice(d + 1, 2 * d + 1)  # the squares' rows (:func:`_pairs`)
    lb = np.empty(n_windows)
    for c0 in range(0, n_windows, _BLOCK):
        c1 = min(c0 + _BLOCK, n_windows)
        # the coordinates' and the squares' rows alone: |p|² and the cross products are
        # not read (4 rows of 10 fewer to read and subtract, in 3-D)
        s1, s2 = _halves(psum, slice(0, d), starts, c0, c1, k1 * dil, k * dil, stride)
        # C order, as the squares' rows gathered from the sums were: np.einsum adds the
        # axes' terms in another order on another layout (the last bit of the bound)
        q1, q2 = map(
            np.ascontiguousarray, _halves(psum, sq, starts, c0, c1, k1 * dil, k * dil, stride)
        )
        # each step as written, in place where the layout then stays what it was (the
        # squares' energies C-ordered: q's order wins over the products')
        dvec = s1 * (1.0 / k1)
        dvec -= s2 * (1.0 / k2)
        dvec -= query.half_vector[:, None]
        e = []
        for s, q, kh in ((s1, q1, k1), (s2, q2, k2)):
            t = s * s
            t *= 1.0 / kh
            t = q - t
            e.append(np.maximum(t, 0.0, out=t))
        if rotation == "z":
            pv = s1[:2] * (1.0 / k1) - s2[:2] * (1.0 / k2)
            dxy = np.sqrt(np.einsum("ij,ij->j", pv, pv)) - math.hypot(*query.half_vector[:2])
            dist2 = dxy * dxy + dvec[2] * dvec[2]
            gap = 0.0
            for h, kh in ((0, k1), (1, k2)):
                qe = query.half_axis_energy[h]
                gxy = np.sqrt((e[h][0] + e[h][1]) / kh) - math.sqrt((qe[0] + qe[1]) / kh)
                gz = np.sqrt(e[h][2] / kh) - math.sqrt(qe[2] / kh)
                gap = gap + kh * (gxy * gxy + gz * gz)
        else:
            dist2 = np.einsum("ij,ij->j", dvec, dvec)
            gap = 0.0
            for h, kh in ((0, k1), (1, k2)):
                g = np.sqrt(np.divide(e[h], kh, out=e[h]), out=e[h])
                g -= np.sqrt(query.half_axis_energy[h] / kh)[:, None]
                gap = gap + kh * np.einsum("ij,ij->j", g, g)
        out = np.sqrt((k1 * k2 / k * dist2 + gap) / k, out=lb[c0:c1])
        out -= margin + 1e-12 * (query.gyration + out)
    return lb


def principal_bound(
    psum: np.ndarray,
    starts: np.ndarray,
    dil: int,
    query: QueryMoments,
    pmax: np.ndarray,
    radius: float,
) -> np.ndarray:
    """The principal-value lower bound of the windows starting at ``starts`` (module notes),
    from the prefix sums' scatter matrices.

    Round-off: Weyl moves each eigenvalue by ≤ ‖E‖ (the scatter's error in Frobenius norm,
    plus the closed form's 1e-7·trace), and |√a − √b| ≤ √|a − b|.

    Returns
    -------
    array, shape (len(starts),)
    """
    k = query.k
    d = query.principal.size
    every = slice(0, psum.shape[0])
    s = _columns(psum, every, starts, 0, starts.size, k * dil) - _columns(
        psum, every, starts, 0, starts.size, 0)  # (c, m)  # fmt: skip
    scat = np.empty((starts.size, d, d))
    for i, (a, b) in enumerate(_pairs(d)):
        v = s[d + 1 + i] - s[a] * s[b] * (1.0 / k)
        scat[:, a, b] = v
        scat[:, b, a] = v
    err_c = (k + 2) * _U * float(pmax[:d].max())
    err_pp = (k + 2) * _U * float(pmax[d + 1 :].max())
    err_m = d * (err_pp + 2 * radius * err_c + err_c * err_c / k)  # ‖E‖_F of a scatter
    return _principal(scat, query, err_m)


def principal_bound_points(
    pts: np.ndarray, starts: np.ndarray, dil: int, query: QueryMoments, radius: float
) -> np.ndarray:
    """:func:`principal_bound` of the windows starting at ``starts`` from their points
    (gathered and centred: no prefix sums of products needed, and a smaller round-off).

    Round-off: a centred coordinate errs by ≤ (k + 2)·u·r (r = ``radius`` ≥ max |p|) and is
    at most 2r; a scatter entry, a sum of k products, by ≤ 8·k·(k + 2)·u·r², so
    ‖E‖_F ≤ 8·d·k·(k + 2)·u·r²; then as :func:`principal_bound`.

    Returns
    -------
    array, shape (len(starts),)
    """
    k = query.k
    d = query.principal.size
    idx = starts[:, None] + np.arange(k) * dil
    cols = [pts[:, a][idx] for a in range(d)]  # (m, k) per axis: 2x faster than (m, k, d)
    for c in cols:
        c -= c.mean(axis=1, keepdims=True)
    scat = np.empty((starts.size, d, d))
    for a, b in _pairs(d):
        scat[:, a, b] = scat[:, b, a] = np.einsum("mk,mk->m", cols[a], cols[b])
    err_m = 8.0 * d * k * (k + 2) * _U * radius * radius
    return _principal(scat, query, err_m)


def _principal(scat: np.ndarray, query: QueryMoments, err_m: float) -> np.ndarray:
    """The principal-value bound from the windows' scatter matrices (m, d, d), lowered by
    the margin of a scatter error ‖E‖_F ≤ ``err_m``."""
    k = query.k
    d = query.principal.size
    sv_p = np.sqrt(np.maximum(sym_eigvals(scat), 0.0))
    tr = np.maximum(np.trace(scat, axis1=1, axis2=2), 0.0)
    lb = np.sqrt(np.sum((sv_p - query.principal) ** 2, axis=1) / k)
    lb -= (
        np.sqrt(d * (err_m + 1e-7 * tr) / k) + query.principal_error + 1e-12 * (query.gyration + lb)
    )
    return lb


def gyration_bound(energy: np.ndarray, query_energy: float, k: int) -> np.ndarray:
    """|g(P) − g(Q)| ≤ rmsd: the radii of gyration from Σ|p̃|² and Σ|q̃|² (Cauchy–Schwarz on
    eq. (2): tr(R S) ≤ |P̃|·|Q̃|)."""
    return np.abs(np.sqrt(np.maximum(energy, 0.0) / k) - math.sqrt(query_energy / k))


def sym_eigvals(a: np.ndarray) -> np.ndarray:
    """Eigenvalues, descending, of symmetric (m, d, d) matrices, d in {2, 3}, in closed form
    (the trigonometric solution of the characteristic cubic for d = 3)."""
    if a.shape[-1] == 2:
        mid = 0.5 * (a[:, 0, 0] + a[:, 1, 1])
        rad = np.hypot(0.5 * (a[:, 0, 0] - a[:, 1, 1]), a[:, 0, 1])
        return np.stack([mid + rad, mid - rad], axis=1)
    q = (a[:, 0, 0] + a[:, 1, 1] + a[:, 2, 2]) / 3.0
    p1 = a[:, 0, 1] ** 2 + a[:, 0, 2] ** 2 + a[:, 1, 2] ** 2
    p2 = (a[:, 0, 0] - q) ** 2 + (a[:, 1, 1] - q) ** 2 + (a[:, 2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    safe = np.where(p > 0, p, 1.0)
    # B = (A − q·I)/p entry by entry, as rows of one (9, m) array (no (m, 3, 3)
    # temporaries, one division for the nine entries); the off-diagonal entries
    # a_ij − q·0 = a_ij, so every entry is the value the whole-matrix form gave up to the
    # sign of a zero. The determinant by its first row's cofactors, the three 2×2 minors
    # at once: elementwise the same products and sums, in the same order, as term by term
    b = a.reshape(-1, 9).T.copy()
    b[[0, 4, 8]] -= q
    b /= safe
    minors = b[[4, 3, 3]] * b[[8, 8, 7]] - b[[5, 5, 4]] * b[[7, 6, 6]]
    terms = b[:3] * minors
    det = terms[0] - terms[1] + terms[2]
    phi = np.arccos(np.clip(det / 2.0, -1.0, 1.0)) / 3.0
    l1 = q + 2.0 * p * np.cos(phi)
    l3 = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    l2 = 3.0 * q - l1 - l3
    return np.stack([l1, l2, l3], axis=1)
