"""Binary-search segmentation (primitive-matching paper, §3.2, Fig. 2): :func:`segment_path`.

From the current cut a (initially 0) the paper probes the whole remainder first (v̄ = 1,
step b = 1 − a); a probe that matches (some stored piece within ε, Step 2) moves the split
forward by half the step, one that fails moves it back (Steps 3–4), until the step falls
below the minimum σ; the longest matching prefix found becomes a segment (Step 5) and the
search restarts from its end. The paper does not say what happens when nothing matches even
at the minimum step: here the stretch [a, a + σ] becomes an *unmatched* segment
(``primitive = None``; neighbouring unmatched stretches are merged) and the search goes on,
so no part of the path is ever dropped. The split runs on the path's sample grid (σ = one
sample by default), so a path made of exact copies is cut exactly at its joins. When nothing
matches from a cut, the unmatched stretch grows by σ, doubling while the failures go on: a
sub-sample sliver left by a join between samples costs one step, a long stretch nothing
matches only log₂ of its length in searches.

A minimum segment of m steps (``min_samples`` − 1, default and at least 7: 8 samples) is
the floor of every probe: a segment is the longest matching prefix the search finds among
those of m steps or more. A start where nothing that long matches is unmatched — the first
probe after one is m steps; after a match it is the last length, halved while it fails until
below m — and the stretch then grows as above (σ, doubling), the next start being its end; a
remainder of m steps or less is absorbed. Dropping short matches afterwards
(:func:`drop_short`) leaves the cuts of the rest as found with the floor at 7: a match of
k < m steps, found at two whole searches' cost, is dropped and the next start is its end
(guess k); with the floor at m the next start is the stretch's σ-grown end (one step on),
so a long match that starts inside such a short piece is found, one that starts at its end
may be missed, and the matched fraction and cuts differ. At m = 7 both are today's. With
no short match to reset it, the doubling leaps over most starts of a mostly unmatched path
(rotation none, novel paths, m = 15: 0-8 % matched; the stretch grown by m + 1 at most: 3-25 %).

Where this differs from the paper (for speed; the answer is the same wherever "prefix [a, b]
matches" is monotone in b, and always a prefix that matches followed by one that does not):

* The first probe from a cut is as long as the previous segment (the whole remainder for
  the first cut, the shortest piece after a first cut nothing matched from); while it
  fails, the failing search's seeds are tried shrunk (at their time scales) to where their
  RMSD predicts ε and to half the length, then a whole search at half the length. From the
  first match the split gallops (to where the match's RMSD, growing like L², predicts ε:
  1/8 to 2× longer), then narrows the bracket between the longest prefix that matched and
  the shortest that failed down to σ, placing each split where a power law r ∝ Lᵖ through
  both ends' RMSDs reaches ε (regula falsi in log-log, Illinois-damped; the midpoint while
  an end's RMSD is unknown). On a path the library does not hold, segments are a few dozen
  samples long and the paper's first probes (the remainder, its half, ...) all fail;
  starting from the previous length skips them. The trade-off: a prefix much longer than
  the last one that matched, after a shorter one failed, is not looked for (a non-monotone
  case; the paper's halving finds it only when it lies on its probe points). On the first
  start of a path whose short pieces are noisier than eps, the halving's shortest probe is
  made right after the first failure, and a failure there ends the start
  (:mod:`._step_back`: the same answers wherever the probes between would fail too).
* Inside that search a probe only stretches the match of the longest prefix so far to the
  new length at the same time scale and refines it until it matches or will not
  (:meth:`_Segmenter.extend`, a few Gauss–Newton steps of one candidate, none when the
  stretch already matches): a success is a match like any other; a failure moves the upper
  end but proves nothing, and is followed by the longest prefix the match's own fit keeps
  provably within ε up to there (:meth:`_Segmenter.within`: at a join, the join itself).
  The search stops only when the prefix one step (≤ σ) longer fails both ways — the match
  stretched and the whole search (seeds from :mod:`._index_search`, or on a small bank at a
  fixed time scale from the time-uniform grid, refined) — so a prefix is never cut short
  because the match followed so far left the path while another primitive goes on. On a
  novel path this leaves about two whole searches per segment (the first match, the final
  failure) where the bisection ran about eleven.

A probe "matches" when some candidate, refined continuously (:mod:`._refine`), has Kabsch
RMSD below ε against the piece, compared at the path's own samples in the piece (cuts lie on
samples; a piece is never shorter than 8 samples) and the primitive at the corresponding
uniform times — the RMSD reported in the segment. The segment's primitive is then the
lowest-RMSD one among the match and the seeds of the whole search that failed one step
further (:meth:`_Segmenter.best`; a new search when there was none).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from primlib._errors import InputError
from primlib.match._bank import BankIndex, as_index
from primlib.match._checks import check_path_samples, check_time_scale
from primlib.match._cuts import _gallop, _split, _unmatched, drop_short
from primlib.match._grid import GridSearch
from primlib.match._index_search import GRID_BANK, IndexSearch
from primlib.match._interp import CurveTable
from primlib.match._kabsch import ROTATION_MODES, kabsch
from primlib.match._options import Candidate, PathPiece, SearchOptions, SearchStats
from primlib.match._refine import piece_rmsd, prim_at
from primlib.match._refine_many import refine_many
from primlib.match._reject import rejects
from primlib.match._rough import rough_bounds
from primlib.match._rough_diff import DiffRoughness, diff_scales
from primlib.match._screen import SlopeRanges, prefixes_fail
from primlib.match._step_back import first_match
from primlib.match._types import Segment

if TYPE_CHECKING:
    from primlib.store import Bank

__all__ = ["segment_path", "segment_with", "Seeder", "check_options", "resolve_options",
           "drop_short"]  # fmt: skip

_MIN_SAMPLES = 8  # shortest piece probed, in path samples
_SCREEN_MAX, _SCREEN_BANK = 32, 1 << 16  # screened: first guesses, banks up to (table rows)
_TABLE_ROWS = 1 << 17  # samples of a bank whose curves the refinements tabulate (CurveTable)


class Seeder(Protocol):
    """What the segmentation needs of a search: seeds for a piece, and its counters."""

    stats: SearchStats

    def seeds(self, path: PathPiece, a: float, b: float, eps: float) -> list[Candidate]: ...


@dataclass(frozen=True)
class _Found:
    cand: Candidate
    rmsd: float


def resolve_options(
    rotation: str, time_scale: tuple[float, float] | None, options: SearchOptions | None
) -> SearchOptions:
    """``options`` (default :class:`SearchOptions`) with ``rotation`` and ``time_scale``
    (when given) put in."""
    base = options or SearchOptions()
    ts = base.time_scale if time_scale is None else time_scale
    return replace(base, rotation=rotation, time_scale=(float(ts[0]), float(ts[1])))


def check_options(eps: float, opts: SearchOptions, dim: int) -> None:
    """Raise :class:`InputError` for a bad tolerance, rotation family or time-scale range."""
    if not (isinstance(eps, int | float) and math.isfinite(eps) and eps > 0):
        raise InputError(f"eps: expected a tolerance > 0, got {eps!r}")
    if opts.rotation not in ROTATION_MODES:
        raise InputError(f"rotation: expected one of full, z, none, got {opts.rotation!r}")
    check_time_scale(opts.time_scale)
    if opts.rotation == "z" and dim != 3:
        raise InputError(f"rotation: 'z' needs a 3-D machine, got {dim}-D")


def _check_points(points: np.ndarray, bank: BankIndex) -> None:
    if points.ndim != 2 or points.shape[0] < 2 or not np.all(np.isfinite(points)):
        raise InputError(f"path: expected finite samples of shape (n >= 2, d), got {points.shape}")
    if points.shape[1] != bank.dim:
        raise InputError(
            f"path: expected {bank.dim}-D points like the machine's primitives, "
            f"got {points.shape[1]}-D"
        )
    check_path_samples(points, "path")


class _Segmenter:
    """One segmentation: the path, the bank, the search, and the probes (module notes)."""

    def __init__(self, seeder: Seeder, bank: BankIndex, path: PathPiece, eps: float,
                 opts: SearchOptions, least: int = _MIN_SAMPLES - 1) -> None:  # fmt: skip
        self.seeder = seeder
        self.least = least  # the shortest prefix probed, in path steps (samples − 1)
        self.bank = bank
        self.path = path
        self.eps = eps
        self.opts = opts
        self.probes = 0
        self.extensions = 0
        self.rejected = 0
        self.sig = 1  # the minimum step σ in samples (set by run)
        # the last failing whole search: (a, b, its seeds, them refined, best first)
        self.failed: tuple[float, float, list[Candidate], list[Candidate]] | None = None
        self.slopes, self.missed = None, False  # _screened's tables; the last start failed
        self.noisy: dict[int, bool] = {}  # per piece length, the path's noisier than eps
        self.noisy_starts = 0  # starts left unmatched unsearched as noisy (_step_back)
        self.screen = opts.rotation != "full" and SlopeRanges.rows(bank) <= _SCREEN_BANK
        # the refinements' curves from a table (CurveTable) on banks up to _TABLE_ROWS samples
        # (on 1,000 of 2,000: 180 MB more, a build per curve refined, more time than saved)
        small = bank.points.shape[0] <= _TABLE_ROWS
        self.table = CurveTable(bank.points, bank.offsets) if small else None

    def _try(self, a: float, b: float, seeds: list[Candidate], kc: int, q=None):
        """A seed within eps of [a, b] as it comes or once refined (or None), and every
        seed refined, with its RMSD (those of a primitive too short for the time-scale range
        left out: :func:`._refine_many.refine_many` clamps the others into it).

        The seeds are refined together (:func:`._refine_many.refine_many`) on the check's own
        kc points until one is below eps (a match; one that matches as it comes stops them
        before any step), giving up on those that will not be.
        """
        bank, path, opts, eps = self.bank, self.path, self.opts, self.eps
        # converged to 1e-4 of the cost: the RMSD only places the next split
        refined, r = refine_many(bank, seeds, path, a, b, opts, target=eps * (1 - 1e-9),
                                 give_up=eps, first=True, points=kc, rtol=1e-4,
                                 samples=q, table=self.table)  # fmt: skip
        refined, r = _fitting(refined, r)
        hit = np.flatnonzero(r < eps)
        found = _Found(refined[hit[0]], float(r[hit[0]])) if hit.size else None
        return found, refined, r

    def probe(self, a: float, b: float) -> tuple[_Found | None, float]:
        """Step 2 of the paper: is there a stored piece within eps of the path piece [a, b]?

        The whole search: an up-front rejection (:mod:`._reject`), then the seeds (:meth:`_staged`).
        Returns the match (or None) and the lowest RMSD a seed reached (inf if none tried)."""
        self.probes += 1
        if (b - a) * (self.path.n - 1) < self.least - 1e-9:
            return None, np.inf
        steps = (b - a) * self.path.duration / self.bank.dt
        env, low = self.bank.envelope(), self.opts.time_scale[0]
        if low * steps * (1.0 - 1e-9) > env.last.max():
            # longer than any primitive allows at the lowest time scale: rejected before
            # the piece is sampled, so the first probes of a long path cost nothing
            self.rejected += 1
            return None, np.inf
        kc = self.path.confirm_points(a, b)
        q = self.path.at(np.linspace(a, b, kc))
        table, ts = self.bank.roughness(), self.opts.time_scale
        large = isinstance(table, DiffRoughness)  # R_j from the differences, no tight table
        if large:
            sc = diff_scales(table, q, steps, ts, self.eps)
            # a primitive with no time scale left: none of its windows within eps
            rough = None if sc is None else np.where(sc[2] > sc[3], np.inf, 0.0)
        else:
            rough = rough_bounds(table, q, steps, ts, self.eps)
        if rejects(env, q, steps, low, self.opts.rotation, self.eps, rough) or (
            # a shortest probe also by the tighter R_j (._rough_tight): its failure is all the
            # segmentation takes from it (none of its seeds is shrunk below the minimum, nor
            # kept for a later start), so rejected or searched, the answer is the same
            rough is not None and not large and kc - 1 == self.least
            and rejects(env, q, steps, low, self.opts.rotation, self.eps,
                        rough_bounds(table, q, steps, ts, self.eps, tight=True))
        ):  # fmt: skip
            self.rejected += 1  # no primitive can be within eps: the exact check would say so
            return None, np.inf
        found, seeds, refined, r = self._staged(a, b, kc, q)
        if found is None:
            self.failed = (a, b, seeds, [refined[i] for i in np.argsort(r, kind="stable")])
        return found, float(r.min(initial=np.inf))

    def _staged(self, a: float, b: float, kc: int, q: np.ndarray):
        """:meth:`_try` on the seeds for [a, b], then on the seeder's ``more_seeds`` if those
        give no match (the grid's of a loose piece, :mod:`._index_search`): the match or
        None, every seed tried, them refined and their RMSDs."""
        sd, piece = self.seeder, (self.path, a, b, self.eps)
        staged = hasattr(sd, "more_seeds")
        seeds = sd.first_seeds(*piece) if staged else sd.seeds(*piece)
        found, refined, r = self._try(a, b, seeds, kc, q)  # q: the samples rejects had
        more = sd.more_seeds(*piece) if staged and found is None else []
        if more:
            found, refined_more, r_more = self._try(a, b, more, kc, q)
            seeds, refined, r = seeds + more, refined + refined_more, np.concatenate([r, r_more])
        return found, seeds, refined, r

    def _stretched(self, a: float, b_old: float, b: float, cands: list[Candidate]):
        """Candidates for [a, b_old] stretched to [a, b] at their time scales, tried."""
        k = (b - a) / (b_old - a)
        cands = [Candidate(c.prim, c.x0, c.x0 + k * (c.x1 - c.x0), 0.0) for c in cands]
        found, _, r = self._try(a, b, cands, self.path.confirm_points(a, b))
        return found, float(r.min(initial=np.inf))

    def extend(self, a: float, b_old: float, b: float, found: _Found):
        """The match ``found`` of [a, b_old] stretched to [a, b] at the same time scale and
        refined until it is a match or will not become one (a success is a match like any
        other, taken as soon as it is one: on a long piece most stretches already are; a
        failure proves nothing), and the RMSD it reached (which places the next split)."""
        self.extensions += 1
        return self._stretched(a, b_old, b, [found.cand])

    def within(self, ia: int, lo: int, hi: int, found: _Found) -> tuple[int, _Found] | None:
        """After the match of [ia, lo] failed stretched to hi, the longest prefix between
        that it provably keeps within eps, tried (so a match like any other), or None.

        The match's rotation and translation fitted on [ia, lo], kept, carry the stretched
        piece onto every path sample up to hi: the residuals e_j bound every prefix's RMSD,
        (Σ_{j<n} |e_j|² − |Σ_{j<n} e_j|²/n)/n for n samples (the translation re-fitted; a
        refit of the rest only lowers it). Past a join they grow from one sample to the
        next: the bracket closes there in one step where the power-law splits crept on.
        """
        c, bank = found.cand, self.bank
        n_p = int(bank.offsets[c.prim + 1] - bank.offsets[c.prim])
        per = (c.x1 - c.x0) / (lo - ia)  # stored samples per path sample
        top = min(hi - 1, ia + int((n_p - 1 - c.x0) / per))  # the piece stays in its primitive
        if top <= lo:
            return None
        x = c.x0 + per * np.arange(top - ia + 1)
        p = prim_at(bank, c.prim, x)
        q = self.path.points[ia : top + 1]
        fit = kabsch(p[: lo - ia + 1], q[: lo - ia + 1], rotation=self.opts.rotation)
        res = q - p @ np.asarray(fit.rotation).T - fit.translation
        e2 = np.cumsum(np.einsum("kd,kd->k", res, res))
        es = np.cumsum(res, axis=0)
        n = np.arange(1, res.shape[0] + 1)
        r2 = (e2 - np.einsum("kd,kd->k", es, es) / n) / n
        ok = np.flatnonzero(r2[lo - ia + 1 :] < (0.999 * self.eps) ** 2)
        if ok.size == 0:
            return None
        at = lo + 1 + int(ok[-1])  # end sample of the longest such prefix
        a, b = self._t(ia), self._t(at)
        short = Candidate(c.prim, c.x0, c.x0 + per * (at - ia), 0.0)
        self.extensions += 1
        near, _, _ = self._try(a, b, [short], self.path.confirm_points(a, b))
        return None if near is None else (at, near)

    def _screened(self, ia: int, length: int) -> bool:
        """True when every prefix from ia of ``least`` to ``length`` steps provably
        fails (:func:`._screen.prefixes_fail`; tried in unmatched stretches, where it holds)."""
        if not (self.screen and self.missed) or length > _SCREEN_MAX:
            return False
        self.slopes = self.slopes or SlopeRanges(self.bank.points, self.bank.offsets)
        ends = [self._t(ia + ell) for ell in range(length, self.least - 1, -1)]
        a, opts = self._t(ia), self.opts  # the longest prefix first: it fails most
        if not prefixes_fail(self.slopes, self.path, a, ends, self.bank.dt, opts, self.eps):
            return False
        self.rejected += 1
        return True

    def longest_prefix(self, ia: int, sig: int, guess: int) -> tuple[int, _Found] | None:
        """The longest matching prefix from sample ia (module notes): its end sample and
        match, or None when no prefix of ``least`` steps or more matches."""
        last, a = self.path.n - 1, self._t(ia)
        first = first_match(self, ia, sig, guess)
        if first is None:
            return None
        found, lo, hi, r_hi, tried = first
        r_lo = np.nan  # a first match's RMSD is only below eps, not its optimum: bisect once
        while True:
            side = 0  # which end the last extension moved: +1 lo, -1 hi
            while lo < last and (hi is None or hi - lo > sig):
                if hi is None:
                    r = found.rmsd if np.isnan(r_lo) else r_lo  # an upper bound will do
                    iv = min(last, ia + max(lo - ia + sig, _gallop(lo - ia, r, self.eps)))
                else:
                    iv = _split(lo - ia, hi - ia, r_lo, r_hi, self.eps) + ia
                ext, r = self.extend(a, self._t(lo), self._t(iv), found)
                if ext is None:
                    hi, tried, r_hi = iv, {"extend"}, r
                    if side < 0:
                        r_lo = 0.5 * (r_lo + self.eps)  # Illinois: the stuck end counts half
                    side = -1
                    near = self.within(ia, lo, hi, found)
                    if near is not None:
                        lo, found, r_lo, side = near[0], near[1], near[1].rmsd, 0
                else:
                    lo, found, r_lo = iv, ext, ext.rmsd
                    if side > 0:
                        r_hi = 0.5 * (r_hi + self.eps)
                    side = 1
            if lo == last:
                return lo, found
            # hi - lo <= sig: stop only when neither the match stretched nor the whole search
            # (neither finds all the other does) matches at hi
            ext = None
            if "extend" not in tried:
                ext, _ = self.extend(a, self._t(lo), self._t(hi), found)
            if ext is None and "probe" not in tried:
                ext, _ = self.probe(a, self._t(hi))
            if ext is None:
                return lo, found
            lo, found, hi, r_lo, r_hi = hi, ext, None, np.nan, np.inf

    def best(self, a: float, b: float, found: _Found) -> Candidate:
        """The lowest-RMSD match of [a, b] among the probe's match and the search's seeds,
        each at its refined optimum (or as it came, when that is lower): the longest prefix
        is the binary search's, the primitive the best that matches it.

        The seeds are those of the whole search that failed one step (≤ σ) further from the
        same start, shrunk to [a, b] at their time scale, when the search stopped on one
        (the index's candidates for a piece one sample longer); a seed whose refinement
        will not end below the match's RMSD is given up.
        """
        bank, path, opts = self.bank, self.path, self.opts
        cands = [found.cand, *self._seeds_near(a, b)]
        kc = path.confirm_points(a, b)
        # a refinement only takes steps that lower the cost (on the check's kc points); to
        # 1e-4 of the cost, as the probes: the last 1e-8 took a third of the steps and only
        # moved RMSDs in their 6th digit (a primitive too short for the time-scale range
        # comes back at inf: never the lowest, the match being finite)
        refined, r = refine_many(bank, cands, path, a, b, opts, give_up=found.rmsd, points=kc,
                                 rtol=1e-4, table=self.table)  # fmt: skip
        return refined[int(np.argmin(r))]

    def _t(self, i: int) -> float:
        """Sample i's normalised time i / (n − 1), one float per sample everywhere (the
        probes' i·(1/(n − 1)) differed in the last bit and a start compared by == missed)."""
        return i / (self.path.n - 1)

    def _seeds_near(self, a: float, b: float) -> list[Candidate]:
        """Seeds for [a, b]: the last failing whole search's when it started at a and ended
        at most σ after b (shrunk to [a, b]), else a new search."""
        if self.failed is not None:
            fa, fb, seeds, _ = self.failed
            if fa == a and 0 < (fb - b) * (self.path.n - 1) <= self.sig + 1e-6:
                k = (b - a) / (fb - a)
                return [Candidate(c.prim, c.x0, c.x0 + k * (c.x1 - c.x0), c.score) for c in seeds]
        return self.seeder.seeds(self.path, a, b, self.eps)

    def segment(self, a: float, b: float, found: _Found) -> Segment:
        """The segment [a, b] of a probe's match (:meth:`best`)."""
        bank, path, opts = self.bank, self.path, self.opts
        cand = self.best(a, b, found)
        kc = path.confirm_points(a, b)
        res = piece_rmsd(bank, cand, path, a, b, kc, opts.rotation)
        n_p = bank.offsets[cand.prim + 1] - bank.offsets[cand.prim]
        return Segment(
            start=float(a),
            end=float(b),
            primitive=int(bank.ids[cand.prim]),
            primitive_name=bank.names[cand.prim],
            primitive_start=float(cand.x0 / (n_p - 1)),
            primitive_end=float(cand.x1 / (n_p - 1)),
            rotation=np.asarray(res.rotation),
            translation=np.asarray(res.translation),
            time_scale=float((cand.x1 - cand.x0) * bank.dt / ((b - a) * path.duration)),
            rmsd=float(res.rmsd),
        )

    def run(self, sig: int, progress=None) -> list[Segment]:
        """The whole path, cut by cut; unmatched stretches grow σ first, doubling while the
        failures go on (a sub-sample sliver costs one step, a long unmatched stretch only
        log₂ of its length in searches)."""
        self.sig = sig
        last = self.path.n - 1
        d = self.bank.dim
        segments: list[Segment] = []
        ia = 0
        advance = sig
        guess = last
        while ia < last:
            best = self.longest_prefix(ia, sig, guess)
            self.missed = best is None
            if best is not None:
                segments.append(self.segment(self._t(ia), self._t(best[0]), best[1]))
                guess = best[0] - ia
                ia = best[0]
                advance = sig
                if progress is not None:
                    progress(ia, last, len(segments))
                continue
            ib = min(last, ia + advance)
            if last - ib <= self.least:
                ib = last  # never leave a sliver too short to match
            if segments and segments[-1].primitive is None:
                segments[-1] = _unmatched(segments[-1].start, self._t(ib), d)
            else:
                segments.append(_unmatched(self._t(ia), self._t(ib), d))
            ia = ib
            advance *= 2
            if guess == last:
                # nothing matched yet, not even the shortest piece: the next start's first
                # probe is the shortest piece (a match there gallops up through extensions)
                guess = self.least
            if progress is not None:
                progress(ia, last, len(segments))
        return segments


def _fitting(refined: list[Candidate], r: np.ndarray) -> tuple[list[Candidate], np.ndarray]:
    """The refined seeds and RMSDs of :func:`._refine_many.refine_many` without those of a
    primitive too short for the time-scale range (RMSD inf, left as they came): not matches,
    nor worth shrinking later (every refined seed's RMSD is finite)."""
    keep = np.flatnonzero(np.isfinite(r))
    if keep.size == r.size:
        return refined, r
    return [refined[i] for i in keep], r[keep]


def segment_with(
    seeder: Seeder,
    bank: BankIndex,
    points: np.ndarray,
    dt: float,
    eps: float,
    opts: SearchOptions,
    min_step: float | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    min_samples: int | None = None,
) -> tuple[list[Segment], dict[str, Any]]:
    """:func:`segment_path` with a given seed finder (the index search, or a reference)."""
    t_start = time.perf_counter()
    pts = np.asarray(points, dtype=float)
    check_options(eps, opts, bank.dim)
    _check_points(pts, bank)
    n = pts.shape[0]
    if not (isinstance(dt, int | float) and dt > 0):
        raise InputError(f"dt: expected a sample time > 0, got {dt!r}")
    sigma = 1.0 / (n - 1) if min_step is None else float(min_step)
    if not (0 < sigma <= 1):
        raise InputError(f"min_step: expected a fraction in (0, 1], got {min_step!r}")
    least = _least(min_samples)
    bank.require()
    built = bank.index_seconds
    seg = _Segmenter(seeder, bank, PathPiece(pts, (n - 1) * float(dt)), eps, opts, least)
    segments = seg.run(max(1, int(round(sigma * (n - 1)))), progress)
    stats = seeder.stats
    info = {
        "search": getattr(seeder, "name", "index"),
        "probes": seg.probes,
        "extensions": seg.extensions,
        "rejected": seg.rejected,
        "noisy_starts": seg.noisy_starts,
        "windows": stats.windows,
        "bounded": stats.bounded,
        "scored": stats.scored,
        "queries": stats.queries,
        "index_seconds": bank.index_seconds if built == 0.0 else 0.0,
        "seconds": time.perf_counter() - t_start,
        "min_step": sigma,
        "skipped": len(bank.skipped),
    }
    return segments, info


def _least(min_samples: int | None) -> int:
    """The shortest prefix probed, in path steps: ``min_samples`` − 1 checked, at least
    ``_MIN_SAMPLES`` − 1 (today's shortest probe when None)."""
    if min_samples is None:
        return _MIN_SAMPLES - 1
    if isinstance(min_samples, bool) or not isinstance(min_samples, int | np.integer):
        raise InputError(f"min_samples: expected a whole number of samples, got {min_samples!r}")
    if min_samples < 0:
        raise InputError(f"min_samples: expected a number of samples >= 0, got {min_samples!r}")
    return max(_MIN_SAMPLES, int(min_samples)) - 1


def segment_path(
    bank: Bank | BankIndex,
    points: np.ndarray,
    dt: float,
    eps: float,
    *,
    rotation: str = "full",
    time_scale: tuple[float, float] | None = None,
    min_step: float | None = None,
    options: SearchOptions | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    min_samples: int | None = None,
) -> tuple[list[Segment], dict[str, Any]]:
    """Cut a path into the fewest pieces that each match a stored piece within eps.

    Parameters
    ----------
    bank : primlib.store.Bank or BankIndex
        The machine's primitives on its dt grid; pass a :class:`BankIndex` to reuse its
        index across calls.
    points : array, shape (n, d)
        The new path at uniform time steps ``dt`` (normalised time v = i / (n − 1)).
    dt : float
        Sample time of ``points`` (s); the path lasts (n − 1)·dt.
    eps : float
        RMSD tolerance ε (user units), > 0.
    rotation : {"full", "z", "none"}
        Rotations allowed (overrides ``options.rotation``).
    time_scale : (float, float), optional
        Allowed primitive duration / segment duration; default ``options.time_scale``
        (:data:`primlib.defaults.TIME_SCALE`).
    min_step : float, optional
        Minimum search step σ in normalised path time; default one path sample, so cuts
        land on the sample where a piece stops matching. A stretch nothing matches is
        declared unmatched σ at a time, doubling while nothing matches.
    options : SearchOptions, optional
        Further knobs of the search.
    progress : callable, optional
        ``progress(done, total, segments)`` after each cut: path samples covered so far,
        of ``total = n − 1``, and the segments found so far (matched or not).
    min_samples : int, optional
        Shortest matched segment, in path samples (``min_samples`` − 1 steps): no shorter
        prefix is probed, and a start from which none of that length matches begins an
        unmatched stretch (module notes). Default and at least ``_MIN_SAMPLES`` (8), the
        shortest piece probed at all.

    Returns
    -------
    segments : list of Segment
        Contiguous, in path order, covering [0, 1].
    info : dict
        Probe, candidate and timing counts; ``skipped`` primitives of the bank.

    Raises
    ------
    InputError
        eps <= 0, an unknown rotation, a path of another dimension than the bank, a
        ``min_samples`` that is not a whole number >= 0.
    NoMatchError
        The bank holds no usable primitive.
    """
    index = as_index(bank)
    opts = resolve_options(rotation, time_scale, options)
    seeder = seeder_for(index, opts)
    return segment_with(seeder, index, points, dt, eps, opts, min_step, progress, min_samples)


def seeder_for(index: BankIndex, opts: SearchOptions) -> Seeder:
    """The arc-length index, or at a fixed time scale on a bank of up to ``GRID_BANK`` samples
    the exhaustive grid at that scale (1-1, novel paths, CPU s, index / grid: 7,834 samples 1.5-2
    / 1.0-1.2; 25, 100, 1,000 primitives 3.4-4 / 3.8-5.2, 5.4-6.3 / 10-12, 3.4-4.9 / 44-60)."""
    lo, hi = opts.time_scale
    if lo == hi and index.points.shape[0] <= GRID_BANK:
        return GridSearch(index, opts)
    return IndexSearch(index, opts)
