"""Benchmark of matching noisy queries (issue 13): the index search against the exhaustive
time-uniform grid (``grid`` of ``_reference_search.py``) on the same queries.

Queries: a stored piece (60-100 % of a primitive of the bundled library ``data/library``,
or with ``--big`` of 1,000 random primitives), rotated at random, translated, time-scaled by
k = stored / new duration in [0.5, 2] (log-uniform), sampled at the machine's dt, with white
noise of σ = 0.1 % and 1 % of the piece's extent on every axis; eps = 2 × the noise RMS
(σ·√d, what the Kabsch RMSD of the noise alone is). A query is *answered* when the
segmentation is one matched segment whose stored piece, carried through its transform, lies
within eps of the noise-free query (any stored piece within eps of the truth is a right
answer: the bundled lines are pieces of one another). Printed per noise level and search:
queries answered, median and worst time per query, the index's time over the grid's (ratio)
and the queries where the two disagree (:func:`compare`).

With ``--deformed N``, N noise-free stored pieces per case bent by a smooth wiggle of RMS
eps / 2 (1-3, 5-15 or 20-60 periods per piece; eps 1 % and 3 % of the extent): whole shapes
within eps of one stored shape, which must come out as one segment, as from the grid.

With ``--stored-noise``, the same queries against the library with white noise of the same
level on every stored primitive (noise in a stored path must not change the answer either).

With ``--unmatched``, the same single queries at a quarter of their eps (σ·√d / 2, half
what the noise alone leaves): nothing is within it, so a path comes out unmatched or in short
pieces; the time of that against the same query's time at its eps.

Junctions: paths joined from 3 stored pieces (rotated, time-scaled, noise as above); the cut
errors in samples of each search against the true joins, and the index's cuts against the
grid's.

Goal (issue 13): >= 59 of 60 answered at each noise level, as the grid; index cuts where the
grid cuts.

With ``--unmatched-only --copies N``, the unmatched table on a library of N copies of the
bundled primitives, each turned and moved (realistic primitives, at rest at their ends, in a
bank past the roughness table's size from 17 copies on).

Run: ``python benchmarks/bench_match_noisy.py [--queries 60] [--joined 10] [--big]
[--stored-noise] [--deformed 14] [--unmatched] [--unmatched-only [--copies 24]]``.
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
from _noise import white_noise  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

from primlib.match import BankIndex, matched_pieces  # noqa: E402
from primlib.store import Bank  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DT = 0.005  # data/machines/xyz.json
NOISE = (0.001, 0.01)  # σ / extent of the piece
SCALES = (0.5, 2.0)  # k = stored duration / new duration


@dataclass(frozen=True)
class Query:
    """Noisy samples, the noise-free ones, eps, the source row and the true cuts (samples)."""

    points: np.ndarray
    clean: np.ndarray
    eps: float
    row: int
    cuts: tuple[int, ...]


def library(kind: str) -> BankIndex:
    """The bundled library (14 primitives) or 1,000 random smooth 3-D primitives."""
    if kind == "bundled":
        from primlib.nurbs import Trajectory

        files = sorted(f for f in (ROOT / "data" / "library").glob("*.csv")
                       if not f.name.endswith(".signal.csv"))  # fmt: skip
        pieces = [Trajectory.from_csv(f).sample(DT) for f in files]
        names = [f.stem for f in files]
        return BankIndex(Bank.from_samples(pieces, DT, names=names))
    rng = np.random.default_rng(0)
    pieces = []
    for _ in range(1000):
        n = int(rng.integers(400, 2001))
        t = np.linspace(0.0, 1.0, n)[:, None, None]
        f = np.arange(1, 5)[None, :, None]
        amp = rng.normal(size=(1, 4, 3)) * 30.0 / f**1.5
        ph = rng.uniform(0, 2 * np.pi, size=(1, 4, 3))
        pieces.append((amp * np.sin(2 * np.pi * f * t + ph)).sum(axis=1))
    return BankIndex(Bank.from_samples(pieces, DT))


def copies_library(copies: int, seed: int = 7) -> BankIndex:
    """``copies`` copies of the bundled primitives, each copy turned and moved at random: a
    library of realistic primitives (at rest at their ends) past the roughness table's 131,072
    samples from 17 copies on, whose bound is then taken from the differences
    (``primlib/match/_rough_diff.py``). Its first 14 rows are the bundled primitives turned,
    so :func:`single_queries` draws from them."""
    small = library("bundled")
    rng = np.random.default_rng(seed)
    pieces = []
    for _ in range(copies):
        turn = Rotation.random(random_state=int(rng.integers(2**31))).as_matrix()
        pieces += [small.points_of(j) @ turn.T + rng.uniform(-50, 50, small.dim)
                   for j in range(small.k)]  # fmt: skip
    return BankIndex(Bank.from_samples(pieces, DT))


def noisy_library(bank: BankIndex, level: float, seed: int) -> BankIndex:
    """``bank`` with white noise of σ = ``level`` × each primitive's extent on every axis."""
    rng = np.random.default_rng(seed)
    pieces = []
    for i in range(bank.k):
        p = bank.points_of(i)
        pieces.append(p + rng.normal(scale=level * float(np.ptp(p, axis=0).max()), size=p.shape))
    return BankIndex(Bank.from_samples(pieces, DT, ids=bank.ids, names=bank.names))


