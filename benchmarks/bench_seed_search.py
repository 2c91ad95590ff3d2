"""Benchmark of the seed search alone (issue 13): the index searches a segmentation asks for
on novel paths, timed apart from the probes and the refinement.

The queries (a piece [a, b] of a path, and eps) are those ``segment_path`` asks the index
search for on ``--paths`` smooth random 3-D paths of 2,400 samples (``bench_match_novel``'s)
against the 14 bundled primitives or, with ``--big``, 1,000 random ones, recorded with this
tree. This tree and git revision ``--baseline`` (extracted with ``git archive``) then each
answer all of them in a process of their own, alternated ``--rounds`` times: a first pass
on a fresh ``BankIndex`` (the indexes the queries need are built inside it) and the best of
3 passes on the warm index, in CPU seconds (steadier than wall-clock on a shared machine);
medians over the rounds and their ratio. The seeds of the two trees are compared (the same
primitives, starts and ends within 1e-6 samples: the changes are meant to be exact).

Run: ``python benchmarks/bench_seed_search.py [--big] [--paths 2] [--baseline REV]
[--rounds 2]``.
"""

from __future__ import annotations

import argparse
import json
import pickle
import statistics
import tempfile
import time
from pathlib import Path

from _revisions import alternated

BASELINE = "7970a67"  # main before this session's seed-search changes


def record(library: str, paths: int, samples: int = 2400) -> list[dict]:
    """The index searches ``segment_path`` asks for on ``paths`` novel paths (this tree)."""
    import bench_match_novel as novel
    import numpy as np

    from primlib.match import BankIndex, default_eps, segment_path
    from primlib.match._index_search import IndexSearch

    bank, dt = novel._library(library)
    asked: list[dict] = []
    seeds = IndexSearch.seeds

    def spy(self, path, a, b, eps):
        asked.append({"points": path.points, "duration": path.duration, "a": a, "b": b,
                      "eps": eps})  # fmt: skip
        return seeds(self, path, a, b, eps)

    IndexSearch.seeds = spy
    try:
        for seed in range(paths):
            rng = np.random.default_rng(100 + seed)
            path = novel._walk(rng, samples, dt, max(8, samples // 200))
            pts = path.at(np.linspace(0.0, 1.0, samples))
            segment_path(BankIndex(bank), pts, path.duration / (samples - 1), default_eps(path))
    finally:
        IndexSearch.seeds = seeds
    return asked


def worker(spec: dict) -> dict:
    """Answer the recorded queries with the primlib importable here: first pass (fresh
    index) and best of 3 warm passes, CPU seconds; the seeds as (primitive, x0, x1)."""
    import bench_match_novel as novel

    from primlib.match import BankIndex
    from primlib.match._index_search import IndexSearch
    from primlib.match._options import PathPiece, SearchOptions

    bank, _ = novel._library(spec["library"])
    with open(spec["queries"], "rb") as f:
        queries = pickle.load(f)
    asked = [(PathPiece(q["points"], q["duration"]), q["a"], q["b"], q["eps"]) for q in queries]
    index = BankIndex(bank)
    search = IndexSearch(index, SearchOptions())
    t0 = time.process_time()
    out = [[(c.prim, c.x0, c.x1) for c in search.seeds(*q)] for q in asked]
    first = time.process_time() - t0
    warm = []
    for _ in range(3):
        search = IndexSearch(index, SearchOptions())
        t0 = time.process_time()
        for q in asked:
            search.seeds(*q)
        warm.append(time.process_time() - t0)
    return {"first": first, "warm": min(warm), "seeds": out}


def _same(new: list, old: list) -> int:
    """Queries whose seeds differ (another primitive, or an end moved by > 1e-6)."""
    return sum(len(x) != len(y) or any(p != q or abs(a - c) > 1e-6 or abs(b - d) > 1e-6
                                       for (p, a, b), (q, c, d) in zip(x, y, strict=True))
               for x, y in zip(new, old, strict=True))  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--big", action="store_true", help="1,000 random primitives")
    ap.add_argument("--paths", type=int, default=2)
    ap.add_argument("--baseline", default=BASELINE)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return
    library = "random-1000" if args.big else "bundled"
    with tempfile.TemporaryDirectory(prefix="bench_seeds_") as tmp:
        queries = Path(tmp) / "queries.pkl"
        with open(queries, "wb") as f:
            pickle.dump(record(library, args.paths), f)
        spec = json.dumps({"library": library, "queries": str(queries)})
        res = alternated(__file__, spec, args.baseline, args.rounds)
    new, old = res["this tree"], res[args.baseline]
    n = len(new[0]["seeds"])
    print(f"\nseed search alone, {library} library, {n} queries of {args.paths} novel paths "
          f"({args.rounds} rounds alternated; CPU seconds, medians)")  # fmt: skip
    print("| pass | this tree | baseline | ratio |")
    print("|---|---|---|---|")
    for key, name, unit in (("first", "first (indexes built)", 1.0), ("warm", "warm, a query", n)):
        a = statistics.median(r[key] for r in new) / unit
        b = statistics.median(r[key] for r in old) / unit
        scale, suffix = (1.0, "s") if unit == 1.0 else (1000.0, "ms")
        print(f"| {name} | {a * scale:.3f} {suffix} | {b * scale:.3f} {suffix} | {b / a:.2f}x |")
    differ = _same(new[0]["seeds"], old[0]["seeds"])
    print(f"queries whose seeds differ from the baseline's: {differ} of {n}; baseline: git "
          f"revision {args.baseline}")  # fmt: skip


if __name__ == "__main__":
    main()
