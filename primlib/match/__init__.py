"""Matching a new path against stored primitives (primitive-matching paper, §3.1–3.2).

Kabsch RMSD up to a proper rotation and a translation, a sub-curve search over every start
and duration of every primitive, and the paper's binary-search segmentation.
"""

from primlib.match._types import Match, Segment

__all__ = ["Match", "Segment"]