def _piece(bank: BankIndex, row: int, rng) -> np.ndarray:
    """60-100 % of primitive ``row``, time-scaled, rotated at random (noise-free)."""
    src = bank.points_of(row)
    n_p = src.shape[0]
    frac = rng.uniform(0.6, 1.0)
    v0 = rng.uniform(0.0, 1.0 - frac)
    k = float(np.exp(rng.uniform(*np.log(SCALES))))
    n_out = max(int(round(frac * (n_p - 1) / k)) + 1, 16)
    spl = CubicSpline(np.linspace(0.0, 1.0, n_p), src, axis=0)
    pts = spl(np.linspace(v0, v0 + frac, n_out))
    return pts @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T


def _noisy(clean: np.ndarray, level: float, rng) -> tuple[np.ndarray, float]:
    """``clean`` with white noise of σ = ``level`` × its extent, and eps = 2× the noise's RMS."""
    noisy, rms = white_noise(clean, level, rng)
    return noisy, 2.0 * rms


def single_queries(bank: BankIndex, count: int, level: float, seed: int) -> list[Query]:
    """``count`` noisy stored pieces (module notes), primitives in turn."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        row = i % bank.k
        clean = _piece(bank, row, rng) + rng.uniform(-50, 50, size=bank.dim)
        noisy, eps = _noisy(clean, level, rng)
        out.append(Query(noisy, clean, eps, row, (0, clean.shape[0] - 1)))
    return out


def deformed_queries(bank: BankIndex, count: int, frac: float, seed: int, periods: int = 1,
                     rms: float = 0.5) -> list[Query]:  # fmt: skip
    """``count`` noise-free stored pieces bent by a smooth deformation (3 sinusoids of 1, 2
    and 3 times ``periods`` periods per axis) of RMS ``rms`` × eps, eps = ``frac`` × the
    piece's extent: whole shapes within eps of one stored shape, not composed of pieces
    (issue 13: such a path must not be cut into pieces of others)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        row = i % bank.k
        clean = _piece(bank, row, rng)
        eps = frac * float(np.ptp(clean, axis=0).max())
        t = np.linspace(0.0, 1.0, clean.shape[0])[:, None, None]
        f = periods * np.arange(1, 4)[None, :, None]
        wave = (
            rng.normal(size=(1, 3, bank.dim))
            / f
            * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi, (1, 3, bank.dim)))
        ).sum(axis=1)
        wave *= rms * eps / np.sqrt(np.mean(np.sum(wave**2, axis=1)))
        out.append(Query(clean + wave, clean, eps, row, (0, clean.shape[0] - 1)))
    return out


