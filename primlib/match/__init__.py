"""Matching a new path against stored primitives (primitive-matching paper, §3.1–3.2).

Kabsch RMSD up to a proper rotation and a translation (:func:`kabsch`, batched), a sub-curve
search over every start and duration of every primitive (an arc-length index with provable
pruning, checked against the exhaustive grid), and the paper's binary-search segmentation
(:func:`segment_path` on arrays, :func:`match_path` on a library).

Notation: a piece is K points at uniform time; P the stored piece, Q the new path's;
``Q ≈ P @ R.T + t``; time scale k = stored duration / new duration.
"""

from primlib.match._bank import BankArrays
from primlib.match._kabsch import KabschResult, kabsch, rmsd_from_moments
from primlib.match._search import ArcIndex, SearchOptions
from primlib.match._segment import (
    DEFAULT_EPS,
    default_eps,
    match_path,
    matched_pieces,
    segment_path,
)
from primlib.match._types import Match, Segment

__all__ = [
    "Match",
    "Segment",
    "kabsch",
    "KabschResult",
    "rmsd_from_moments",
    "segment_path",
    "match_path",
    "DEFAULT_EPS",
    "default_eps",
    "matched_pieces",
    "SearchOptions",
    "BankArrays",
    "ArcIndex",
]
