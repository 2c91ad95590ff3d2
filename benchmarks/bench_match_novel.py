"""Benchmark of matching paths the library does not hold (issue 13): smooth random 3-D paths
(clamped cubic B-splines through a random walk of control points, ~one per second) against
the 14 bundled primitives (and, with ``--big``, 1,000 random primitives), with the default
search, ``rotation="none"`` and ``time_scale=(1, 1)``.

Each case is timed as a first call (a fresh ``BankIndex``: the arc-length index is built
inside the call; with ``--warm`` the second call on one index, which keeps it and the grid's
tables) on ``--paths`` paths: median and worst, segments, fraction matched. The
baseline is the same measurement run, in the same session, by the code of git revision
``--baseline`` (extracted with ``git archive`` into a temporary folder, run in a
subprocess), path by path alternately with this tree's: ratio = baseline time / this tree's
time, in wall-clock and in CPU seconds of the process (steadier on a shared machine). How
the cuts and primitives differ from the baseline's is printed beside it (the changes are
meant to be exact). Goals (issue 13): 2,400 samples against the
bundled library <= 1 s, against 1,000 primitives <= 2 s; ``rotation none`` and time scale
1-1 never slower than the default; 2,400 -> 24,000 samples x12 or less (``--long``).

Below the table, each case's whole searches (the paper's Step 2 probes) and its CPU per
search, path by path, and each restricted case's cost per search against the default's
(``_per_search``): a restricted answer has more, shorter segments, each cut proven by a
search that fails one sample past it, so it is slower unless its searches are cheaper by as
much. Then (``_needed``) what that takes, path by path: the default's CPU over the restricted
case's whole searches, beside the 10th percentile and median of what each of its searches
costs (each timed, ``_search_clock``), and the case's time over the default's were every
search to cost one or the other: where a need lies below the median, no cut of the costliest
searches alone (the tail) meets the goal.

Run: ``python benchmarks/bench_match_novel.py [--paths 3] [--samples 2400]
[--big [--big-cases CASE ...]] [--long] [--baseline REV | --no-baseline]
[--cases default "rotation none" ...] [--glyph-chain] [--as-stored] [--shrink F] [--noise F]
[--rests]``;
``--glyph-chain`` times the cases on ``data/paths/glyph-chain.csv`` (the restricted
searches of ``bench_match.py --restricted``) instead, beside the baseline; ``--shrink 1e-6``
scales the novel paths (and eps) down until they barely move against the primitives.

``--as-stored`` times paths every restriction holds of instead: 5 stretches of stored
primitives' own samples, not turned, at time scale 1, each moved to start where the last
ended (``_as_stored``). The restricted searches then find the default's answer, and the
report's last lines (``_over_default``) show whether restricting alone costs time: on the
novel paths a restriction that does not hold cuts the path finer, and each cut costs a
whole search.

``--noise F`` adds white noise of σ = F × the path's largest extent on an axis to every sample
(seeded per path) and times each case twice on the same noisy path: at eps twice the noise's
RMS (σ√3: the path matches) and at half of it (nothing can match: an unmatched path), then
prints each path's unmatched time against its matched time (issue 13: "a path that mostly does
not match must cost about what one that matches does").

``--rests`` times each case on the novel paths with three rests added (the path held still
for 1 s, ``REST`` samples, at each quarter: a machine that stops, as a dwell in a part
program) and on the same paths without them, and prints each path's time with its rests over
its time without. A piece at rest has no arc length for the index, so the time-uniform grid
searches it (``primlib/match/_grid.py``): on 1,000 primitives a path with three rests cost
17x the path without them before the grid's blocks and caps.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

from _revisions import extract, run_worker

ROOT = Path(__file__).resolve().parents[1]
CASES = {"default": {}, "rotation none": {"rotation": "none"}, "time scale 1-1": {
    "time_scale": (1.0, 1.0)}}  # fmt: skip
# --noise: each case at these multiples of the noise's RMS (labels "CASE, eps ..."), in order
NOISE_EPS = {"eps 2x noise": 2.0, "eps noise/2": 0.5}
RESTS = ("with rests", "moving")  # --rests: each case on the path with its rests, and without
REST = 200  # samples of each rest (1 s at the bundled machine's dt)
BASELINE = "3d2aff9"  # main before the lockstep refinement and the up-front rejection


def _library(kind: str):
    """Bank of the bundled library or of 1,000 random primitives (2,000 samples each)."""
    import numpy as np

    from primlib.nurbs import Trajectory
    from primlib.plant import Machine
    from primlib.store import Bank

    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    if kind == "bundled":
        pieces = []
        for f in sorted((ROOT / "data" / "library").glob("*.csv")):
            if not f.name.endswith(".signal.csv"):
                pieces.append(Trajectory.from_csv(f).sample(machine.dt))
        return Bank.from_samples(pieces, machine.dt), machine.dt
    rng = np.random.default_rng(0)
    pieces = [_walk(rng, 2000, machine.dt, 24).sample(machine.dt) for _ in range(1000)]
    return Bank.from_samples(pieces, machine.dt), machine.dt


def _walk(rng, n: int, dt: float, m: int):
    import numpy as np

    from primlib.nurbs import Trajectory

    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 12.0, axis=0)
    knots = np.concatenate([np.zeros(3), np.linspace(0.0, 1.0, m - 2), np.ones(3)])
    return Trajectory.from_definition(3, knots, ctrl, None, (n - 1) * dt)


def _as_stored(bank, rng, n: int, dt: float, pieces: int = 5):
    """A path every restriction holds of: ``pieces`` stretches of stored primitives' own
    samples (about n / pieces each, at random starts; the whole primitive where none is
    that long), neither turned nor time-scaled, each moved to start where the last ended."""
    import numpy as np

    from primlib.nurbs import Trajectory

    counts = np.diff(bank.offsets)
    out, last, left = [], np.zeros(bank.points.shape[1]), n
    for j in range(pieces):
        want = left // (pieces - j) + (1 if j else 0)  # the first sample of a piece is shared
        ok = np.flatnonzero(counts >= want)
        p = int(rng.choice(ok)) if ok.size else int(np.argmax(counts))
        m = min(want, int(counts[p]))
        s0 = int(rng.integers(0, counts[p] - m + 1))
        pts = bank.points[bank.offsets[p] + s0 : bank.offsets[p] + s0 + m]
        pts = pts - pts[0] + last
        last = pts[-1]
        out.append(pts if not out else pts[1:])
        left -= m - (1 if j else 0)
    return Trajectory.from_samples(np.concatenate(out), dt)


def worker(spec: dict) -> dict:
    """Time every case of ``spec`` with the primlib importable here; JSON-able results."""
    import numpy as np

    from primlib.match import BankIndex, default_eps, segment_path
    from primlib.match._segment import drop_short
    from primlib.nurbs import Trajectory

    bank, dt = _library(spec["library"])
    out = {}
    for label in spec["cases"]:
        case, _, at = label.partition(", ")
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in CASES[case].items()}
        times, cpu, segs, frac, probes, each = [], [], [], [], [], []
        for seed in spec.get("seeds", range(spec["paths"])):
            n = spec["samples"]
            if spec.get("file"):  # one stored path, timed ``paths`` times
                path = Trajectory.from_csv(ROOT / spec["file"])
            elif spec.get("as_stored"):  # stored pieces as stored: the restrictions hold
                path = _as_stored(bank, np.random.default_rng(300 + seed), n, dt)
            else:
                path = _walk(np.random.default_rng(100 + seed), n, dt, max(8, n // 200))
            n = int(round(path.duration / dt)) + 1  # a file's own length (a walk's is n)
            pts = path.at(np.linspace(0.0, 1.0, n))
            eps = default_eps(path)
            if spec.get("noise"):  # white noise; eps a multiple of its RMS (NOISE_EPS)
                pts, eps = _noisy(pts, spec["noise"], seed, NOISE_EPS[at])
            if at == RESTS[0]:  # held still at each quarter (RESTS)
                pts = _with_rests(pts)
            if spec.get("shrink"):  # a path that barely moves: the same shape, scaled down
                pts = pts.mean(axis=0) + (pts - pts.mean(axis=0)) * spec["shrink"]
                eps *= spec["shrink"]
            out["samples"] = n
            index = BankIndex(bank)  # first call: the index is built inside
            more, shortest = _min_segment(spec, segment_path, path.duration / (n - 1))
            if spec.get("warm"):  # the second call on the index: the first one untimed
                segment_path(index, pts, path.duration / (n - 1), eps, **kw, **more)
            t0, c0 = time.perf_counter(), time.process_time()
            with _search_clock() as clock:
                s, info = segment_path(index, pts, path.duration / (n - 1), eps, **kw, **more)
            if shortest is not None:  # as match_path: matches shorter than it dropped after
                s = drop_short(s, shortest / path.duration, 3)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            segs.append([(round(x.end, 9), x.primitive) for x in s])
            frac.append(sum(x.end - x.start for x in s if x.primitive is not None))
            probes.append(int(info.get("probes", 0)))  # whole searches (the paper's Step 2)
            each.append(clock)
        out[label] = {"times": times, "cpu": cpu, "segments": segs, "fraction": frac,
                      "probes": probes, "search_cpu": each}  # fmt: skip
    return out


@contextlib.contextmanager
def _search_clock():
    """The CPU seconds of each whole search (the segmenter's ``probe``, the paper's Step 2)
    made inside the block, in order; none recorded on a revision without that method."""
    from primlib.match import _segment

    seg = getattr(_segment, "_Segmenter", None)
    probe = getattr(seg, "probe", None)
    clock: list[float] = []
    if probe is None:
        yield clock
        return

    def timed(self, a, b):
        c0 = time.process_time()
        try:
            return probe(self, a, b)
        finally:
            clock.append(time.process_time() - c0)

    seg.probe = timed
    try:
        yield clock
    finally:
        seg.probe = probe


def _with_rests(pts, rests: int = 3, length: int = REST):
    """``pts`` held still for ``length`` samples at each of ``rests`` evenly spaced points
    (the samples there repeated): the same motion, with rests."""
    import numpy as np

    n = len(pts)
    at = [n * (j + 1) // (rests + 1) for j in range(rests)]
    parts = np.split(pts, at)
    held = [np.repeat(pts[a - 1 : a], length, axis=0) for a in at]
    return np.concatenate([x for pair in zip(parts, held + [pts[:0]], strict=True) for x in pair])


def _noisy(pts, noise: float, seed: int, times: float):
    """``pts`` with white noise of σ = ``noise`` × its largest extent on an axis (the same
    draw for every case of a path: seeded by it), and eps ``times`` the noise's RMS σ√d."""
    import numpy as np
    from _noise import white_noise

    noisy, rms = white_noise(pts, noise, np.random.default_rng(200 + seed))
    return noisy, times * rms


