"""What the benchmarks of the index search against the exhaustive time-uniform grid share
(``bench_match_noisy.py``, ``bench_match_real.py``): one search of a query, timed; two
segmentations compared; and the cuts of joined paths against their true joins and against
each other."""

from __future__ import annotations

import time

from _reference_search import reference_segment_path

from primlib.match import segment_path

SEARCHES = ("grid", "index")


def run(bank, points, dt: float, eps: float, search: str):
    """(segments, seconds) of one search (``"index"``: primlib's; else a reference)."""
    t0 = time.perf_counter()
    if search == "index":
        segs, _ = segment_path(bank, points, dt, eps)
    else:
        segs, _ = reference_segment_path(bank, points, dt, eps, search)
    return segs, time.perf_counter() - t0


def compare(a, b, n: int) -> str:
    """``a`` (index) against ``b`` (grid): "cuts" when they cut elsewhere, "worse" when a
    segment names another primitive at an RMSD more than 1 % above the grid's, "better"
    when more than 1 % below, else "same" (primitives that hold the same piece, as the
    bundled lines and quarter arcs at two speeds do, are either of them the answer)."""
    if [round(s.end * n) for s in a] != [round(s.end * n) for s in b]:
        return "cuts"
    worse = better = False
    for x, y in zip(a, b, strict=True):
        if x.primitive != y.primitive and x.primitive is not None and y.primitive is not None:
            worse |= x.rmsd > 1.01 * y.rmsd
            better |= x.rmsd < y.rmsd / 1.01
    return "worse" if worse else "better" if better else "same"


def joined_cuts(bank, queries, dt: float) -> dict:
    """For paths of three pieces (each query has ``points``, ``eps`` and its true joins
    ``cuts``, first 0, last n): per search the paths cut in three matched pieces and the cut
    errors (samples) against the joins there; the paths where the index cuts elsewhere than
    the grid and the largest difference (n for a different number of cuts)."""
    errs: dict[str, list[int]] = {s: [] for s in SEARCHES}
    three = dict.fromkeys(SEARCHES, 0)
    vs, differ = [0], 0
    for q in queries:
        n = len(q.points) - 1
        cut = {}
        for s in SEARCHES:
            segs, _ = run(bank, q.points, dt, q.eps, s)
            cut[s] = [round(x.end * n) for x in segs[:-1]]
            if len(segs) == 3 and all(x.primitive is not None for x in segs):
                three[s] += 1
                errs[s] += [abs(c - t) for c, t in zip(cut[s], q.cuts[1:-1], strict=True)]
        differ += cut["grid"] != cut["index"]
        if len(cut["grid"]) == len(cut["index"]):
            vs += [abs(a - b) for a, b in zip(cut["index"], cut["grid"], strict=True)]
        else:
            vs.append(n)  # a different number of cuts: as far off as can be
    return {"errors": errs, "three": three, "differ": differ, "worst_vs_grid": max(vs)}


def print_joined(label: str, res: dict, count: int, first: str | None = None) -> None:
    """The rows (grid, index) of :func:`joined_cuts`' ``res`` on ``count`` paths, under the
    table's header when ``first`` (the first column's title) is given."""
    import statistics

    if first is not None:
        print(f"\n| {first} | search | paths cut in 3 | median |cut error| | worst | "
              "index vs grid: paths that differ, worst |\n|---|---|---|---|---|---|")  # fmt: skip
    for s in SEARCHES:
        e = res["errors"][s] or [0]
        w = f"{res['differ']}/{count}, {res['worst_vs_grid']}" if s == "index" else "-"
        print(f"| {label} | {s} | {res['three'][s]}/{count} | {statistics.median(e):g} | "
              f"{max(e)} | {w} |")  # fmt: skip
