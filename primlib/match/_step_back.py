"""A start's first match (:meth:`._segment._Segmenter.longest_prefix`): the step back from a
first probe that fails, by halving, until a prefix matches (:func:`first_match`).

From a prefix of L steps that fails, the probes go L/2, L/4, ... down to the shortest of
them that is still ``least`` steps or more (:func:`halving_floor`), each failing search's
refined seeds tried shrunk first. On a path's first start (nothing matched yet) that
shortest probe is made right after the first failure instead of last (issue 13, a noisy
path nothing matches: its first start cost 4-7 whole searches, each failing): when it fails
too, the start is unmatched and the probes between are skipped; when it matches, the halving
goes on as before, and reaching it takes its result, not a new search. So the answer is the
halving's wherever "a prefix matches" is monotone in its length on the probes between; it
differs only where L/2^j matches while the shortest fails (a longer prefix that matches
although its start does not, the non-monotone case the halving itself only finds on its own
probe points). Measured, not proven: no cut or primitive changed on the noisy queries
(matched, unmatched, joined), the novel paths and LASA (``benchmarks/bench_match_noisy.py``,
``bench_match_novel.py``, ``bench_match_real.py``), and the match tests.

The starts after it in an unmatched stretch (the doubling's, :meth:`._segment._Segmenter.run`)
each probe a short piece (the shortest, or as long as the last match), and on such a path most
of those searches fail too (issue 13: a noisy path nothing matches cost 13x a match on the
bundled library, 9 of its 10 searches at these starts, and 2,500x on 1,000 primitives). A
start whose first probe has at most ``K_MAX`` samples, on a path where the median of its
disjoint pieces of that length lies farther than eps (RMS) from their own least-squares
cubics, is unmatched without a search when every prefix the probe could end at (its own
length down to the shortest, where its seeds shrunk would be tried) lies that far from its
own cubic too (:func:`noisy_start`); so is the first start, before its shortest probe out of
turn. The proven bound (:mod:`._rough`) rejects such a piece only where every primitive's
windows are smooth enough, ‖(I − P)q‖ − R_j ≥ eps·√K; this takes R_j as 0: a stored window
would have to be as rough as the path's noise, and in the same way, to match it. Measured,
not proven, as above: on the noisy queries (bundled and 1,000 primitives) no cut or primitive
changed, and paths whose pieces lie within eps of a cubic (clean paths, and noisy ones at an
eps above ~0.7x the noise's RMS) never take this test. (Testing the probe's own piece alone
changed one answer on 1,000 primitives: a first start's 11-step piece was that rough, its
8-step prefix not, and the failed search's seeds shrunk to it matched.)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from primlib.match._rough import K_MAX, block_roughness

if TYPE_CHECKING:
    from primlib.match._segment import _Segmenter

__all__ = ["first_match", "halving_floor", "noisy_start"]


def halving_floor(length: int, sig: int, least: int) -> int | None:
    """The last length the halving from a failing ``length`` searches (None if none): the
    halving goes on from a failure at ℓ only while ℓ > σ and ℓ >= ``least``, to max(σ, ℓ // 2),
    and a probe shorter than ``least`` fails unsearched."""
    seq = [length]
    while seq[-1] > sig and seq[-1] >= least:
        seq.append(max(sig, seq[-1] // 2))
    searched = [ell for ell in seq if ell >= least]
    return searched[-1] if searched else None


def first_match(seg: _Segmenter, ia: int, sig: int, guess: int) -> tuple[Any, ...] | None:
    """Step back from a prefix as long as ``guess`` until one matches: after a whole
    search fails at L, its refined seeds are tried shrunk (at their time scales) to
    where their RMSD predicts eps (a misfit growing like L², 10 % margin) and to L/2,
    before a whole search at L/2; on the path's first start the halving's shortest probe
    first (module notes).

    Returns (match, its end, the shortest failing end (None if none), its RMSD, how it
    failed) or None when nothing of ``least`` steps or more matches."""
    last, a = seg.path.n - 1, seg._t(ia)
    length = min(max(guess, sig), last - ia)
    if seg._screened(ia, length):
        return None
    if seg.missed and length < K_MAX and noisy_start(seg, ia, length):
        seg.noisy_starts += 1
        return None
    first_start = guess == last  # nothing matched nor declared unmatched before (run)
    early: dict[int, tuple[Any, float]] = {}  # the shortest probe, made out of turn, matched
    hi, r_hi = None, np.inf
    found, r = seg.probe(a, seg._t(ia + length))
    while found is None:
        if length <= sig or length < seg.least:
            return None
        hi, r_hi, half = ia + length, r, max(sig, length // 2)
        shrunk = _shrunk(seg, ia, length, r, half)
        if shrunk is not None:
            return shrunk[0], ia + shrunk[1], hi, r_hi, {"probe"}
        if first_start:
            first_start = False
            floor = halving_floor(length, sig, seg.least)
            if floor is not None and floor < half and _rough(seg, ia, floor, length):
                if noisy_start(seg, ia, floor):  # as a later start's
                    seg.noisy_starts += 1
                    return None
                f_found, f_r = seg.probe(a, seg._t(ia + floor))
                if f_found is None:  # the start is unmatched: as the halving ends there
                    shrunk = _shrunk(seg, ia, floor, f_r, max(sig, floor // 2))
                    if shrunk is None:
                        return None
                    return shrunk[0], ia + shrunk[1], ia + floor, f_r, {"probe"}
                early[floor] = (f_found, f_r)
        length = half
        found, r = early.pop(length) if length in early else seg.probe(a, seg._t(ia + length))
    return found, ia + length, hi, r_hi, {"probe"} if hi is not None else set()


def noisy_start(seg: _Segmenter, ia: int, length: int) -> bool:
    """True when the path's pieces of ``length`` steps lie farther than eps (RMS) from their
    own least-squares cubics by the median over its disjoint ones (found once a path and
    length), and every prefix from ia of ``least`` to ``length`` steps does too: none of them
    is then searched, however the probe from ia would have gone on (module notes)."""
    k = length + 1
    if ia + k > seg.path.n:
        return False
    if k not in seg.noisy:
        m = seg.path.n // k
        seg.noisy[k] = _noisier(seg.path.points[: m * k].reshape(m, k, -1), seg.eps)
    pts = seg.path.points
    return seg.noisy[k] and all(
        _noisier(pts[None, ia : ia + ell + 1], seg.eps) for ell in range(seg.least, length + 1)
    )


def _noisier(pieces: np.ndarray, eps: float) -> bool:
    """True when the pieces (m, K, d) lie eps (RMS) or farther from their own least-squares
    cubics, by their median."""
    return float(np.median(block_roughness(pieces))) >= eps * math.sqrt(pieces.shape[1])


def _rough(seg: _Segmenter, ia: int, length: int, span: int) -> bool:
    """True when pieces of ``length`` steps lie farther than eps (RMS) from their own
    least-squares cubics (noise above eps, where such short probes fail), by the median over
    up to 8 disjoint pieces in the ``span`` steps from ia: a probe out of turn on a path
    that matches (its shortest piece too short in arc length for the index) cost 13-36 ms
    of a 60 ms path, and one piece alone is below eps in ~1 of 5 noisy paths."""
    k = length + 1
    m = max(1, min(8, (span + 1) // k))
    return _noisier(seg.path.points[ia : ia + m * k].reshape(m, k, -1), seg.eps)


def _shrunk(seg: _Segmenter, ia: int, length: int, r: float, half: int):
    """After the whole search of ``length`` steps from ia failed (lowest RMSD r), its
    refined seeds tried shrunk to where their RMSD predicts eps and to ``half``: the match
    and its length in steps, or None."""
    a, hi = seg._t(ia), seg._t(ia + length)
    near = int(0.9 * length * math.sqrt(seg.eps / r)) if np.isfinite(r) else 0
    failed = seg.failed
    if failed is None or failed[:2] != (a, hi) or not failed[3]:
        return None
    for at in sorted({min(max(near, half), length - 1), half}, reverse=True):
        if at >= seg.least:
            seg.extensions += 1
            found, _ = seg._stretched(a, hi, seg._t(ia + at), failed[3])
            if found is not None:
                return found, at
    return None
