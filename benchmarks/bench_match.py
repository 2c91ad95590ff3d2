"""Benchmark of ``primlib match``: 1,000 primitives of 2,000 samples (3-D), a new path of
2,400 samples made of 5 rotated, translated, time-scaled pieces of stored primitives.

Reports, each beside its baseline measured in the same run:

* the whole ``Library.match`` on a library file, the first call (a freshly opened file:
  the bank read from DuckDB, the arc-length index built, the segmentation; median of 3
  fresh opens) and warm calls (``match_path`` on one ``BankIndex`` kept across calls, as
  the pipeline keeps it; median of 5), against issue 13's goals (first call <= 1 s, warm
  <= 0.5 s) and the baselines below (``--composed`` times both beside a git revision);
* the same segmentation from the exhaustive scan of the same candidate windows with no
  bounds (``scan`` of ``_reference_search.py``) on 1,000 primitives, and from the
  exhaustive time-uniform grid (``grid``: every primitive × start × time scale,
  vectorised) on 100 — both asserted equal;
* the plain per-candidate Kabsch loop: timed on 3,000 windows, scaled by the number of
  windows the exhaustive scan scores;
* first-call and warm match time against library size 10 / 100 / 1,000.

* the persisted index: reading the 1,000 primitives' index and envelopes back from a
  DuckDB file against building them (``_index_persist.py``, interleaved, medians of 5;
  the read in three layouts: DOUBLE[] lists, one BLOB per array, plain DOUBLE columns);
  rebuilding is cheaper (build 0.34 s against a 0.46 s read, 0.42 s against 0.52 s, 0.63 s
  against 0.73 s, in three runs at load 5-6, lists only; and before a stored index could
  be used it would also have to be checked against the stored primitives), so the index
  is not kept in the library file.

Run: ``python benchmarks/bench_match.py`` (single-threaded BLAS; ``--full-grid`` also runs
the time grid on 1,000 primitives, about ten minutes; ``--restricted`` instead times the
restricted searches — ``rotation="none"``, time scale 1-1 — against the default on the
bundled library and ``data/paths/glyph-chain.csv``, the per-axis bound beside the
rotation-invariant one; ``--length 2400 24000 100000 [--baseline REV]`` instead times
composed and novel paths of those lengths against the bundled library, each in its own
process with its peak memory, the ratios to the first length beside the goals, and with
``--baseline`` the same paths matched by revision REV's primlib, with ``--rests`` the novel
paths also held still 3 times per 2,400 samples (dwells) — ``_length_scaling.py``;
``--index [--baseline REV]`` only the index row, on 1,000 random primitives (with the
build also timed with revision REV); ``--composed [--baseline REV] [--rounds N]``
only the composed path's first and warm calls at 1,000 primitives, this tree and revision
REV (default main) alternated N times (default 2), each in its own process —
``_composed.py``).
"""

from __future__ import annotations

import os

if __name__ == "__main__":  # timed single-threaded; a test importing this keeps its threads
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere

import numpy as np  # noqa: E402
from _composed import EPS, PIECES, build_library, build_path, first_call  # noqa: E402
from _index_persist import compare as index_read_vs_build  # noqa: E402
from _length_scaling import bank_of  # noqa: E402
from _length_scaling import run as run_length  # noqa: E402
from _reference_search import reference_segment_path  # noqa: E402
from _revisions import alternated, extract  # noqa: E402
from _timing import median_time  # noqa: E402

from primlib.match import BankIndex, kabsch, match_path, segment_path  # noqa: E402
from primlib.match._options import PathPiece  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402
from primlib.pipeline import Library  # noqa: E402
from primlib.plant import Machine  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def key(segments) -> list[tuple[float, int | None]]:
    return [(round(s.end, 9), s.primitive) for s in segments]