def _min_segment(spec: dict, segment_path, dt: float) -> tuple[dict, float | None]:
    """The segmentation's keywords for ``spec``'s minimum segment (seconds), as match_path
    passes it (``min_samples``: min_segment / dt samples, rounded; none on a revision whose
    segmentation has no such option, which only drops the short matches after), and it."""
    import inspect

    shortest = spec.get("min_segment")
    if shortest is None or "min_samples" not in inspect.signature(segment_path).parameters:
        return {}, shortest
    return {"min_samples": int(round(shortest / dt))}, shortest


def _merge(into: dict, more: dict) -> None:
    """Append one worker's per-path lists to ``into`` (case by case)."""
    for label, r in more.items():
        if isinstance(r, dict):
            for key, values in r.items():
                into.setdefault(label, {}).setdefault(key, []).extend(values)
        else:
            into[label] = r


def _compare(new: list, old: list, last: int) -> str:
    """How the cuts and primitives of each path differ from the baseline's (empty if not)."""
    notes = []
    for i, (x, y) in enumerate(zip(new, old, strict=True)):
        cx, cy = [round(e * last) for e, _ in x], [round(e * last) for e, _ in y]
        if cx != cy:
            if len(cx) == len(cy):
                shift = max(abs(a - b) for a, b in zip(cx, cy, strict=True))
                notes.append(f"path {i}: {sum(a != b for a, b in zip(cx, cy, strict=True))} "
                             f"of {len(cx)} cuts moved, by {shift} samples at most")  # fmt: skip
            else:
                notes.append(f"path {i}: {len(cx)} segments (baseline {len(cy)})")
        elif [p for _, p in x] != [p for _, p in y]:
            changed = sum(p != q for (_, p), (_, q) in zip(x, y, strict=True))
            notes.append(f"path {i}: same cuts, {changed} other primitive(s)")
    return f" ({'; '.join(notes)})" if notes else " (same cuts and primitives)"