def joined_queries(bank: BankIndex, count: int, level: float, seed: int) -> list[Query]:
    """``count`` paths of 3 noisy stored pieces of distinct primitives joined end to start."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(count):
        rows = rng.choice(bank.k, size=3, replace=False)
        parts, cuts, last = [], [0], np.zeros(bank.dim)
        for row in rows:
            p = _piece(bank, int(row), rng)
            p += last - p[0]
            last = p[-1]
            parts.append(p if not parts else p[1:])
            cuts.append(cuts[-1] + p.shape[0] - 1)
        clean = np.concatenate(parts)
        noisy, eps = _noisy(clean, level, rng)
        out.append(Query(noisy, clean, eps, int(rows[0]), tuple(cuts)))
    return out


def run(bank: BankIndex, q: Query, search: str):
    """(segments, seconds) of one search on one query."""
    return _against_grid.run(bank, q.points, DT, q.eps, search)


def answered(bank: BankIndex, q: Query, segs) -> bool:
    """One matched segment whose stored piece lies within eps of the noise-free query."""
    if len(segs) != 1 or segs[0].primitive is None:
        return False
    piece = matched_pieces(segs, bank, n=q.clean.shape[0])[0]
    return float(np.sqrt(np.mean(np.sum((piece - q.clean) ** 2, axis=1)))) <= q.eps


def _levels(bank: BankIndex, count: int, head: tuple[str, ...]):
    """A table's header printed, then each noise level with its single queries."""
    print("| " + " | ".join(head) + " |")
    print("|---" * len(head) + "|")
    for j, level in enumerate(NOISE):
        yield level, single_queries(bank, count, level, seed=10 + j)


def single_table(bank: BankIndex, count: int, stored_noise: bool = False) -> dict:
    """Answered, times and disagreements per noise level and search (printed); with
    ``stored_noise`` the searched library has noise of the same level (:func:`noisy_library`)
    and the queries are drawn from ``bank``."""
    out = {}
    head = ("noise σ", "search", "answered", "median s", "worst s", "median ratio",
            "other cuts / worse / better primitive than the grid")  # fmt: skip
    for j, (level, qs) in enumerate(_levels(bank, count, head)):
        lib = noisy_library(bank, level, seed=30 + j) if stored_noise else bank
        res = {s: [run(lib, q, s) for q in qs] for s in ("grid", "index")}
        ok = {s: sum(answered(lib, q, r[0]) for q, r in zip(qs, res[s], strict=True))
              for s in res}  # fmt: skip
        cmp = [compare(a[0], b[0], len(q.points) - 1)
               for q, a, b in zip(qs, res["index"], res["grid"], strict=True)]  # fmt: skip
        diff = {c: cmp.count(c) for c in ("cuts", "worse", "better")}
        ratio = statistics.median(a[1] / b[1] for a, b in zip(res["index"], res["grid"],
                                                                strict=True))  # fmt: skip
        for s in ("grid", "index"):
            t = [r[1] for r in res[s]]
            rr = f"{ratio:.2f}" if s == "index" else "1"
            dd = " / ".join(str(v) for v in diff.values()) if s == "index" else "-"
            print(f"| {100 * level:g} % | {s} | {ok[s]}/{count} | {statistics.median(t):.3f} | "
                  f"{max(t):.3f} | {rr} | {dd} |")  # fmt: skip
        out[level] = {"answered": ok, "differ": diff, "ratio": ratio}
    return out


def unmatched_table(bank: BankIndex, count: int, searches=("grid", "index")) -> dict:
    """The queries of :func:`single_table` at a quarter of their eps (σ·√d / 2, about half
    the RMSD the noise alone leaves over a whole query: the query cannot match whole, and
    comes out unmatched or in short pieces, where a fit absorbs more of the noise): per
    search the matched fraction, the segments and the time, and the index's time over its own
    on the same queries at their eps (issue 13: a path that does not match must cost about
    what one that matches does). ``searches``: ("index",) leaves the grid out (on 1,000
    primitives it takes minutes a query)."""
    out = {}
    print()
    head = ("noise σ", "search", "matched, median (worst)", "segments, median", "median s",
            "worst s", "time / the same query matched, median (worst)")  # fmt: skip
    for level, qs in _levels(bank, count, head):
        hit = [run(bank, q, "index") for q in qs]
        low = [Query(q.points, q.clean, q.eps / 4.0, q.row, q.cuts) for q in qs]
        res = {s: [run(bank, q, s) for q in low] for s in searches}
        ratio = [r[1] / h[1] for r, h in zip(res["index"], hit, strict=True)]
        out[level] = {"ratio": statistics.median(ratio), "worst_ratio": max(ratio)}
        for s in searches:
            frac = [sum(x.end - x.start for x in r[0] if x.primitive is not None)
                    for r in res[s]]  # fmt: skip
            t = [r[1] for r in res[s]]
            segs = statistics.median(len(r[0]) for r in res[s])
            rr = f"{statistics.median(ratio):.2f} ({max(ratio):.2f})" if s == "index" else "-"
            print(f"| {100 * level:g} % | {s} | {100 * statistics.median(frac):.0f} % "
                  f"({100 * max(frac):.0f} %) | {segs:g} | {statistics.median(t):.3f} | "
                  f"{max(t):.3f} | {rr} |")  # fmt: skip
            out[level][s] = {"matched": statistics.median(frac), "median_s": statistics.median(t)}
    return out


