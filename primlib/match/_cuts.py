"""The segmentation's step rules and its unmatched stretches (:mod:`._segment`): where the
next split goes between a match and a failure (:func:`_split`), how far a match gallops
(:func:`_gallop`), and the unmatched segments (:func:`drop_short`)."""

from __future__ import annotations

import math

import numpy as np

from primlib.match._types import Segment

__all__ = ["drop_short"]


def _split(lo: int, hi: int, r_lo: float, r_hi: float, eps: float) -> int:
    """Where the RMSD reaches eps between a match of lo samples (RMSD r_lo < eps, nan when
    only known to be below eps) and a failure of hi (r_hi), strictly between: a power law
    r ∝ Lᵖ through both (regula falsi in log-log: a piece's misfit grows like a power of its
    length), through the failure alone with p = 2 (a curvature mismatch) when r_lo is
    unknown; the midpoint when r_hi is unknown too."""
    if not (np.isfinite(r_hi) and r_hi > eps):
        return (lo + hi + 1) // 2
    if 0 < r_lo < eps:
        at = lo * (hi / lo) ** (math.log(eps / r_lo) / math.log(r_hi / r_lo))
    else:
        at = hi * math.sqrt(eps / r_hi)
    return min(hi - 1, max(lo + 1, int(round(at))))


def _gallop(lo: int, r_lo: float, eps: float) -> int:
    """The next prefix length to try after a match of lo samples at RMSD r_lo: where r ∝ L²
    reaches eps, with a 10 % margin, from 1/8 longer to twice as long."""
    grow = 1.1 * math.sqrt(eps / r_lo) if 0 < r_lo < eps else 2.0
    return int(math.ceil(lo * min(2.0, max(1.125, grow))))


def _unmatched(a: float, b: float, d: int) -> Segment:
    nan = float("nan")
    return Segment(float(a), float(b), None, None, nan, nan, np.eye(d), np.zeros(d), nan, nan)


def drop_short(segments: list[Segment], shortest: float, d: int) -> list[Segment]:
    """Matched segments shorter than ``shortest`` (normalised time) made unmatched, merged
    with the unmatched stretches beside them; the cuts of the others stay where they are."""
    out: list[Segment] = []
    for s in segments:
        if s.primitive is not None and s.end - s.start < shortest * (1.0 - 1e-9):
            s = _unmatched(s.start, s.end, d)
        if s.primitive is None and out and out[-1].primitive is None:
            s = _unmatched(out[-1].start, s.end, d)
            out.pop()
        out.append(s)
    return out
