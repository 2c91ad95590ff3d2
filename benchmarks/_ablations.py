"""Residual corrections the warm start was compared with (ablations, not part of primlib).

Each implements :class:`primlib.splice.Correction`; ``bench_warm_start.py`` prints their
first-trial errors beside the production :class:`primlib.splice.ErrorCorrection`
(``"error"``). Measured there:

- ``"input"``: ``u_s + G^-1 y_d - Σ λ_j G^-1 y_j`` (y_j a piece's own path from its rest,
  :func:`primlib.splice.piece_path`): the blended input corrections; cutting a piece's
  correction at its window leaves a state mismatch that integrates (worse than "error").
- ``"output"``: ``u_s + G^-1 (y_d - y_w)``, y_w the pieces' paths blended like the inputs.
  Blending inputs is not blending outputs: ``G (λ u) != λ G u`` over a band, and the
  difference (first order in the pieces' mismatch through the band) is left as an offset;
  measured no better than "none".
- ``"junction"`` (the design before "error"): least squares on the input within
  ``max(band / 2, 10 dt)`` of each junction so that the model's simulated output follows the
  path; good on a refined model, harmful on the nominal one (it fits the model's accumulated
  error, not the machine's).
- ``"none"``: the spliced pieces as they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib.splice import CorrectionJob, ErrorCorrection, PlacedPiece, model_inverse, piece_path

__all__ = [
    "InputCorrection",
    "OutputCorrection",
    "JunctionCorrection",
    "NoCorrection",
    "CORRECTIONS",
]

# weight of the first-difference penalty of the junction correction (relative)
JUNCTION_SMOOTH = 1e-3


@dataclass(frozen=True)
class InputCorrection:
    """``u_s + G^-1 y_d - Σ λ_j G^-1 y_j``: the blended model inverses of the pieces' paths."""

    name: str = "input"
    keeps_stored: bool = True

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> np.ndarray:
        pl = piece.placement
        if piece.stored is None:  # unmatched: the piece is the path's own inverse
            return piece.u
        if pl is None:
            return np.zeros((n, machine.dim))
        prim = piece.stored
        y_full = piece_path(machine, prim.signal, prim.points, **pl.transform_args())
        ref = y_full if machine.feedback else None
        v = model_inverse(machine, y_full, reference=ref)
        return pl.put(v + pl.hold[None, :], pl.hold, n)

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, str]:
        # eq. (11) by superposition on the residual: G^-1 y_d - Σ λ_j G^-1 y_j is the
        # model's input for what the pieces miss
        inv = model_inverse(job.machine, job.y_d, reference=job.reference)
        u = job.spliced + (inv - job.blend(job.terms))
        return u, (
            "residual correction: the model inverse of the path minus the blended model "
            "inverses of the pieces' own paths added to the spliced input"
        )


@dataclass(frozen=True)
class OutputCorrection:
    """``u_s + G^-1 (y_d - y_w)``, y_w the pieces' paths blended like the inputs."""

    name: str = "output"
    keeps_stored: bool = True

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> None:
        return None

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, str]:
        r = job.y_d - job.blend([p.path for p in job.pieces])
        u = job.spliced + model_inverse(
            job.machine, r, reference=r if job.machine.feedback else None
        )
        return u, (
            "residual correction: the model inverse of the path minus the pieces' blended "
            "paths added to the spliced input"
        )


def _junction_samples(t, bands, half: float) -> np.ndarray:
    mask = np.zeros(t.size, dtype=bool)
    for b in bands:
        mask |= np.abs(t - b.junction) <= half + 1e-9
    return np.flatnonzero(mask)


def correct_junctions(machine, u, y_d, t, bands, half: float, feedback: bool, smooth=None):
    """Least-squares input correction near the junctions; returns (u, samples per axis).

    min ||y_d - G (u + E x)||^2 + lam (smooth ||D x||^2 + 1e-8 ||x||^2) over x, E selecting
    the samples within ``half`` of a junction, G the lifted (closed-loop) model, D the first
    difference inside each band; lam = trace(A^T A) / m, A = G E, so the weights are
    relative and scale-free. The difference penalty keeps the correction from the
    alternating (Nyquist) inputs an exact sampled-data inverse would use.
    """
    n = u.shape[0]
    idx = _junction_samples(t, bands, half)
    if idx.size == 0:
        return u, 0
    resid = y_d - machine.simulate(u, y_d if feedback else None)
    h = machine.impulse_response(n)
    rows = np.arange(n)[:, None] - idx[None, :]  # G[r, j] = h[r - j] for r >= j
    valid = rows >= 0
    m = idx.size
    d = np.zeros((m - 1, m))
    d[np.arange(m - 1), np.arange(m - 1)] = -1.0
    d[np.arange(m - 1), np.arange(1, m)] = 1.0
    d = d[np.diff(idx) == 1]  # no difference across two bands
    smooth = JUNCTION_SMOOTH if smooth is None else smooth
    reg = smooth * (d.T @ d) + 1e-8 * np.eye(m)
    out = u.copy()
    for i in range(machine.dim):
        a = np.where(valid, h[np.clip(rows, 0, n - 1), i], 0.0)
        ata = a.T @ a
        lam = np.trace(ata) / m
        if lam <= 0:
            continue
        x = np.linalg.solve(ata + lam * reg, a.T @ resid[:, i])
        out[idx, i] += x
    return out, int(m)


@dataclass(frozen=True)
class JunctionCorrection:
    """Least squares on the input near each junction so the model follows the path."""

    name: str = "junction"
    keeps_stored: bool = False

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> None:
        return None

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, str | None]:
        plan = job.plan
        if not plan.bands:
            return job.spliced, None
        half = max(plan.band / 2, 10 * plan.dt)
        fb = bool(job.machine.feedback)
        u, fixed = correct_junctions(
            job.machine, job.spliced, job.y_d, plan.t, plan.bands, half, fb
        )
        return u, (
            f"junction correction: input in {fixed} band sample(s) per axis fitted so the "
            "model follows the path through the junctions"
        )


@dataclass(frozen=True)
class NoCorrection:
    """The spliced pieces as they are."""

    name: str = "none"
    keeps_stored: bool = False

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> None:
        return None

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, None]:
        return job.spliced, None


CORRECTIONS = {
    "error": ErrorCorrection(),
    "input": InputCorrection(),
    "output": OutputCorrection(),
    "junction": JunctionCorrection(),
    "none": NoCorrection(),
}
