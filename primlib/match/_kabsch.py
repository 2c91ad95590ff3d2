"""Kabsch superposition up to a proper rotation and a translation, batched.

Notation (used throughout ``primlib.match``): a *piece* is K points sampled at uniform time;
``P`` is the stored (moving) piece and ``Q`` the target, both shape (K, d). The superposition
``Q ≈ P @ R.T + t`` minimises the root-mean-square deviation (RMSD)

    rmsd² = min_{R ∈ SO(d), t} (1/K) Σ_j |q_j − R p_j − t|²                      (1)

(primitive-matching paper, §3.1: the "lrm" of the Kabsch algorithm, ref. [12]). With centred
pieces P̃, Q̃ and the cross-covariance S = P̃ᵀ Q̃ (d × d),

    rmsd² = (|P̃|² + |Q̃|² − 2 max_R tr(R S)) / K                                 (2)

and ``max_R tr(R S) = σ₁ + σ₂ + sign(det S) σ₃`` over proper rotations (σ the singular
values of S), which is also the largest eigenvalue of Horn's 4 × 4 quaternion matrix. For
the many-candidate searches we only need (2), never R: :func:`rmsd_from_moments` gets the
eigenvalue by deflating S's dominant singular pair (:func:`_deflated_lambda_max`; most pieces
are nearly straight, where the quartic's top root is nearly double) or else by Newton's
method on its characteristic polynomial (Theobald's QCP, 2005). Eq. (2)
resolves an RMSD down to about 1e-8 of the pieces' size (round-off in the difference); taking
σ₃ as the square root of an eigenvalue of SᵀS would lose it already at 1e-4, which matters
for planar pieces (σ₃ ≈ 0). :func:`kabsch` forms R by SVD for the few winners.

Rotation families (``rotation=``): ``"full"`` (SO(d)), ``"z"`` (3-D only: rotation about
the vertical z axis, so a 2-D Kabsch in the xy plane plus a z translation) and ``"none"``
(translation only).
A 2-D machine uses 2-D rotations, so a mirrored planar curve is never a match.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError

__all__ = ["KabschResult", "kabsch", "rmsd_from_moments", "rotation_for", "ROTATION_MODES"]

ROTATION_MODES = ("full", "z", "none")

# Relative size below which a singular value of S counts as zero (degenerate pieces: a
# straight line has rank-1 S, a point rank 0); then the rotation is chosen canonically.
_RANK_TOL = 1e-9
# ... and the canonical rotation is used only where it loses at most this much of tr(R S),
# relative to σ₁ (~45 ulps): for an exact line nothing, for a nearly straight one too much.
_CANON_LOSS = 1e-14
# Below this many pieces left by the deflation, eigvalsh of Horn's matrix costs less than
# Newton's vectorised iterations (each a dozen array operations, up to 60 of them)
_FEW = 256


@dataclass(frozen=True)
class KabschResult:
    """Optimal superposition ``Q ≈ P @ rotation.T + translation``.

    Attributes
    ----------
    rotation : array, shape (k, d, d) or (d, d)
        Proper rotations (det = +1).
    translation : array, shape (k, d) or (d,)
    rmsd : array, shape (k,) or float
    """

    rotation: np.ndarray
    translation: np.ndarray
    rmsd: np.ndarray


def _check_rotation(rotation: str, d: int) -> None:
    if rotation not in ROTATION_MODES:
        raise InputError(f"rotation: expected one of full, z, none, got {rotation!r}")
    if rotation == "z" and d != 3:
        raise InputError(f"rotation 'z' needs 3-D points, got {d}-D")


def _rotation_2d(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotations maximising ``a cos θ + b sin θ``; identity where a = b = 0."""
    norm = np.hypot(a, b)
    ok = norm > 0
    c = np.where(ok, a / np.where(ok, norm, 1.0), 1.0)
    s = np.where(ok, b / np.where(ok, norm, 1.0), 0.0)
    r = np.empty(a.shape + (2, 2))
    r[..., 0, 0] = c
    r[..., 0, 1] = -s
    r[..., 1, 0] = s
    r[..., 1, 1] = c
    return r