def restricted(machine: Machine) -> None:
    """``--restricted``: the bundled library and data/paths/glyph-chain.csv, matched with the
    default search, ``rotation="none"`` and ``time_scale=(1, 1)``; the restricted searches
    with the per-axis bounds beside the same search with the rotation-invariant bound."""
    from primlib.io import read_signal_csv
    from primlib.match import default_eps

    lib = Library()
    lib.add_machine(machine)
    for f in sorted((ROOT / "data" / "library").glob("*.csv")):
        if not f.name.endswith(".signal.csv"):
            _, u = read_signal_csv(f.with_suffix(".signal.csv"))
            lib.add(Trajectory.from_csv(f), u, machine=machine.name, name=f.stem)
    index = BankIndex(lib.bank(machine.name))
    path = Trajectory.from_csv(ROOT / "data" / "paths" / "glyph-chain.csv")
    n = int(round(path.duration / machine.dt)) + 1
    pts, dt = path.at(np.linspace(0.0, 1.0, n)), path.duration / (n - 1)
    eps = default_eps(path)
    print(f"\nrestricted searches: bundled library ({index.k} primitives), glyph-chain.csv")
    print("| search | time | segments | probes | windows past bound 1 | baseline | ratio |")
    print("|---|---|---|---|---|---|---|")
    t_def, (segs, info) = median_time(lambda: segment_path(index, pts, dt, eps), 1)
    print(f"| default | {t_def:.2f} s | {len(segs)} | {info['probes']} | {info['bounded']:,} "
          "| - | - |")  # fmt: skip
    for label, kw in (("rotation none", {"rotation": "none"}),):
        t_new, (segs, info) = median_time(lambda kw=kw: segment_path(index, pts, dt, eps, **kw), 1)
        t_old, (segs_o, info_o) = median_time(
            lambda kw=kw: reference_segment_path(index, pts, dt, eps, "invariant-bound", **kw), 1
        )
        assert key(segs) == key(segs_o), "the per-axis bound changed the segmentation"
        print(
            f"| {label} | {t_new:.2f} s | {len(segs)} | {info['probes']} | "
            f"{info['bounded']:,} (was {info_o['bounded']:,}) | invariant bound {t_old:.2f} s "
            f"| {t_old / t_new:.1f}x; {t_new / t_def:.1f}x the default |"
        )
    t_ts, (segs, info) = median_time(
        lambda: segment_path(index, pts, dt, eps, time_scale=(1.0, 1.0)), 1
    )
    past = "time-uniform grid" if info["search"] == "grid" else f"{info['bounded']:,}"
    print(
        f"| time scale 1-1 | {t_ts:.2f} s | {len(segs)} | {info['probes']} | "
        f"{past} | default {t_def:.2f} s | {t_ts / t_def:.1f}x the default |"
    )
    lib.close()


def length_scaling(lengths: list[int], library: str = "bundled", timeout: float = 1800.0,
                   baseline: Path | None = None, rests: bool = False):  # fmt: skip
    """``--length``: composed and novel paths of each length (``_length_scaling.py``; with
    ``rests``, also the novel paths held still: its kind ``rests``), one process each; time
    and peak memory, each kind's ratio to its first length, and (with ``baseline``, a tree
    holding another revision's ``primlib``) the same run there."""
    print(f"\nmatch time and peak memory against path length ({library} library; first call, "
          "one process per path: peak RSS includes the interpreter and numpy)")  # fmt: skip
    print("| path | samples | time | segments | matched | peak RSS | time / first length "
          "| samples / first length | goal (CPU ratio) | baseline time, peak | ratio |"
          )  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for kind in ("composed", "novel") + (("rests",) if rests else ()):
        first = None
        for n in lengths:
            spec = {"kind": kind, "samples": n, "library": library}
            r = run_length(spec, timeout=timeout)
            old = run_length(spec, tree=baseline, timeout=timeout) if baseline else None
            rows.append((kind, n, r, old))
            if "timeout" in r:
                print(f"| {kind} | {n:,} | > {timeout:.0f} s (stopped) |" + " - |" * 8)
                continue
            first = first or (n, r["seconds"], r["cpu_seconds"])
            ratio, grow = r["seconds"] / first[1], n / first[0]
            cpu_ratio = r["cpu_seconds"] / first[2]  # the goal's ratio: less the load's
            goal = _length_goal(n, grow, cpu_ratio, r)
            base = (f"> {timeout:.0f} s | -" if "timeout" in old else
                    f"{old['seconds']:.1f} s (CPU {old['cpu_seconds']:.1f} s), "
                    f"{old['peak_mb']:.0f} MB | {old['seconds'] / r['seconds']:.1f}x (CPU "
                    f"{old['cpu_seconds'] / r['cpu_seconds']:.1f}x), same segments: "
                    f"{'yes' if _same(old, r) else 'NO'}") if old else "- | -"  # fmt: skip
            print(f"| {kind} | {n:,} | {r['seconds']:.1f} s (CPU {r['cpu_seconds']:.1f} s) | "
                  f"{r['segments']} | {100 * r['matched']:.0f} % | {r['peak_mb']:.0f} MB | "
                  f"x{ratio:.1f} (CPU x{cpu_ratio:.1f}) | "
                  f"x{grow:.1f} | {goal} | {base} |")  # fmt: skip
    return rows


