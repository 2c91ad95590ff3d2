"""Binary-search segmentation (primitive-matching paper, §3.2, Fig. 2) and ``match_path``.

From the current cut a (initially 0) the paper probes the whole remainder first (v̄ = 1,
step b = 1 − a); a probe that matches (some stored piece within ε, Step 2) moves the split
forward by half the step, one that fails moves it back (Steps 3–4), until the step falls
below the minimum σ; the longest matching prefix found becomes a segment (Step 5) and the
search restarts from its end. The paper does not say what happens when nothing matches even
at the minimum step: here the stretch [a, a + σ] becomes an *unmatched* segment
(``primitive = None``; neighbouring unmatched stretches are merged) and the search goes on,
so no part of the path is ever dropped. The split runs on the path's sample grid (σ = one
sample by default; halving with rounding up reaches every sample), so a path made of exact
copies is cut exactly at its joins. When nothing matches from a cut, the unmatched stretch
grows by σ, doubling while the failures go on: a sub-sample sliver left by a join between
samples costs one step, a long stretch nothing matches only log₂ of its length in searches.

Within one binary search, the match found by the last successful probe is tried first on
the next probe (stretched to its length at the same time scale) before searching.

A probe "matches" when some seed (see ``_search``), refined continuously, has Kabsch RMSD
below ε against the piece, compared at the path's own samples in the piece (cuts lie on
samples; 16 points at least) and the primitive at the corresponding uniform times — the RMSD
reported in the segment.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from primlib._errors import InputError, NoMatchError, NotFoundError
from primlib.match._bank import BankArrays, as_bank, cubic_at
from primlib.match._kabsch import ROTATION_MODES
from primlib.match._search import (
    ArcIndex,
    Candidate,
    GridSearch,
    IndexSearch,
    LoopSearch,
    PathPiece,
    SearchOptions,
    clamp,
    piece_rmsd,
    refine,
)
from primlib.match._types import Match, Segment

__all__ = ["segment_path", "match_path", "matched_pieces", "SEARCHES"]

SEARCHES = ("index", "scan", "grid", "loop")

# The arc-length index of the last bank searched, keyed by its arrays' identity, its ids and
# a sample of its rows: the store hands out the same arrays while a machine's primitives are
# unchanged, so a batch of paths (or the benchmark) builds the index once.
_INDEX_CACHE: dict[tuple, ArcIndex] = {}


@dataclass(frozen=True)
class _Found:
    cand: Candidate
    rmsd: float
    refined: bool


def _check_inputs(points: np.ndarray, bank: BankArrays, eps: float, opts: SearchOptions):
    if not (isinstance(eps, int | float) and math.isfinite(eps) and eps > 0):
        raise InputError(f"eps: expected a tolerance > 0, got {eps!r}")
    if opts.mode not in ROTATION_MODES:
        raise InputError(f"rotation: expected one of full, z, none, got {opts.mode!r}")
    lo, hi = opts.time_scale
    if not (0 < lo <= hi and math.isfinite(hi)):
        raise InputError(f"time_scale: expected 0 < low <= high, got ({lo!r}, {hi!r})")
    if points.ndim != 2 or points.shape[0] < 2 or not np.all(np.isfinite(points)):
        raise InputError(f"path: expected finite samples of shape (n >= 2, d), got {points.shape}")
    if points.shape[1] != bank.dim:
        raise InputError(
            f"path: expected {bank.dim}-D points like the machine's primitives, "
            f"got {points.shape[1]}-D"
        )
    if opts.mode == "z" and bank.dim != 3:
        raise InputError(f"rotation: 'z' needs a 3-D machine, got {bank.dim}-D")


def _make_searcher(bank: BankArrays, opts: SearchOptions, search: str):
    if search == "grid":
        return GridSearch(bank, opts)
    if search == "loop":
        return LoopSearch(bank, opts)
    if search not in ("index", "scan"):
        raise InputError(f"search: expected one of index, scan, grid, loop, got {search!r}")
    # ids are never reused by the store; the sampled rows guard arrays built by hand
    stride = max(1, bank.points.shape[0] // 1009)
    key = (
        id(bank.points),
        bank.points.shape,
        bank.offsets.tobytes(),
        np.asarray(bank.ids).tobytes(),
        bank.points[::stride].tobytes(),
    )
    index = _INDEX_CACHE.get(key)
    if index is None:
        index = ArcIndex.build(bank)
        _INDEX_CACHE.clear()
        _INDEX_CACHE[key] = index
    return IndexSearch(bank, opts, index=index, prune=search == "index")


def _try(bank, path, a, b, eps, opts, seed, kc) -> _Found | None:
    seed = clamp(bank, seed, (b - a) * path.duration, opts)
    r0 = piece_rmsd(bank, seed, path, a, b, kc, opts.mode).rmsd
    if r0 < eps:
        return _Found(seed, r0, False)
    ref = refine(bank, seed, path, a, b, opts, target=0.5 * eps)
    r1 = piece_rmsd(bank, ref, path, a, b, kc, opts.mode).rmsd
    if r1 < eps:
        return _Found(ref, r1, True)
    return None


def _probe(searcher, bank, path, a, b, eps, opts, min_samples, hint=None) -> _Found | None:
    """Step 2 of the paper: is there a stored piece within eps of the path piece [a, b]?

    ``hint`` (a match found for [a, b'] in this binary search) is tried first, stretched to
    the new length at the same time scale: a success there is a match like any other; the
    search runs when it fails.
    """
    if (b - a) * (path.n - 1) < min_samples - 1 - 1e-9:
        return None
    kc = path.confirm_points(a, b)
    if hint is not None:
        cand, b_old = hint
        x1 = cand.x0 + (cand.x1 - cand.x0) * (b - a) / (b_old - a)
        found = _try(bank, path, a, b, eps, opts, Candidate(cand.prim, cand.x0, x1, 0.0), kc)
        if found is not None:
            return found
    for seed in searcher.seeds(path, a, b, eps):
        found = _try(bank, path, a, b, eps, opts, seed, kc)
        if found is not None:
            return found
    return None


def _segment_of(bank, path, a, b, found: _Found, opts) -> Segment:
    # the probe stopped at the first candidate within eps; report the refined optimum
    cand, rmsd = found.cand, found.rmsd
    kc = path.confirm_points(a, b)
    ref = refine(bank, cand, path, a, b, opts)
    if piece_rmsd(bank, ref, path, a, b, kc, opts.mode).rmsd < rmsd:
        cand = ref
    res = piece_rmsd(bank, cand, path, a, b, kc, opts.mode)
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


def _unmatched(a: float, b: float, d: int) -> Segment:
    nan = float("nan")
    return Segment(float(a), float(b), None, None, nan, nan, np.eye(d), np.zeros(d), nan, nan)


def segment_path(
    bank: Any,
    points: np.ndarray,
    dt: float,
    eps: float,
    *,
    rotation: str = "full",
    time_scale: tuple[float, float] = (0.25, 4.0),
    min_step: float | None = None,
    search: str = "index",
    options: SearchOptions | None = None,
) -> tuple[list[Segment], dict[str, Any]]:
    """Cut a path into the fewest pieces that each match a stored piece within eps.

    Parameters
    ----------
    bank : BankArrays or the store's Bank
        The machine's primitives on its dt grid (``points``, ``offsets``, ``dt``, ``ids``,
        ``names``).
    points : array, shape (n, d)
        The new path at uniform time steps ``dt`` (normalised time v = i / (n − 1)).
    dt : float
        Sample time of ``points`` (s); the path lasts (n − 1)·dt.
    eps : float
        RMSD tolerance ε (user units), > 0.
    rotation : {"full", "z", "none"}
    time_scale : (float, float)
        Allowed primitive duration / segment duration.
    min_step : float, optional
        Minimum search step σ in normalised path time; default one path sample, so cuts
        land on the sample where a piece stops matching. A stretch nothing matches is
        declared unmatched σ at a time, doubling while nothing matches.
    search : {"index", "scan", "grid", "loop"}
        Seed finder (module notes of ``_search``): "index" the arc-length index with
        provable pruning (fast), "scan" the same windows all scored, "grid" the exhaustive
        time-uniform grid, "loop" the grid's per-candidate Kabsch loop.
    options : SearchOptions, optional
        Further knobs; ``rotation`` and ``time_scale`` override its fields.

    Returns
    -------
    segments : list of Segment
        Contiguous, in path order, covering [0, 1].
    info : dict
        Probe, candidate and timing counts.

    Raises
    ------
    InputError
        eps <= 0, an unknown mode or search, a path of another dimension than the bank.
    NoMatchError
        The bank is empty.
    """
    t_start = time.perf_counter()
    bank = as_bank(bank)
    pts = np.asarray(points, dtype=float)
    base = options or SearchOptions()
    opts = SearchOptions(
        mode=rotation,
        time_scale=(float(time_scale[0]), float(time_scale[1])),
        grid_points=base.grid_points,
        scale_ratio=base.scale_ratio,
        seeds=base.seeds,
        refine_points=base.refine_points,
    )
    _check_inputs(pts, bank, eps, opts)
    n = pts.shape[0]
    if not (isinstance(dt, int | float) and dt > 0):
        raise InputError(f"dt: expected a sample time > 0, got {dt!r}")
    path = PathPiece(pts, (n - 1) * float(dt))
    min_samples = 8
    sigma = 1.0 / (n - 1) if min_step is None else float(min_step)
    if not (0 < sigma <= 1):
        raise InputError(f"min_step: expected a fraction in (0, 1], got {min_step!r}")
    t_index = time.perf_counter()
    searcher = _make_searcher(bank, opts, search)
    t_index = time.perf_counter() - t_index
    segments: list[Segment] = []
    probes = 0
    sig = max(1, int(round(sigma * (n - 1))))  # σ in samples
    last = n - 1
    ia = 0
    advance = sig
    while ia < last:
        # Steps 1-5 on the sample grid: halving with rounding up still reaches every split.
        step = last - ia
        iv = last
        best: tuple[int, _Found] | None = None
        hint = None
        while True:
            probes += 1
            found = _probe(searcher, bank, path, ia / last, iv / last, eps, opts, min_samples, hint)
            if found is not None:
                best = (iv, found)
                hint = (found.cand, iv / last)
                if iv == last:
                    break
            if step <= sig:
                break
            step = (step + 1) // 2
            iv = min(last, iv + step) if found is not None else max(ia + 1, iv - step)
        if best is not None:
            segments.append(_segment_of(bank, path, ia / last, best[0] / last, best[1], opts))
            ia = best[0]
            advance = sig
            continue
        # Nothing matches from ia: declare an unmatched stretch, σ first, doubling while
        # the failures go on (a sub-sample sliver costs one step, a long unmatched stretch
        # only log2 of its length in searches).
        ib = min(last, ia + advance)
        if last - ib < min_samples:
            ib = last  # never leave a sliver too short to match
        if segments and segments[-1].primitive is None:
            segments[-1] = _unmatched(segments[-1].start, ib / last, bank.dim)
        else:
            segments.append(_unmatched(ia / last, ib / last, bank.dim))
        ia = ib
        advance *= 2
    stats = searcher.stats
    info = {
        "search": search,
        "probes": probes,
        "windows": stats.windows,
        "bounded": stats.bounded,
        "scored": stats.scored,
        "queries": stats.queries,
        "index_seconds": t_index,
        "seconds": time.perf_counter() - t_start,
        "min_step": sigma,
    }
    return segments, info


def match_path(
    library: Any,
    path: Any,
    machine: str,
    eps: float,
    rotation: str = "full",
    time_scale: tuple[float, float] = (0.25, 4.0),
    **kw: Any,
) -> Match:
    """Match a new path against a machine's primitives in a library (``Library.match``).

    Parameters
    ----------
    library : primlib.store.Library
    path : Trajectory
        The new path; sampled at the machine's dt (uniform in normalised time).
    machine : str
        Machine name; its primitives are the candidates.
    eps : float
        Kabsch RMSD tolerance (user units), > 0.
    rotation : {"full", "z", "none"}
    time_scale : (float, float)
    **kw
        ``min_step``, ``search``, ``options`` of :func:`segment_path`.

    Returns
    -------
    Match

    Raises
    ------
    InputError
        eps <= 0, a path of another dimension than the machine, a bad option.
    NotFoundError
        An unknown machine.
    NoMatchError
        No primitive stored for the machine.

    Examples
    --------
    >>> mt = lib.match(path, machine="xyz", eps=0.05)
    >>> mt.segments[0].start, mt.segments[-1].end       # contiguous, covering the whole path
    (0.0, 1.0)
    >>> all(s.rmsd <= 0.05 for s in mt.segments if s.primitive is not None)
    True
    """
    if not (isinstance(eps, int | float) and math.isfinite(eps) and eps > 0):
        raise InputError(f"eps: expected a tolerance > 0, got {eps!r}")
    try:
        mach = library.machine(machine)
    except NotFoundError:
        raise
    except LookupError as exc:
        raise NotFoundError(f"machine: no machine named {machine!r} in the library") from exc
    if path.dim != mach.dim:
        raise InputError(f"path: expected {mach.dim}-D like machine {machine!r}, got {path.dim}-D")
    bank = library.bank(machine)
    if len(bank.offsets) < 2:
        raise NoMatchError(f"machine {machine!r}: no primitive stored, nothing to match against")
    n = max(int(round(path.duration / mach.dt)) + 1, 2)
    points = path.at(np.linspace(0.0, 1.0, n))
    segments, info = segment_path(
        bank, points, path.duration / (n - 1), eps, rotation=rotation, time_scale=time_scale, **kw
    )
    return Match(tuple(segments), machine, float(eps), rotation, path, info)


def matched_pieces(segments, bank: Any, n: int = 200) -> list[np.ndarray | None]:
    """Each matched segment's stored piece carried through its transform (for figures).

    Parameters
    ----------
    segments : sequence of Segment
    bank : BankArrays or the store's Bank
        The primitives the segments refer to.
    n : int
        Uniform-time points per piece.

    Returns
    -------
    list of (array, shape (n, d)) or None
        ``rotation @ prim(primitive_start + (primitive_end − primitive_start)·s) +
        translation``; None for unmatched segments.
    """
    bank = as_bank(bank)
    row = {int(pid): i for i, pid in enumerate(bank.ids)}
    out: list[np.ndarray | None] = []
    s = np.linspace(0.0, 1.0, n)
    for seg in segments:
        if seg.primitive is None:
            out.append(None)
            continue
        i = row[int(seg.primitive)]
        n_p = int(bank.offsets[i + 1] - bank.offsets[i])
        x = (seg.primitive_start + (seg.primitive_end - seg.primitive_start) * s) * (n_p - 1)
        p = cubic_at(bank.points, bank.offsets[i], n_p, x)
        out.append(p @ np.asarray(seg.rotation).T + np.asarray(seg.translation))
    return out


# Default match tolerance, relative to the path's extent. One number for `primlib match`, the
# warm start and `primlib learn`: the warm start's first-trial error follows the pieces' shape
# error, so a tight match pays (3e-4 of a 70 mm path is 0.02 mm).
DEFAULT_EPS = 3e-4


def default_eps(path) -> float:
    """The default Kabsch RMSD tolerance for ``path``: ``DEFAULT_EPS`` times its extent.

    Parameters
    ----------
    path : Trajectory

    Returns
    -------
    eps : float
        In the path's units (1 for a path of zero extent).
    """
    return DEFAULT_EPS * (path.extent or 1.0)