def _minimal_rotation(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest-angle rotation taking unit vectors u to v, shape (k, 3, 3) (Rodrigues)."""
    k = u.shape[0]
    axis = np.cross(u, v)
    s = np.linalg.norm(axis, axis=1)
    c = np.einsum("ki,ki->k", u, v)
    out = np.empty((k, 3, 3))
    small = s < 1e-12
    # antiparallel: half-turn about an axis normal to u (the first of x, y not parallel to u)
    anti = small & (c < 0)
    if np.any(anti):
        ref = np.where(np.abs(u[anti, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        ax = np.cross(u[anti], ref)
        ax /= np.linalg.norm(ax, axis=1, keepdims=True)
        out[anti] = 2.0 * ax[:, :, None] * ax[:, None, :] - np.eye(3)
    gen = ~small
    if np.any(gen):
        ax = axis[gen] / s[gen, None]
        kx = np.zeros((ax.shape[0], 3, 3))
        kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -ax[:, 2], ax[:, 1], -ax[:, 0]
        kx -= kx.transpose(0, 2, 1)
        ang = np.arctan2(s[gen], c[gen])
        out[gen] = (
            np.eye(3)
            + np.sin(ang)[:, None, None] * kx
            + (1.0 - np.cos(ang))[:, None, None] * (kx @ kx)
        )
    out[small & ~anti] = np.eye(3)
    return out


def _rotation_full(s: np.ndarray) -> np.ndarray:
    """Proper rotations R maximising tr(R S) for S of shape (k, d, d), canonical if degenerate."""
    k, d, _ = s.shape
    if d == 2:
        return _rotation_2d(s[:, 0, 0] + s[:, 1, 1], s[:, 0, 1] - s[:, 1, 0])
    u, sig, vt = np.linalg.svd(s)
    v = vt.transpose(0, 2, 1)
    det = np.sign(np.linalg.det(v @ u.transpose(0, 2, 1)))
    det[det == 0] = 1.0
    fix = np.ones((k, d))
    fix[:, -1] = det
    r = (v * fix[:, None, :]) @ u.transpose(0, 2, 1)
    top = sig[:, 0]
    rank0 = top <= 0.0
    rank1 = ~rank0 & (sig[:, 1] <= _RANK_TOL * top)
    if np.any(rank1):
        # a straight-line piece: every rotation about the line is optimal; take the least
        # turn, unless that costs more than round-off (a nearly straight piece, whose small
        # singular values still decide the best rotation about the line)
        idx = np.flatnonzero(rank1)
        r_min = _minimal_rotation(u[idx, :, 0], v[idx, :, 0])
        loss = np.einsum("kab,kba->k", r[idx] - r_min, s[idx])
        same = loss <= _CANON_LOSS * top[idx]
        r[idx[same]] = r_min[same]
    r[rank0] = np.eye(d)
    return r


def rotation_for(s: np.ndarray, rotation: str = "full") -> np.ndarray:
    """The optimal rotation (d, d) for one cross-covariance S = P̃ᵀ Q̃ (no checks; hot loops)."""
    d = s.shape[0]
    if rotation == "full":
        return _rotation_full(s[None])[0]
    r = np.eye(d)
    if rotation == "z":
        r[:2, :2] = _rotation_2d(np.array(s[0, 0] + s[1, 1]), np.array(s[0, 1] - s[1, 0]))
    return r


def _pieces(P, Q, weights, rotation: str):
    """Checked (k, n, d) float arrays, normalised weights (k, n), and whether the input
    was a single pair."""
    p = np.asarray(P, dtype=float)
    q = np.asarray(Q, dtype=float)
    single = p.ndim == 2
    if p.shape != q.shape or p.ndim not in (2, 3) or p.shape[-1] not in (2, 3):
        raise InputError(
            f"kabsch: expected P and Q of equal shape (k, n, d) or (n, d) with d in 2 or 3, "
            f"got {p.shape} and {q.shape}"
        )
    if p.shape[-2] < 1:
        raise InputError("kabsch: expected at least one point per piece, got 0")
    if single:
        p, q = p[None], q[None]
    k, n, d = p.shape
    _check_rotation(rotation, d)
    if weights is None:
        w = np.full((k, n), 1.0 / n)
    else:
        w = np.broadcast_to(np.asarray(weights, dtype=float), (k, n)).copy()
        if not np.all(np.isfinite(w)) or np.any(w < 0) or np.any(w.sum(axis=1) <= 0):
            raise InputError("kabsch: expected finite non-negative weights, not all zero")
        w /= w.sum(axis=1, keepdims=True)
    return p, q, w, single


def kabsch(
    P: np.ndarray,
    Q: np.ndarray,
    weights: np.ndarray | None = None,
    rotation: str = "full",
) -> KabschResult:
    """Optimal proper rotation and translation taking P onto Q, batched.

    Minimises ``Σ_j w_j |q_j − R p_j − t|² / Σ_j w_j`` over R ∈ SO(d) (or the z-axis
    rotations, or R = I) and t, eq. (1) of the module notes.

    Parameters
    ----------
    P, Q : array, shape (k, n, d) or (n, d)
        Moving and target point sets, d in {2, 3}, corresponding point by point.
    weights : array, shape (n,) or (k, n), optional
        Non-negative point weights (not all zero); uniform when None.
    rotation : {"full", "z", "none"}
        Rotation family: all proper rotations, rotations about the z axis (3-D only), or
        none (translation only).

    Returns
    -------
    KabschResult
        ``rotation`` (k, d, d), ``translation`` (k, d), ``rmsd`` (k,) — without the leading
        axis when P and Q were 2-D arrays. The rotation has det = +1 always: a mirror image
        is never reached. For degenerate pieces the rotation is canonical: identity for a
        point, the least-angle rotation aligning the two directions for straight lines.

    Raises
    ------
    InputError
        Shapes that differ or are not (k, n, d) with d in {2, 3}; an unknown rotation; bad
        weights.

    References
    ----------
    W. Kabsch, Acta Cryst. A32 (1976) 922; primitive-matching paper §3.1.

    Examples
    --------
    >>> P = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    >>> res = kabsch(P, P @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + 2.0)
    >>> round(float(res.rmsd), 12)
    0.0
    """
    p, q, w, single = _pieces(P, Q, weights, rotation)
    k, n, d = p.shape
    pc = np.einsum("kn,knd->kd", w, p)
    qc = np.einsum("kn,knd->kd", w, q)
    pt = p - pc[:, None, :]
    qt = q - qc[:, None, :]
    s = np.einsum("kn,kna,knb->kab", w, pt, qt)
    r = np.broadcast_to(np.eye(d), (k, d, d)).copy()
    if rotation == "full":
        r = _rotation_full(s)
    elif rotation == "z":
        r[:, :2, :2] = _rotation_2d(s[:, 0, 0] + s[:, 1, 1], s[:, 0, 1] - s[:, 1, 0])
    t = qc - np.einsum("kab,kb->ka", r, pc)
    resid = q - (np.einsum("kab,knb->kna", r, p) + t[:, None, :])
    rmsd = np.sqrt(np.einsum("kn,kn->k", w, np.einsum("knd,knd->kn", resid, resid)))
    if single:
        return KabschResult(r[0], t[0], float(rmsd[0]))
    return KabschResult(r, t, rmsd)


def _qcp_coefficients(s: np.ndarray):
    """C₂, C₁, C₀ of the characteristic polynomial λ⁴ + C₂λ² + C₁λ + C₀ of Horn's matrix
    (Theobald, Acta Cryst. A61 (2005) 478, eqs. 10-14)."""
    sxx, sxy, sxz = s[:, 0, 0], s[:, 0, 1], s[:, 0, 2]
    syx, syy, syz = s[:, 1, 0], s[:, 1, 1], s[:, 1, 2]
    szx, szy, szz = s[:, 2, 0], s[:, 2, 1], s[:, 2, 2]
    sxx2, syy2, szz2 = sxx * sxx, syy * syy, szz * szz
    sxy2, syx2, sxz2 = sxy * sxy, syx * syx, sxz * sxz
    szx2, syz2, szy2 = szx * szx, syz * syz, szy * szy
    sxzpszx, syzpszy, sxypsyx = sxz + szx, syz + szy, sxy + syx
    syzmszy, sxzmszx, sxymsyx = syz - szy, sxz - szx, sxy - syx
    sxxpsyy, sxxmsyy = sxx + syy, sxx - syy
    c2 = -2.0 * (sxx2 + syy2 + szz2 + sxy2 + syx2 + sxz2 + szx2 + syz2 + szy2)
    c1 = 8.0 * (sxx * syz * szy + syy * szx * sxz + szz * sxy * syx) - 8.0 * (
        sxx * syy * szz + syz * szx * sxy + szy * syx * sxz
    )
    dyz = syy * szz - syz * szy
    base = -sxx2 + syy2 + szz2 + syz2 + szy2
    c0 = (
        (sxy2 + sxz2 - syx2 - szx2) ** 2
        + (base - 2.0 * dyz) * (base + 2.0 * dyz)
        + (-sxzpszx * syzmszy + sxymsyx * (sxxmsyy - szz))
        * (-sxzmszx * syzpszy + sxymsyx * (sxxmsyy + szz))
        + (-sxzpszx * syzpszy - sxypsyx * (sxxpsyy - szz))
        * (-sxzmszx * syzmszy - sxypsyx * (sxxpsyy + szz))
        + (sxypsyx * syzpszy + sxzpszx * (sxxmsyy + szz))
        * (-sxymsyx * syzmszy + sxzpszx * (sxxpsyy + szz))
        + (sxypsyx * syzmszy + sxzmszx * (sxxmsyy - szz))
        * (-sxymsyx * syzpszy + sxzmszx * (sxxpsyy - szz))
    )
    return c2, c1, c0


def _horn_matrix(s: np.ndarray) -> np.ndarray:
    """Horn's symmetric 4 × 4 quaternion matrix N(S), shape (m, 4, 4): its largest
    eigenvalue is max tr(R S) over SO(3) (Horn, J. Opt. Soc. Am. A 4 (1987) 629)."""
    sxx, sxy, sxz = s[:, 0, 0], s[:, 0, 1], s[:, 0, 2]
    syx, syy, syz = s[:, 1, 0], s[:, 1, 1], s[:, 1, 2]
    szx, szy, szz = s[:, 2, 0], s[:, 2, 1], s[:, 2, 2]
    rows = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors b1, b2 making (n, b1, b2) a proper orthonormal basis, for unit vectors n
    of shape (3, m) (Duff et al., J. Comput. Graph. Tech. 6 (2017) 1: no division by zero)."""
    x, y, z = n
    sg = np.where(z >= 0, 1.0, -1.0)
    a = -1.0 / (sg + z)
    b = x * y * a
    return np.stack([1.0 + sg * x * x * a, sg * b, -sg * x]), np.stack([b, sg + y * y * a, -y])


def _deflated_lambda_max(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """max tr(R S) over SO(3) for S (m, 3, 3) with a dominant singular value, and where the
    result is as accurate as ``eigvalsh`` of Horn's matrix (a few ulps of σ₁).

    Two power steps on SᵀS from S's largest row give v ≈ v₁, u = Sv/|Sv|; completed to
    proper bases U = [u u₁ u₂], V = [v v₁ v₂] (:func:`_basis`), M = UᵀSV = [[a, c], [r, B]]
    has the same max tr(R M) as S (R ↦ V R Uᵀ maps SO(3) onto itself), r = 0 up to
    round-off, a = |Sv|, and the block-diagonal part's is a + max over 2-D rotations of
    tr(R₂ B) = a + hypot(b₀₀ + b₁₁, b₀₁ − b₁₀). In Horn's matrix N(M) the rotations about
    the first axis span an invariant pair of the block-diagonal part, holding its top two
    eigenvalues (≥ a − √2‖B‖) apart from the other two (≤ −a + √2‖B‖); the off-diagonal
    blocks of M only couple the two pairs (tr(R E) = 0 for those rotations), so by the
    block-perturbation bound they move λ_max by at most ‖N(E)‖²/gap ≤ 4‖E‖²/(2(a − √2‖B‖))
    (‖N(E)‖_F = 2‖E‖_F). Rows where that is at most 1e-15·λ are marked good; the others
    (σ₂ close to σ₁, or σ₁ = 0) are left to :func:`_qcp_lambda_max`. Where the quartic's
    top root is nearly double (σ₂, σ₃ ≪ σ₁: straight or nearly straight pieces, the most
    common windows of a smooth path) this is where Newton's method cannot resolve it.
    """
    t = np.ascontiguousarray(s.transpose(1, 2, 0))  # t[a, b] = S_ab, shape (3, 3, m)
    tt = np.ascontiguousarray(s.transpose(2, 1, 0))  # Sᵀ
    v = np.take_along_axis(t, np.argmax((t * t).sum(axis=1), axis=0)[None, None], axis=0)[0]
    for _ in range(2):
        v = (tt * (t * v).sum(axis=1)).sum(axis=1)
        v /= np.maximum(np.sqrt((v * v).sum(axis=0)), 1e-300)
    sv = (t * v).sum(axis=1)
    a = np.sqrt((sv * sv).sum(axis=0))
    u = sv / np.maximum(a, 1e-300)
    v1, v2 = _basis(v)
    u1, u2 = _basis(u)
    w = (tt * u).sum(axis=1)  # Sᵀu: c = (w·v₁, w·v₂)
    sv1, sv2 = (t * v1).sum(axis=1), (t * v2).sum(axis=1)
    b00, b01 = (u1 * sv1).sum(axis=0), (u1 * sv2).sum(axis=0)
    b10, b11 = (u2 * sv1).sum(axis=0), (u2 * sv2).sum(axis=0)
    lam = a + np.hypot(b00 + b11, b01 - b10)
    off2 = (w * v1).sum(axis=0) ** 2 + (w * v2).sum(axis=0) ** 2
    off2 += (u1 * sv).sum(axis=0) ** 2 + (u2 * sv).sum(axis=0) ** 2
    sep = a - np.sqrt(2.0 * (b00 * b00 + b01 * b01 + b10 * b10 + b11 * b11))
    return lam, (sep > 0) & (2.0 * off2 <= 1e-15 * lam * sep)


def _qcp_lambda_max(s: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of Horn's quaternion matrix for S (m, 3, 3) = max tr(R S) over SO(3).

    Newton's method on the characteristic polynomial (:func:`_qcp_coefficients`) started
    from an upper bound (|P̃|·|Q̃| ≤ (|P̃|² + |Q̃|²)/2), from which it decreases monotonically to the
    largest root (f is convex there: f'' > 0 beyond ‖S‖_F/√3 ≤ σ₁ ≤ λ_max). Fast, but
    ill-conditioned where the largest root is (nearly) double — straight or nearly straight
    pieces, points — since f and f' are then at round-off and the root is resolved only to
    √u of its size. Those (f' < 0.05·λ³ at the end, i.e. the next root within ~1 % of λ, or
    a step that left the bracket [‖S‖_F/√3, upper]) are recomputed by ``eigvalsh`` of
    Horn's matrix, which is backward stable: its error is u·‖N‖ however close the roots.
    """
    c2, c1, c0 = _qcp_coefficients(s)
    lam = upper.copy()
    lower = np.sqrt(np.einsum("mab,mab->m", s, s) / 3.0)
    idx = np.arange(lam.size)
    bad = np.zeros(lam.size, dtype=bool)
    for _ in range(60):
        lc = lam[idx]
        l2 = lc * lc
        f = (l2 + c2[idx]) * l2 + c1[idx] * lc + c0[idx]
        g = 4.0 * l2 * lc + 2.0 * c2[idx] * lc + c1[idx]
        step = np.where(g > 0, f / np.where(g > 0, g, 1.0), 0.0)
        new = lc - step
        lost = (g <= 0) | (new < lower[idx]) | (new > upper[idx])
        bad[idx[lost]] = True
        lam[idx] = np.where(lost, lc, new)
        busy = ~lost & (np.abs(step) > 1e-12 * np.maximum(np.abs(lc), 1e-300))
        idx = idx[busy]
        if idx.size == 0:
            break
    l2 = lam * lam
    g = 4.0 * l2 * lam + 2.0 * c2 * lam + c1
    bad |= g < 0.05 * l2 * lam
    if np.any(bad):
        lam[bad] = np.linalg.eigvalsh(_horn_matrix(s[bad]))[:, -1]
    return lam


def rmsd_from_moments(
    s: np.ndarray, sp: np.ndarray, sq: np.ndarray, n: int, rotation: str = "full"
) -> np.ndarray:
    """Kabsch RMSD of many pairs from their centred moments, no rotation formed.

    Parameters
    ----------
    s : array, shape (m, d, d)
        Cross-covariances S = P̃ᵀ Q̃ of centred pieces (moving P, target Q).
    sp, sq : array, shape (m,) or (m, d)
        Σ|p̃|² and Σ|q̃|² — per axis (m, d) when ``rotation="z"`` (the z column is needed
        apart).
    n : int
        Points per piece, K.
    rotation : {"full", "z", "none"}

    Returns
    -------
    rmsd : array, shape (m,)
        Eq. (2) of the module notes, clipped at 0 against round-off.
    """
    d = s.shape[-1]
    _check_rotation(rotation, d)
    if rotation == "z":
        sp = np.asarray(sp)
        sq = np.asarray(sq)
        best = np.hypot(s[:, 0, 0] + s[:, 1, 1], s[:, 0, 1] - s[:, 1, 0]) + s[:, 2, 2]
        total = sp.sum(axis=-1) + sq.sum(axis=-1)
    else:
        total = sp + sq
        if rotation == "none":
            best = np.trace(s, axis1=1, axis2=2)
        elif d == 2:
            best = np.hypot(s[:, 0, 0] + s[:, 1, 1], s[:, 0, 1] - s[:, 1, 0])
        else:
            best, good = _deflated_lambda_max(s)
            rest = np.flatnonzero(~good)
            if rest.size > _FEW:
                # tr(R S) = <P̃ Rᵀ, Q̃> <= |P̃| |Q̃| <= (|P̃|² + |Q̃|²) / 2: the tighter start
                # spares Newton's halving steps where the pieces' sizes differ
                top = np.sqrt(np.broadcast_to(sp, total.shape) * np.broadcast_to(sq, total.shape))
                best[rest] = _qcp_lambda_max(s[rest], top[rest] * (1.0 + 1e-12))
            elif rest.size:
                best[rest] = np.linalg.eigvalsh(_horn_matrix(s[rest]))[:, -1]
    return np.sqrt(np.maximum(total - 2.0 * best, 0.0) / n)