def _same(old: dict, new: dict) -> bool:
    """The same segments (ends, primitives) and RMSDs to 1e-12 of each (round-off)."""
    if old["cuts"] != new["cuts"] or len(old.get("rmsds", [])) != len(new.get("rmsds", [])):
        return False
    return bool(np.allclose(old.get("rmsds", []), new.get("rmsds", []), rtol=1e-12, atol=0))


def _length_goal(n: int, grow: float, ratio: float, r: dict) -> str:
    """The issue-13 goal a row is held to, and whether it is met."""
    parts = []
    if grow > 1:  # issue 13: x10 the samples in x12 the time or less, i.e. about linear
        parts.append(f"x{1.2 * grow:.0f} or less: {'met' if ratio <= 1.2 * grow else 'NOT met'}")
    if n >= 100_000:
        ok = r["seconds"] <= 30 and r["peak_mb"] <= 1024
        parts.append(f"<= 30 s and <= 1 GB: {'met' if ok else 'NOT met'}")
    return "; ".join(parts) or "-"


def composed(baseline: str, rounds: int = 2) -> None:
    """``--composed``: the composed path's first call (median of 3 fresh opens) and warm
    call (median of 5) against 1,000 primitives, this tree and revision ``baseline``
    alternated ``rounds`` times, each in its own process (``_composed.py``); the medians
    over the rounds (wall and CPU seconds), the ratios, and whether both cut the same
    segments (asserted)."""
    import json

    spec = json.dumps({"k": 1000, "first": 3, "warm": 5, "root": str(ROOT)})
    res = alternated(ROOT / "benchmarks" / "_composed.py", spec, baseline, rounds)
    new, old = res["this tree"], res[baseline]
    assert all(r["segments"] == new[0]["segments"] for r in new + old), "segments differ"
    print(f"\ncomposed path, 1,000 primitives ({rounds} rounds alternated; baseline git "
          f"revision {baseline})")  # fmt: skip
    print("| call | this tree | baseline | ratio | goal | CPU: this tree | baseline | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for name, goal in (("first", 1.0), ("warm", 0.5)):
        a = statistics.median(r[name] for r in new)
        b = statistics.median(r[name] for r in old)
        ca = statistics.median(r[f"{name}_cpu"] for r in new)
        cb = statistics.median(r[f"{name}_cpu"] for r in old)
        print(f"| {name} | {a:.3f} s | {b:.3f} s | {b / a:.2f}x | <= {goal} s: "
              f"{'met' if a <= goal else 'NOT met'} | {ca:.3f} s | {cb:.3f} s | "
              f"{cb / ca:.2f}x |")  # fmt: skip
    print(f"same segments: {len(new[0]['segments'])}, equal in every run")


def index_build_baseline(baseline: str, rounds: int = 3) -> None:
    """``--index --baseline REV``: the index build alone (``_index_persist.build_seconds``,
    median of 5) with this tree and revision REV, alternated ``rounds`` times, each in its
    own process."""

    res = alternated(ROOT / "benchmarks" / "_index_persist.py", "5", baseline, rounds)
    med = {k: {u: statistics.median(r[u] for r in v) for u in ("wall", "cpu")}
           for k, v in res.items()}  # fmt: skip
    a, b = med["this tree"], med[baseline]
    print(f"index build alone (arc-length index + envelopes, 1,000 primitives; {rounds} rounds "
          f"alternated): this tree {a['wall']:.3f} s ({a['cpu']:.3f} s CPU), git revision "
          f"{baseline} {b['wall']:.3f} s ({b['cpu']:.3f} s CPU), {b['wall'] / a['wall']:.2f}x "
          f"({b['cpu'] / a['cpu']:.2f}x CPU)")  # fmt: skip


def index_persistence(bank, folder: Path, repeat: int = 5) -> tuple[float, float, float]:
    """Median seconds to build the 1,000 primitives' index and to read it from DuckDB (the
    fastest of the layouts of ``_index_persist.py``: DOUBLE[] lists, BLOBs, plain DOUBLE
    columns, each printed)."""
    r = index_read_vs_build(bank, folder / "index.duckdb", repeat)
    layouts = ", ".join(f"{lay} {r[f'read_{lay}']:.3f} s" for lay in ("list", "blob", "column"))
    print(f"\nthe index of {len(bank.ids):,} primitives ({r['mb']:.0f} MB of arrays): build "
          f"{r['build']:.3f} s, read back from a DuckDB file {r['read']:.3f} s at best "
          f"({layouts}; medians of {repeat}, interleaved)")  # fmt: skip
    return r["build"], r["read"], r["mb"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument(
        "--full-grid",
        action="store_true",
        help="also run the time-uniform grid on 1,000 primitives (about 10 minutes)",
    )
    ap.add_argument(
        "--restricted",
        action="store_true",
        help="only the restricted searches (rotation none, time scale 1-1) on glyph-chain",
    )
    ap.add_argument(
        "--length",
        type=int,
        nargs="+",
        metavar="SAMPLES",
        help="only the path-length study: composed and novel paths of these lengths",
    )
    ap.add_argument(
        "--library",
        choices=("bundled", "random-1000"),
        default="bundled",
        help="with --length: the library matched against (default bundled; random-1000: "
        "bench_match_novel's 1,000 random primitives)",
    )
    ap.add_argument(
        "--rests",
        action="store_true",
        help="with --length: also the novel paths held still 3 times per 2,400 samples for "
        "1 s each (the same samples: dwells)",
    )
    ap.add_argument(
        "--baseline",
        metavar="REV",
        help="with --length: also run each path with git revision REV's primlib; with "
        "--composed or --index: the revision timed beside this tree (--composed: default "
        "main)",
    )
    ap.add_argument(
        "--composed",
        action="store_true",
        help="only the composed path's first and warm calls at 1,000 primitives, this tree "
        "and --baseline alternated",
    )
    ap.add_argument(
        "--rounds",
        type=int,
        default=2,
        help="with --composed: rounds of this tree and the baseline alternated (default 2)",
    )
    ap.add_argument(
        "--index",
        action="store_true",
        help="only the index row: read back from DuckDB against rebuilt, 1,000 primitives",
    )
    args = ap.parse_args()
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    if args.index:
        with tempfile.TemporaryDirectory(prefix="bench_index_") as folder:
            build_t, read_t, mb = index_persistence(bank_of("random-1000")[0], Path(folder))
        print(f"read / build: {read_t / build_t:.2f}")
        if args.baseline:
            index_build_baseline(args.baseline)
        return
    if args.restricted:
        restricted(machine)
        return
    if args.composed:
        print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        composed(args.baseline or "main", args.rounds)
        print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return
    if args.length:
        with tempfile.TemporaryDirectory(prefix="bench_length_") as folder:
            base = None
            if args.baseline:
                base = extract(args.baseline, folder)
            length_scaling(args.length, library=args.library, baseline=base, rests=args.rests)
        if args.baseline:
            print(f"baseline: git revision {args.baseline}")
        return
    print(f"machine {machine.name}: dt {machine.dt} s; eps {EPS}; pieces {len(PIECES)}")

    sizes = (10, 100, 1000)
    tmp = tempfile.TemporaryDirectory(prefix="bench_match_")
    dbs = {k: Path(tmp.name) / f"lib{k}.duckdb" for k in sizes}
    t0 = time.perf_counter()
    for k in sizes:
        build_library(k, machine, db=dbs[k]).close()
    with Library(dbs[10]) as lb:
        path, truth = build_path(lb, machine)
    n = int(round(path.duration / machine.dt)) + 1
    setup = time.perf_counter() - t0
    print(f"setup: library files {sizes} and the path ({n} samples) in {setup:.1f} s")
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")

    # -- first call on each library file (fresh open: nothing cached), then warm calls
    first, reads, warms, firsts = {}, {}, {}, {}
    for k in (1000, 100, 10):  # the 1,000 case first: the process's very first call too
        first[k], reads[k], firsts[k], _ = first_call(dbs[k], machine.name, path)
    libs = {k: Library(dbs[k]) for k in sizes}
    indexes = {k: BankIndex(libs[k].bank(machine.name)) for k in sizes}
    for k in sizes:
        match_path(indexes[k], path, eps=EPS)
        warms[k] = median_time(lambda ix=indexes[k]: match_path(ix, path, eps=EPS), 5)
    cold, mt = first[1000], firsts[1000]
    warm, mt2 = warms[1000]

    assert key(mt.segments) == key(mt2.segments)
    segs = mt.segments
    print(f"\nmatch, 1,000 primitives: {len(segs)} segments, {mt.n_unmatched} unmatched")
    for s in segs:
        print(
            f"  {s.start:.4f}-{s.end:.4f}  #{s.primitive}  k={s.time_scale:.3f}  "
            f"angle={np.degrees(s.angle):6.1f}  rmsd={s.rmsd:.4f}"
        )
    assert len(segs) <= len(PIECES) + 1, "more segments than pieces + 1"
    assert [s.primitive for s in segs] == truth, "the pieces' primitives were not recovered"
    assert all(s.rmsd < EPS for s in segs)
    info = mt2.info
    print(
        f"  first call {cold:.3f} s (median of 3 fresh opens; goal <= 1 s): bank read "
        f"{reads[1000]:.3f} s, index {mt.info['index_seconds']:.3f} s, the rest "
        f"{cold - reads[1000] - mt.info['index_seconds']:.3f} s"
    )
    print(
        f"  warm {warm:.3f} s (median of 5; goal <= 0.5 s); {info['probes']} probes, "
        f"{info['windows']:,} windows, {info['bounded']:,} past bound 1, "
        f"{info['scored']:,} scored"
    )

    # -- the exhaustive searches on the same samples
    bank = indexes[1000]
    pts = path.at(np.linspace(0.0, 1.0, n))
    dt = path.duration / (n - 1)
    fast_segs, _ = segment_path(bank, pts, dt, EPS)
    t0 = time.perf_counter()
    scan_segs, scan_info = reference_segment_path(bank, pts, dt, EPS, "scan")
    scan_t = time.perf_counter() - t0
    same_scan = key(scan_segs) == key(fast_segs)
    print(
        f"\nexhaustive scan of every arc window (no bounds), 1,000 primitives: {scan_t:.1f} s, "
        f"{scan_info['scored']:,} windows scored over {scan_info['probes']} probes"
    )
    print(f"  same segmentation as the pruned index search: {same_scan}")
    assert same_scan, f"scan {key(scan_segs)} != index {key(fast_segs)}"

    k_ex = 1000 if args.full_grid else 100
    bank_g = indexes[k_ex]
    fast_g_t, (fast_g, _) = median_time(lambda: segment_path(bank_g, pts, dt, EPS), 1)
    t0 = time.perf_counter()
    grid_segs, grid_info = reference_segment_path(bank_g, pts, dt, EPS, "grid")
    grid_t = time.perf_counter() - t0
    same_grid = key(grid_segs) == key(fast_g)
    print(
        f"\nexhaustive time-uniform grid search, {k_ex} primitives: {grid_t:.1f} s, "
        f"{grid_info['windows']:,} candidates over {grid_info['probes']} probes"
    )
    print(f"  same segmentation as the index search: {same_grid}")
    if k_ex == 100:
        assert same_grid, f"grid {key(grid_segs)} != index {key(fast_g)}"
    elif not same_grid:
        print(f"  grid {key(grid_segs)}\n  index {key(fast_g)}")

    # -- per-candidate Kabsch loop: rate on one probe's windows, scaled to the scan's
    k_q = 16
    q = PathPiece(pts, path.duration).at(np.linspace(0.0, segs[0].end, k_q))
    win = np.lib.stride_tricks.sliding_window_view(bank.points, k_q, axis=0)
    sub = np.arange(0, 3000 * 37, 37)
    t0 = time.perf_counter()
    for m in sub:
        kabsch(win[m].T, q)
    rate = sub.size / (time.perf_counter() - t0)
    loop_t = scan_info["scored"] / rate
    print(f"\nper-candidate Kabsch loop: {rate:,.0f} pairs/s ({sub.size} pairs of {k_q} points)")
    print(
        f"  scaled to the scan's {scan_info['scored']:,} windows: {loop_t:,.0f} s; "
        f"to the time grid's {grid_info['windows']:,} candidates ({k_ex} primitives): "
        f"{grid_info['windows'] / rate:,.0f} s"
    )

    build_t, read_t, _ = index_persistence(indexes[1000].bank, Path(tmp.name))

    # -- time against library size
    print("\nmatch time against library size (first call: median of 3 fresh opens; warm: of 5):")
    for k in sizes:
        w, m_k = warms[k]
        print(
            f"  {k:5d} primitives: first {first[k]:.3f} s (bank read {reads[k]:.3f} s), "
            f"warm {w:.3f} s, {len(m_k.segments)} segments, {m_k.info['probes']} probes"
        )
    growth = warms[1000][0] / warms[10][0]
    growth_first = first[1000] / first[10]
    print(
        f"  1,000 vs 10 primitives: warm x{growth:.1f}, first call x{growth_first:.1f} "
        "for x100 library (linear would be x100)"
    )

    print("\n| figure | value | baseline | ratio | command |")
    print("|---|---|---|---|---|")
    cmd = "`python benchmarks/bench_match.py`"
    print(
        f"| match, 1,000 prims x 2,000 samples, 2,400-sample path, first call (DuckDB read "
        f"+ index + segmentation) | {cold:.2f} s | goal 1 s; exhaustive scan {scan_t:.1f} s | "
        f"{'met' if cold <= 1.0 else 'NOT met'}; {scan_t / cold:,.1f}x | {cmd} |"
    )
    print(
        f"| same, warm | {warm:.2f} s | goal 0.5 s; "
        f"per-candidate Kabsch loop over the same windows {loop_t:,.0f} s (scaled) | "
        f"{'met' if warm <= 0.5 else 'NOT met'}; {loop_t / warm:,.0f}x | {cmd} |"
    )
    print(
        f"| exhaustive time grid, {k_ex} prims | {grid_t:.1f} s | index search {fast_g_t:.2f} s "
        f"| {grid_t / fast_g_t:,.0f}x | {cmd} |"
    )
    print(
        f"| match time, 10 -> 1,000 prims, warm / first call | x{growth:.1f} / "
        f"x{growth_first:.1f} | linear x100 | {100 / growth:.0f}x / {100 / growth_first:.0f}x "
        f"better | {cmd} |"
    )
    print(
        f"| index of 1,000 prims, rebuilt per process (arc-length index + envelopes) | "
        f"{build_t:.3f} s | read back from the library file {read_t:.3f} s | "
        f"{read_t / build_t:.1f}x "
        f"{'rebuilding is cheaper: not persisted' if read_t > build_t else 'reading is cheaper'} "
        f"| {cmd} |"
    )
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    for lb in libs.values():
        lb.close()
    tmp.cleanup()


if __name__ == "__main__":
    main()