def _report(spec: dict, new: dict, old: dict | None) -> None:
    samples = new.get("samples", spec["samples"])
    what = f"{spec['file']}, timed {spec['paths']} times" if spec.get("file") else (
        f"{spec['paths']} paths")  # fmt: skip
    if spec.get("shrink"):
        what += f" scaled by {spec['shrink']:g}"
    if spec.get("min_segment") is not None:
        what += f", min segment {spec['min_segment']:g} s (shorter matches dropped)"
    if spec.get("noise"):
        what += f", white noise σ = {spec['noise']:g} of the extent"
    if spec.get("as_stored"):
        what += ", each of 5 stored pieces as stored (not turned, time scale 1)"
    if spec.get("rests"):
        what += f", and with 3 rests of {REST} samples"
    call = "warm call: the second on one index" if spec.get("warm") else "first call"
    print(f"\n{spec['library']} library, {samples:,} samples, {what} ({call}, seconds)")
    print("| case | median | CPU | worst | segments (median) | matched | baseline median | "
          "baseline CPU | ratio | CPU ratio |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label in spec["cases"]:
        r = new[label]
        med, cpu = statistics.median(r["times"]), statistics.median(r["cpu"])
        base, base_cpu, ratio, cpu_ratio = "-", "-", "-", "-"
        if old is not None:
            b, bc = statistics.median(old[label]["times"]), statistics.median(old[label]["cpu"])
            base, base_cpu = f"{b:.2f}", f"{bc:.2f}"
            ratio, cpu_ratio = f"{b / med:.1f}x", f"{bc / cpu:.1f}x"
            base += _compare(r["segments"], old[label]["segments"], int(samples) - 1)
        nseg = statistics.median(len(s) for s in r["segments"])
        print(f"| {label} | {med:.2f} | {cpu:.2f} | {max(r['times']):.2f} | {nseg:g} | "
              f"{100 * statistics.median(r['fraction']):.0f} % | {base} | {base_cpu} | {ratio} "
              f"| {cpu_ratio} |")  # fmt: skip
    if old is not None:
        print("\nCPU seconds path by path, this tree / baseline (ratio):")
        for label in spec["cases"]:
            print(f"- {label}: {_per_path(new[label]['cpu'], old[label]['cpu'])}")
    print("\nSegments / matched, path by path (the baseline's in brackets):")
    for label in spec["cases"]:
        print(f"- {label}: {_per_path_cuts(new[label], (old or {}).get(label))}")
    _per_search(spec, new)
    _needed(spec, new)
    _over_default(spec, new)
    _unmatched_over_matched(spec, new, old)
    _rests_over_moving(spec, new, old)


def _rests_over_moving(spec: dict, new: dict, old: dict | None) -> None:
    """With rests: each case's CPU on a path with its rests over its CPU on the same path
    without them, path by path, and their median and worst."""
    if spec.get("rests"):
        _pair_ratios(spec, new, old, RESTS, "With rests / without CPU, path by path (median, "
                     f"worst; the rests add {3 * REST} samples):")  # fmt: skip


def _scaling(spec: dict, long: tuple, short: tuple) -> None:
    """With ``--long``: each case's CPU on the paths of 10x the samples over its CPU on the
    paths of the same seeds at the shorter length (other paths: the walk's control points
    grow with the samples), path by path, their median and worst; issue 13's goal is x12 or
    less."""
    print(f"\nLength x{spec['samples'] / spec['short']:g} ({spec['short']:,} -> "
          f"{spec['samples']:,} samples), CPU at this length / at the shorter, path by path "
          "(median, worst; goal x12 or less):")  # fmt: skip
    for label in spec["cases"]:
        for tree, res, base in zip(("this tree", "baseline"), long, short, strict=True):
            if res is None:
                continue
            cells = _ratios(res[label]["cpu"], base[label]["cpu"], "x{:.1f}")
            print(f"- {label}, {tree}: {cells}")


def _unmatched_over_matched(spec: dict, new: dict, old: dict | None) -> None:
    """With noise: each case's CPU on a path at eps noise/2 (unmatched) over its CPU on the
    same path at eps 2x noise (matched), path by path, and their median and worst."""
    if spec.get("noise"):
        pair = tuple(reversed(NOISE_EPS))  # unmatched over matched
        _pair_ratios(spec, new, old, pair, "Unmatched / matched CPU, path by path (median, worst):")


def _pair_ratios(spec: dict, new: dict, old: dict | None, pair: tuple, title: str) -> None:
    """Each case's CPU as ``"case, pair[0]"`` over its CPU as ``"case, pair[1]"``, path by
    path, in this tree and the baseline's, under ``title``."""
    print(f"\n{title}")
    for case in dict.fromkeys(label.partition(", ")[0] for label in spec["cases"]):
        for tree, res in (("this tree", new), ("baseline", old)):
            if res is None:
                continue
            top, bottom = (res[f"{case}, {at}"]["cpu"] for at in pair)
            print(f"- {case}, {tree}: {_ratios(top, bottom, '{:.2f}x')}")


def _ratios(top: list[float], bottom: list[float], fmt: str) -> str:
    """Path by path ``top`` / ``bottom`` formatted by ``fmt``, then their median and worst
    (the largest) in brackets."""
    ratio = [t / max(b, 1e-9) for t, b in zip(top, bottom, strict=True)]
    med, worst = fmt.format(statistics.median(ratio)), fmt.format(max(ratio))
    return f"{', '.join(fmt.format(r) for r in ratio)} (median {med}, worst {worst})"


def _per_search(spec: dict, new: dict) -> None:
    """Whole searches (probes) and CPU per search, path by path, and for each restricted
    case its CPU per search against the default's on the same path.

    Every cut of an answer costs at least one whole search that fails a sample past it (the
    proof that the prefix before it is the longest), so a case's time is at least its
    segments times the cost of a failing search: a restricted answer with four times the
    segments is never slower only if its searches cost a quarter of the default's. This
    table tells the two apart: the cost of one search, and how many the answer needs."""
    if not all(new[label].get("probes") for label in spec["cases"]):
        return  # a revision whose worker does not count them
    print("\nWhole searches (probes) / CPU ms per search, path by path:")
    per = {}
    for label in spec["cases"]:
        r = new[label]
        per[label] = [1e3 * c / max(p, 1) for c, p in zip(r["cpu"], r["probes"], strict=True)]
        cells = ", ".join(f"{p} / {m:.1f}" for p, m in zip(r["probes"], per[label], strict=True))
        print(f"- {label}: {cells}")
    if "default" in per:
        for label in (c for c in spec["cases"] if c != "default"):
            ratios = [d / m for m, d in zip(per[label], per["default"], strict=True)]
            print(f"- {label}, CPU per search against the default's (default / this, >1: "
                  f"cheaper): {', '.join(f'{x:.2f}x' for x in ratios)}")  # fmt: skip


def _needed(spec: dict, new: dict) -> None:
    """For each restricted case, path by path, the CPU a whole search of it may cost for the
    case to be no slower than the default on that path (the default's CPU over this case's
    whole searches) beside what its searches cost: the 10th percentile and the median, the
    share of its searches at or under the need, and the case's CPU over the default's were
    every one of its searches to cost its 10th percentile, or its median.

    With every search at its median (no tail left) above 1x, no cut of the costliest
    searches alone meets "never slower"; with every search at its 10th percentile above 1x,
    every search would have to cost less than the cheapest tenth of them does today."""
    import numpy as np

    timed = all(any(map(len, new[c].get("search_cpu", []))) for c in spec["cases"])
    if "default" not in spec["cases"] or len(spec["cases"]) < 2 or not timed:
        return  # nothing to divide by, or a revision whose searches are not timed
    print(
        "\nNever slower needs, per whole search: the default's CPU / this case's searches; "
        "this case's searches: 10th percentile / median, the share at or under the need; "
        "the case over the default with every search at its 10th percentile / median:"
    )
    base = new["default"]["cpu"]
    for label in (c for c in spec["cases"] if c != "default"):
        cells = []
        for d, each in zip(base, new[label]["search_cpu"], strict=True):
            ms = 1e3 * np.asarray(each)
            need, p10, med = 1e3 * d / ms.size, np.percentile(ms, 10), np.median(ms)
            cells.append(f"{need:.1f} ms: {p10:.1f} / {med:.1f} ms, "
                         f"{100 * np.mean(ms <= need):.0f} %; "
                         f"{p10 / need:.2f}x / {med / need:.2f}x")  # fmt: skip
        print(f"- {label}: {' | '.join(cells)}")


def _over_default(spec: dict, new: dict) -> None:
    """Each restricted case's CPU over the default's on the same path, path by path, their
    median and worst (issue 13: "never slower", so 1.00x or less), and the segments of each
    beside the default's (a restriction that does not hold of the path cuts it finer)."""
    if "default" not in spec["cases"] or len(spec["cases"]) < 2:
        return
    base = new["default"]
    print("\nRestricted over the default, CPU path by path (median, worst; goal <= 1.00x):")
    for label in (c for c in spec["cases"] if c != "default"):
        r = new[label]
        cuts = ", ".join(f"{len(a)}/{len(b)}" for a, b in zip(r["segments"], base["segments"],
                                                              strict=True))  # fmt: skip
        print(f"- {label}: {_ratios(r['cpu'], base['cpu'], '{:.2f}x')}; segments against the "
              f"default's: {cuts}")  # fmt: skip


def _per_path_cuts(r: dict, o: dict | None) -> str:
    """Each path's segments and fraction matched (the baseline's beside, when given)."""
    cells = [
        f"{len(s)} / {100 * f:.1f} %" for s, f in zip(r["segments"], r["fraction"], strict=True)
    ]
    if o is not None:
        old = zip(cells, o["segments"], o["fraction"], strict=True)
        cells = [f"{c} [{len(s)} / {100 * f:.1f} %]" for c, s, f in old]
    return ", ".join(cells)


def _per_path(cpu: list[float], base: list[float]) -> str:
    """Each path's CPU time beside the baseline's (paths differ several-fold in cost, so a
    median of each side alone can pick different paths' times on a loaded machine)."""
    return ", ".join(f"{c:.2f} / {b:.2f} ({b / c:.2f}x)" for c, b in zip(cpu, base, strict=True))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--paths", type=int, default=3)
    ap.add_argument("--samples", type=int, default=2400)
    ap.add_argument("--big", action="store_true", help="also 1,000 random primitives")
    ap.add_argument(
        "--big-cases",
        nargs="+",
        default=["default"],
        choices=list(CASES),
        help="the cases timed on the 1,000 random primitives (default: default only)",
    )
    ap.add_argument(
        "--long",
        action="store_true",
        help="also 10x the samples, on each library timed (the default case only), and the "
        "time at 10x over the time at the shorter length, path by path",
    )
    ap.add_argument("--baseline", default=BASELINE)
    ap.add_argument("--no-baseline", action="store_true")
    ap.add_argument(
        "--cases",
        nargs="+",
        choices=list(CASES),
        default=list(CASES),
        help="only these cases of the bundled library (all three by default)",
    )
    ap.add_argument(
        "--shrink",
        type=float,
        help="scale the novel paths about their centroid by this factor (and eps with "
        "them): 1e-6 makes paths that barely move against the library's primitives",
    )
    ap.add_argument(
        "--min-segment",
        type=float,
        nargs="+",
        help="instead of the segmentation alone, as match_path with these minimum segments "
        "(seconds, one run each): no probe shorter (this tree; a revision without the option "
        "drops the short matches after, as match_path did), shorter matches dropped",
    )
    ap.add_argument(
        "--noise",
        type=float,
        help="add white noise of this fraction of the extent (e.g. 0.001) and time each case "
        "at eps 2x and 1/2x the noise's RMS: matched and unmatched",
    )
    ap.add_argument(
        "--rests",
        action="store_true",
        help="time each case on the novel paths with three rests of 1 s added and without "
        "them, and the ratio path by path",
    )
    ap.add_argument(
        "--warm",
        action="store_true",
        help="time each path's second segmentation on one BankIndex (the first untimed): "
        "what a library or service that keeps the index pays",
    )
    ap.add_argument(
        "--as-stored",
        action="store_true",
        help="instead of novel paths: paths of 5 stored pieces as stored (not turned, time "
        "scale 1), so that every restriction holds of them (and with --big on 1,000 primitives)",
    )
    ap.add_argument(
        "--glyph-chain",
        action="store_true",
        help="instead: data/paths/glyph-chain.csv (glyphs the library holds, rotated), the "
        "cases timed --paths times",
    )
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return
    specs = [{"library": "bundled", "samples": args.samples, "paths": args.paths,
              "cases": args.cases}]  # fmt: skip
    if args.shrink:
        specs[0]["shrink"] = args.shrink
    if args.as_stored:
        specs[0]["as_stored"] = True
    if args.glyph_chain:
        specs = [{"library": "bundled", "samples": 0, "paths": args.paths, "cases": args.cases,
                  "file": "data/paths/glyph-chain.csv"}]  # fmt: skip
    if args.min_segment:
        specs = [dict(specs[0], min_segment=m) for m in args.min_segment] + specs[1:]
    if args.big:
        specs.append({"library": "random-1000", "samples": args.samples, "paths": args.paths,
                      "cases": args.big_cases, "as_stored": args.as_stored})  # fmt: skip
    if args.long:  # each library's paths again at 10x the samples, the default case alone
        specs += [dict(s, samples=10 * s["samples"], cases=["default"], short=s["samples"])
                  for s in specs if not s.get("file")]  # fmt: skip
    if args.warm:
        for spec in specs:
            spec["warm"] = True
    if args.rests and args.noise:
        ap.error("--rests and --noise: one at a time")
    if args.rests:
        for spec in specs:  # each case with rests, then moving, on the same path
            spec.update(rests=True, cases=[f"{c}, {r}" for c in spec["cases"] for r in RESTS])
    if args.noise:
        for spec in specs:  # each case matched, then unmatched, on the same noisy path
            spec.update(
                noise=args.noise, cases=[f"{c}, {e}" for c in spec["cases"] for e in NOISE_EPS]
            )
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory(prefix="bench_novel_") as tmp:
        old_tree = None if args.no_baseline else extract(args.baseline, tmp)
        done = {}  # (library, samples, min segment) -> this tree's and the baseline's results
        for spec in specs:
            # path by path, this tree then the baseline: a shared machine's load then
            # weighs on both alike
            new, old = {}, None if old_tree is None else {}
            for seed in range(spec["paths"]):
                one = dict(spec, seeds=[seed])
                _merge(new, run_worker(__file__, json.dumps(one), ROOT))
                if old_tree is not None:
                    _merge(old, run_worker(__file__, json.dumps(one), old_tree))
            _report(spec, new, old)
            done[spec["library"], spec["samples"], spec.get("min_segment")] = (new, old)
            if spec.get("short"):
                _scaling(spec, (new, old), done[spec["library"], spec["short"],
                                                spec.get("min_segment")])  # fmt: skip
    print(f"\nbaseline: git revision {args.baseline}" if not args.no_baseline else "")
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
