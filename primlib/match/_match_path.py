"""Matching a path (a :class:`~primlib.nurbs.Trajectory`) against a bank: :func:`match_path`."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from primlib._errors import InputError
from primlib.defaults import BAND_SAMPLES, EPS_FRACTION, MIN_SEGMENT_BANDS
from primlib.match._bank import BankIndex, as_index
from primlib.match._checks import check_path_samples
from primlib.match._interp import cubic_at
from primlib.match._options import SearchOptions
from primlib.match._segment import drop_short, segment_path
from primlib.match._types import Match, Segment

if TYPE_CHECKING:
    from primlib.nurbs import Trajectory
    from primlib.store import Bank

__all__ = ["match_path", "matched_pieces", "default_eps", "DEFAULT_EPS"]

# The default match tolerance relative to the path's extent (kept under this name for the
# callers that import it from here; the value lives in primlib.defaults).
DEFAULT_EPS = EPS_FRACTION


def match_path(
    bank: Bank | BankIndex,
    path: Trajectory,
    eps: float,
    *,
    rotation: str = "full",
    time_scale: tuple[float, float] | None = None,
    min_step: float | None = None,
    min_segment: float | None = None,
    options: SearchOptions | None = None,
    progress: Callable[[int, int, int], None] | None = None,
) -> Match:
    """Match a new path against a machine's primitives.

    Parameters
    ----------
    bank : primlib.store.Bank or BankIndex
        The machine's primitives (``Library.bank(machine)``). Pass a :class:`BankIndex`
        built once to keep its search index across calls.
    path : Trajectory
        The new path; sampled at the bank's dt (uniform in normalised time).
    eps : float
        Kabsch RMSD tolerance (user units), > 0.
    rotation : {"full", "z", "none"}
    time_scale : (float, float), optional
        Allowed primitive duration / segment duration; default
        :data:`primlib.defaults.TIME_SCALE`.
    min_step, options, progress
        As for :func:`segment_path` (``progress(done, total, segments)``: path samples
        covered of the path's, and segments found so far).
    min_segment : float, optional
        Shortest matched segment kept, seconds of the path; a shorter match is not worth a
        junction and becomes part of the unmatched stretch beside it (the warm start fills
        those from the model): no piece of fewer samples than ``min_segment`` / dt (rounded,
        ``min_samples`` of :func:`segment_path`) is probed, and one a step shorter than
        ``min_segment`` is dropped after. Default ``MIN_SEGMENT_BANDS`` transition bands of
        ``BAND_SAMPLES`` machine steps (:mod:`primlib.defaults`); 0 keeps every match.

    Returns
    -------
    Match

    Raises
    ------
    InputError
        eps <= 0, min_segment < 0, a path of another dimension than the machine, a bad
        option, a path that does not move or has values out of range (:func:`check_path_samples`).
    NoMatchError
        No usable primitive in the bank.

    Examples
    --------
    >>> mt = match_path(lib.bank("xyz"), path, eps=0.05)
    >>> mt.segments[0].start, mt.segments[-1].end       # contiguous, covering the whole path
    (0.0, 1.0)
    >>> all(s.rmsd <= 0.05 for s in mt.segments if s.primitive is not None)
    True
    >>> 0.0 <= mt.matched_fraction <= 1.0
    True
    """
    if not (isinstance(eps, int | float) and math.isfinite(eps) and eps > 0):
        raise InputError(f"eps: expected a tolerance > 0, got {eps!r}")
    index = as_index(bank)
    shortest = _shortest(min_segment, index.dt)
    machine = index.machine
    if path.dim != index.dim:
        raise InputError(f"path: expected {index.dim}-D like machine {machine!r}, got {path.dim}-D")
    index.require()
    n = max(int(round(path.duration / index.dt)) + 1, 2)
    points = path.at(np.linspace(0.0, 1.0, n))
    check_path_samples(points, "path")
    dt = path.duration / (n - 1)
    kw = {"time_scale": time_scale, "min_step": min_step, "options": options,
          "min_samples": int(round(shortest / dt))}  # fmt: skip
    segments, info = segment_path(
        index, points, dt, eps, rotation=rotation, progress=progress, **kw
    )
    segments = drop_short(segments, float(shortest) / path.duration, index.dim)
    info["min_segment"] = float(shortest)
    return Match(tuple(segments), machine, float(eps), rotation, path, info)


def _shortest(min_segment: float | None, dt: float) -> float:
    """``min_segment`` checked, or its default (one transition band at the bank's dt)."""
    if min_segment is None:
        return MIN_SEGMENT_BANDS * BAND_SAMPLES * dt
    if not (isinstance(min_segment, int | float) and math.isfinite(min_segment)):
        raise InputError(f"min_segment: expected a duration >= 0 s, got {min_segment!r}")
    if min_segment < 0:
        raise InputError(f"min_segment: expected a duration >= 0 s, got {min_segment!r}")
    return float(min_segment)


def matched_pieces(
    segments: Sequence[Segment], bank: Bank | BankIndex, n: int = 200
) -> list[np.ndarray | None]:
    """Each matched segment's stored piece carried through its transform (for figures).

    Parameters
    ----------
    segments : sequence of Segment
    bank : primlib.store.Bank or BankIndex
        The primitives the segments refer to.
    n : int
        Uniform-time points per piece.

    Returns
    -------
    list of (array, shape (n, d)) or None
        ``rotation @ prim(primitive_start + (primitive_end − primitive_start)·s) +
        translation``; None for unmatched segments.
    """
    index = as_index(bank)
    row = {int(pid): i for i, pid in enumerate(index.ids)}
    out: list[np.ndarray | None] = []
    s = np.linspace(0.0, 1.0, n)
    for seg in segments:
        if seg.primitive is None:
            out.append(None)
            continue
        i = row[int(seg.primitive)]
        n_p = int(index.offsets[i + 1] - index.offsets[i])
        x = (seg.primitive_start + (seg.primitive_end - seg.primitive_start) * s) * (n_p - 1)
        p = cubic_at(index.points, index.offsets[i], n_p, x)
        out.append(p @ np.asarray(seg.rotation).T + np.asarray(seg.translation))
    return out


def default_eps(path: Trajectory | Any) -> float:
    """The default Kabsch RMSD tolerance for ``path``: ``EPS_FRACTION`` times its extent.

    :data:`primlib.defaults.EPS_FRACTION` (the same number as ``DEFAULT_EPS``).

    Parameters
    ----------
    path : Trajectory

    Returns
    -------
    eps : float
        In the path's units (``EPS_FRACTION`` for a path of zero extent).
    """
    return EPS_FRACTION * (path.extent or 1.0)
