"""Stage 4 of the splice: the residual correction, as a small protocol.

Each piece is right for the state its primitive had at the window's start; at a junction the
machine arrives in the state the previous piece left, and an integrating axis keeps any input
error there as a lasting position offset (on the benchmark's true machine the raw splice is
as bad as the nominal-model inverse). The machine is linear, so what the spliced pieces miss
can be added by superposition. A :class:`Correction` says how:

- ``piece_term(machine, piece, n)`` — a per-piece signal it needs (placed on the new grid
  like the piece's input, or None), computed once per piece;
- ``__call__(job)`` — the corrected input and a one-line note, from a :class:`CorrectionJob`
  (the plan, the placed pieces, their terms, the spliced input, and the blend).

primlib ships one: :class:`ErrorCorrection`, ``u0 = G^-1 (y_d - E)``. The library's knowledge
is the model's error on its own pairs, ``e_l = y_l - G u_l`` (stored path minus the model's
output of the stored input, at the stored samples); per piece it is time-scaled and rotated
like the piece (:func:`piece_error`), and its increments, blended over the bands like the
inputs, are summed along the new path into E — increments, because the error a primitive had
accumulated before the window is not on the new path. So the model's error only enters
through the change of e_l under the time scale, and the junctions need nothing special: the
inverse of the whole path is continuous through them. On the nominal machine E = 0 and u0 is
the model inverse of the new path, without the band above ~2/3 of Nyquist where the sampled
model's sampling zeros make an exact inverse ring (:func:`band_limited_inverse`): the model
then follows the path at the samples up to the path's own content in that band. The designs
it was measured against (the blended input or output residual, a least-squares fit near the
junctions, no correction) live in ``benchmarks/_ablations.py`` and are compared by
``benchmarks/bench_warm_start.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from scipy import ndimage

from primlib.defaults import BAND_SAMPLES
from primlib.splice._blend import blend
from primlib.splice._inverse import band_limited_inverse
from primlib.splice._place import PlacedPiece
from primlib.splice._plan import JunctionPlan
from primlib.splice._transform import piece_error

__all__ = ["Correction", "CorrectionJob", "ErrorCorrection"]


@dataclass(frozen=True)
class CorrectionJob:
    """Everything a correction may use.

    Attributes
    ----------
    machine : Machine
        The model in use (refined when refined).
    plan : JunctionPlan
    pieces : tuple of PlacedPiece
    terms : tuple of (array, shape (n, d)) or None
        Per piece, what the correction's ``piece_term`` returned.
    spliced : array, shape (n, d)
        The pieces' inputs blended over the bands.
    """

    machine: object
    plan: JunctionPlan
    pieces: tuple[PlacedPiece, ...]
    terms: tuple
    spliced: np.ndarray

    @property
    def y_d(self) -> np.ndarray:
        return self.plan.y_d

    @property
    def reference(self) -> np.ndarray | None:
        """The PID reference of the new path (feedback machines), else None."""
        return self.plan.y_d if self.machine.feedback else None

    def blend(self, parts: Sequence[np.ndarray]) -> np.ndarray:
        """Per-piece signals blended over the bands like the inputs (:func:`blend`)."""
        return blend(parts, self.plan)


@runtime_checkable
class Correction(Protocol):
    """How the spliced pieces are corrected (see the module docstring).

    Attributes
    ----------
    name : str
        Reported in :attr:`SpliceResult.correction`.
    keeps_stored : bool
        True when a path made of the pieces' own stored paths, sample for sample, gets the
        stored inputs back unchanged (the correction would add nothing but rounding).
    """

    name: str
    keeps_stored: bool

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> np.ndarray | None:
        """A per-piece signal, shape (n, d), on the piece's samples; or None."""
        ...

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, str | None]:
        """The corrected input, shape (n, d), and a note saying what was done (or None)."""
        ...


@dataclass(frozen=True)
class ErrorCorrection:
    """``u0 = L G^-1 (y_d - E)``: E the model's error the pieces' stored pairs measured.

    Per piece the term is the increments of ``piece_error`` (the stored path minus the
    model's output of the stored input, transformed like the piece), zero at the piece's
    first sample; E is their blend summed along the path, smoothed over the band's scale.
    L removes the near-Nyquist band of the sampling zeros (:func:`band_limited_inverse`).
    """

    name: str = "error"
    keeps_stored: bool = True

    def piece_term(self, machine, piece: PlacedPiece, n: int) -> np.ndarray:
        pl = piece.placement
        if pl is None:  # unmatched (or too short): the model knows nothing better there
            return np.zeros((n, machine.dim))
        prim = piece.stored
        err = piece_error(machine, prim.signal, prim.points, **pl.transform_args())
        inc = np.diff(err, axis=0, prepend=err[:1])
        term = pl.put(inc, 0.0, n)
        term[max(pl.lo, pl.first)] = 0.0  # the error accumulated before the window is not ours
        return term

    def error_path(self, job: CorrectionJob) -> np.ndarray:
        """E: the model's error along the new path, estimated from the pieces, (n, d)."""
        dt = job.plan.dt
        err_path = np.cumsum(job.blend(job.terms), axis=0)
        # E switches pieces at the junctions (a kink where a band has no width): an estimate,
        # so smoothed over the band's scale (Gaussian, sigma = max(band, BAND_SAMPLES dt) / 4)
        # — the inverse of a kink is an input impulse that the sampling zero near -1 of the
        # XYZ axes rings out for a second
        sigma = max(job.plan.band, BAND_SAMPLES * dt) / (4 * dt)
        err_path = ndimage.gaussian_filter1d(err_path, sigma, axis=0, mode="nearest")
        return err_path - err_path[0]

    def __call__(self, job: CorrectionJob) -> tuple[np.ndarray, str]:
        # without the sampling zeros' near-Nyquist band: the exact inverse rings there after
        # every acceleration step of the path (each junction of pieces with different
        # curvature), input the machine's samples barely see (issue 12)
        y = job.y_d - self.error_path(job)
        u = band_limited_inverse(job.machine, y, reference=job.reference)
        return u, (
            "model-error correction: the model inverse of the path minus the model's error "
            "the pieces measured (stored path minus model output of the stored input), "
            "accumulated along the path, without the near-Nyquist band of the sampled "
            "model's sampling zeros"
        )