def junction_table(bank: BankIndex, count: int) -> dict:
    """Cut errors (samples) against the true joins, per search, and index against grid."""
    out = {}
    for j, level in enumerate(NOISE):
        res = joined_cuts(bank, joined_queries(bank, count, level, seed=20 + j), DT)
        print_joined(f"{100 * level:g} %", res, count, first="noise σ" if j == 0 else None)
        out[level] = {"three": res["three"], "worst_vs_grid": res["worst_vs_grid"]}
    return out


def deformed_table(bank: BankIndex, count: int) -> dict:
    """Noise-free stored pieces bent by a smooth wiggle of RMS eps / 2 (:func:`deformed_queries`):
    one matched segment, per search, and the index against the grid (printed)."""
    print("\n| eps / extent | wiggle periods | grid: one segment | index: one segment | "
          "other cuts / worse / better primitive than the grid |")  # fmt: skip
    print("|---|---|---|---|---|")
    out = {}
    for frac in (0.01, 0.03):
        for periods in (1, 5, 20):
            qs = deformed_queries(bank, count, frac, seed=40, periods=periods)
            res = {s: [run(bank, q, s)[0] for q in qs] for s in ("grid", "index")}
            one = {s: sum(len(r) == 1 and r[0].primitive is not None for r in res[s])
                   for s in res}  # fmt: skip
            cmp = [compare(a, b, len(q.points) - 1)
                   for q, a, b in zip(qs, res["index"], res["grid"], strict=True)]  # fmt: skip
            diff = " / ".join(str(cmp.count(c)) for c in ("cuts", "worse", "better"))
            print(f"| {100 * frac:g} % | {periods}-{3 * periods} | {one['grid']}/{count} | "
                  f"{one['index']}/{count} | {diff} |")  # fmt: skip
            out[(frac, periods)] = one
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--queries", type=int, default=60, help="single pieces per noise level")
    ap.add_argument("--joined", type=int, default=10, help="3-piece paths per noise level")
    ap.add_argument("--big", action="store_true", help="also 1,000 random primitives")
    ap.add_argument("--stored-noise", action="store_true", help="also a noisy library")
    ap.add_argument("--deformed", type=int, default=0, help="smoothly bent pieces per case")
    ap.add_argument("--unmatched", action="store_true",
                    help="also the queries at a quarter of eps (nothing matches)")  # fmt: skip
    ap.add_argument("--unmatched-only", action="store_true",
                    help="only the unmatched table, by the index alone (with --big: fast enough "
                         "for 1,000 primitives)")  # fmt: skip
    ap.add_argument("--copies", type=int, default=0,
                    help="with --unmatched-only: instead, a library of this many copies of the "
                         "bundled primitives, turned (24: 188,016 samples)")  # fmt: skip
    args = ap.parse_args()
    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    kinds = ["bundled", "random-1000"] if args.big else ["bundled"]
    if args.copies:
        kinds = [f"bundled x {args.copies}"]
    for kind in kinds:
        bank = copies_library(args.copies) if args.copies else library(kind)
        print(f"\n{kind} library ({bank.k} primitives), eps = 2 x noise RMS")
        if args.unmatched_only:
            unmatched_table(bank, args.queries, searches=("index",))
            continue
        if args.queries:
            single_table(bank, args.queries)
        if args.queries and args.stored_noise:
            print("\nthe same queries against the library with noise of the same level")
            single_table(bank, args.queries, stored_noise=True)
        if args.queries and args.unmatched:
            unmatched_table(bank, args.queries)
        if args.joined:
            junction_table(bank, args.joined)
        if args.deformed:
            deformed_table(bank, args.deformed)
    print(f"\nload average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
