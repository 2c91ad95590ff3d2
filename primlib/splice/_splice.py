"""Splicing transformed pieces into one first-iteration input (primitive-matching paper §3.3.3).

Four stages, each its own module:

1. plan the junctions (:func:`plan_junctions`): check the segments, join one primitive's
   consecutive windows, absorb unmatched slivers, and set each transition band from the
   paper's junction cases (overlap / gap / continuous);
2. place each piece (:func:`place_piece`): the stored input transformed (time scale,
   rotation, holding input) from the primitive's rest onto the new grid and cut to its
   samples; an unmatched segment gets the model inverse of the path there;
3. blend (:func:`blend`): linear interpolation across the bands (the paper's bumpless switch);
4. correct (:class:`Correction`, default :class:`ErrorCorrection`): the residual correction
   by superposition, ``u0 = G^-1 (y_d - E)``.

Where every piece is its stored signal unchanged and their stored paths are the new path
sample for sample, the stored inputs are returned as they are (a stored primitive's warm
start is its stored signal).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from primlib._errors import InputError
from primlib.plant import invert
from primlib.splice._blend import blend
from primlib.splice._correct import Correction, CorrectionJob, ErrorCorrection
from primlib.splice._place import METHODS, PlacedPiece, place_piece, place_unmatched
from primlib.splice._plan import JunctionPlan, StoredSignal, plan_junctions
from primlib.splice._transform import derivative_orders

__all__ = ["SpliceResult", "splice"]


@dataclass(frozen=True)
class SpliceResult:
    """The spliced input and how each part of it was made.

    Attributes
    ----------
    u : array, shape (n, d)
    bands : tuple of Band
    sample_segment : array of int, shape (n,)
        Index of the segment each sample belongs to (bands blend it with a neighbour).
    sources : tuple of str
        One line per segment saying where its input came from.
    methods : tuple of str
        Per segment: ``"identity"``, ``"model"``, ``"direct"`` or ``"inverse"``.
    notes : tuple of str
    spliced : array, shape (n, d) or None
        The pieces' inputs joined over the bands, before the residual correction.
    correction : str
        The name of the correction applied (see :func:`splice`).
    segments : tuple of Segment
        The segments as planned (one primitive's consecutive windows joined, slivers
        absorbed): what ``sample_segment``, ``sources`` and ``methods`` index.
    """

    u: np.ndarray
    bands: tuple
    sample_segment: np.ndarray
    sources: tuple[str, ...]
    methods: tuple[str, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    spliced: np.ndarray | None = None
    correction: str = "none"
    segments: tuple = ()


def _place_all(machine, plan: JunctionPlan, stored, method, inverse_machine) -> list:
    orders = derivative_orders(machine)
    inverse = None
    pieces: list[PlacedPiece] = []
    for j, seg in enumerate(plan.segments):
        if seg.primitive is not None:
            pieces.append(place_piece(machine, plan, j, stored[seg.primitive], method, orders))
            continue
        if inverse is None:  # once over the whole path, so its state is right at the window
            inv_m = machine if inverse_machine is None else inverse_machine
            ref = plan.y_d if machine.feedback else None
            inverse = invert(inv_m, plan.y_d, reference=ref)
        pieces.append(place_unmatched(plan, j, inverse))
    return pieces


def _correct(machine, plan: JunctionPlan, pieces, u_s, correction) -> tuple[np.ndarray, list]:
    """Stage 4: the correction, or the stored inputs as they are where they are the answer."""
    if (
        correction.keeps_stored
        and all(p.method == "identity" for p in pieces)
        and float(np.max(np.abs(plan.y_d - blend([p.path for p in pieces], plan))))
        <= 1e-12 * plan.extent
    ):
        # the path is the pieces' own stored paths, sample for sample: their stored inputs
        # are the library's answer as they are (no correction to add, not even rounding)
        return u_s, ["the path is made of the pieces' own stored paths: stored inputs as is"]
    terms = tuple(correction.piece_term(machine, p, plan.n) for p in pieces)
    u, note = correction(CorrectionJob(machine, plan, tuple(pieces), terms, u_s))
    return u, [] if note is None else [note]


def splice(
    machine,
    points,
    duration: float,
    segments: Sequence,
    stored: Mapping[int, StoredSignal],
    *,
    band: float | None = None,
    method: str = "auto",
    inverse_machine=None,
    absorb: float | None = None,
    correction: Correction | None = None,
) -> SpliceResult:
    """First-iteration input of a new path from its matched segments.

    Parameters
    ----------
    machine : Machine
        Model of the machine the signals were learned for (refined when refined).
    points : array, shape (n, d)
        The new path on the machine's grid t = 0, dt, ..., n = round(duration / dt) + 1.
    duration : float
        The new path's duration, seconds.
    segments : sequence of Segment
        In path order, contiguous from 0 to 1 (a :class:`primlib.match.Match`'s segments).
    stored : mapping primitive id -> StoredSignal
        Every matched primitive's stored signal and points.
    band : float, optional
        Transition band width in seconds (default ``BAND_SAMPLES`` dt from
        :mod:`primlib.defaults`); 0 switches abruptly.
    method : {"auto", "model", "direct"}
        Time scaling: model-based (one version, the model's filter G(s/k)/G(s)),
        model-free eq. (20) (needs ``versions``), or "auto": eq. (20) when the primitive
        is stored at as many distinct durations as the model has derivative orders
        (:func:`derivative_orders`) and the piece is time-scaled (k != 1), else
        model-based. A piece with k = 1 on the grid needs no time scaling at all.
    inverse_machine : Machine, optional
        Model whose inverse fills unmatched segments (default ``machine``).
    absorb : float, optional
        Unmatched segments at most this long (seconds, default 5 dt) next to a matched one
        are covered by extending that piece (its primitive goes on there, or its last input
        is held): the matcher's last search step can leave such slivers, and the inverse of
        a few samples would only add a junction.
    correction : Correction, optional
        The residual correction (default :class:`ErrorCorrection`: ``G^-1 (y_d - E)``, E
        the model's error measured on the pieces' stored pairs, transformed like them and
        accumulated along the path).

    Returns
    -------
    SpliceResult

    Raises
    ------
    InputError
        For a bad shape, non-contiguous segments, an unknown method, a negative band or a
        correction that is not a :class:`Correction`.

    Examples
    --------
    A path that is a stored primitive gets the primitive's stored input back as it is:

    >>> from primlib.match import Segment
    >>> stored = {1: StoredSignal(u, reference, 1.0, "demo")}
    >>> seg = Segment(0, 1, 1, "demo", 0.0, 1.0, np.eye(3), np.zeros(3), 1.0, 0.0)
    >>> res = splice(m, reference, 1.0, [seg], stored)
    >>> bool(np.array_equal(res.u, u)), res.methods
    (True, ('identity',))
    """
    correction = _checked(method, correction)
    plan = plan_junctions(machine, points, duration, segments, stored, band=band, absorb=absorb)
    pieces = _place_all(machine, plan, stored, method, inverse_machine)
    u_s = blend([p.u for p in pieces], plan)
    u, note = _correct(machine, plan, pieces, u_s, correction)
    return _result(plan, pieces, u, u_s, note, correction.name)


def _checked(method: str, correction) -> Correction:
    """The method checked, the correction checked or the default."""
    if method not in METHODS:
        raise InputError(f"method: expected one of {', '.join(METHODS)}, got {method!r}")
    correction = ErrorCorrection() if correction is None else correction
    if not isinstance(correction, Correction):
        raise InputError(
            f"correction: expected a Correction (name, keeps_stored, piece_term, __call__), "
            f"got {type(correction).__name__}"
        )
    return correction


def _result(plan: JunctionPlan, pieces, u, u_s, more: list, name: str) -> SpliceResult:
    notes = list(plan.notes)
    for p in pieces:
        notes.extend(p.notes)
    notes.extend(more)
    unmatched = sum(p.method == "inverse" for p in pieces)
    if unmatched:
        notes.append(f"{unmatched} unmatched segment(s) filled with the nominal-model inverse")
    return SpliceResult(
        u=u,
        bands=plan.bands,
        sample_segment=plan.sample_segment,
        sources=tuple(p.source for p in pieces),
        methods=tuple(p.method for p in pieces),
        notes=tuple(notes),
        spliced=u_s,
        correction=name,
        segments=tuple(plan.segments),
    )
