"""Matching a new path against stored primitives (primitive-matching paper, §3.1–3.2).

Kabsch RMSD up to a proper rotation and a translation (:func:`kabsch`, batched), a sub-curve
search over every start and duration of every primitive (an arc-length index with provable
lower-bound pruning, kept on a :class:`BankIndex`), and the paper's binary-search
segmentation (:func:`segment_path` on arrays, :func:`match_path` on a path).

Notation: a piece is K points at uniform time; P the stored piece, Q the new path's;
``Q ≈ P @ R.T + t``; time scale k = stored duration / new duration. ``rotation`` names the
rotation family everywhere: ``"full"`` (SO(d)), ``"z"`` (about the vertical axis), ``"none"``.

Modules: ``_kabsch`` (superposition), ``_bounds`` (lower bounds on prefix sums),
``_arc_index`` (the index), ``_pool`` (candidate pool), ``_smooth`` (the path the index
sees), ``_index_search`` (seeds), ``_grid`` (time-uniform grid for short pieces and fixed
time scales), ``_refine`` (Gauss–Newton), ``_segment`` (binary search), ``_bank``
(:class:`BankIndex`), ``_match_path``.
"""

from primlib.match._bank import BankIndex
from primlib.match._checks import check_path_samples, check_time_scale
from primlib.match._kabsch import KabschResult, kabsch, rmsd_from_moments
from primlib.match._match_path import DEFAULT_EPS, default_eps, match_path, matched_pieces
from primlib.match._options import SearchOptions
from primlib.match._segment import segment_path
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
    "check_path_samples",
    "check_time_scale",
    "SearchOptions",
    "BankIndex",
]
