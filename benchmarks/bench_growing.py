"""Benchmark of a growing library: the warm start of a path the library has not been asked
for, and of one right after it took in a new primitive, this tree against a baseline revision
in the same run.

Before stop 46 a machine's models were fitted on every primitive and the linear model was
refined on the primitives each path matched (plus others up to 24), so on a library of more
than 24 primitives every new path, and every warm start after an ingest, fitted them again.

The library: ``--primitives`` smooth random 3-D primitives of 2,000 samples
(``bench_serve.py``'s), each stored with the exact input of ``bench_warm_start.py``'s true
machine (+8 % gain, +15 % time constant, a 12 ms lag: not the nominal model the library
holds), so the first trial's error on that machine says what the models are worth beside
the time. New paths: five pieces of random primitives, rotated and time-scaled
(``bench_serve.py``'s composition), ``--paths`` of them, each asked for once; then
``--ingests`` primitives taken in one at a time, a new path's warm start after each. Each
tree runs in a fresh process of its own (single-threaded, :mod:`_revisions`) on a copy of
the same file, alternated round by round.

Printed per tree: the first warm start (it fits the models), a new path's (median, worst),
one after an ingest (median, worst), and the new paths' first-trial RMS error on the true
machine (median, worst), with this tree's time over the baseline's.

Run: ``python benchmarks/bench_growing.py [--primitives 1000] [--paths 5] [--ingests 3]
[--baseline 918e29b] [--rounds 1]``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _pieces import joined
from _revisions import alternated, run_worker

ROOT = Path(__file__).resolve().parents[1]
if "--worker" not in sys.argv:  # a worker runs the primlib its PYTHONPATH names
    sys.path.insert(0, str(ROOT))  # this checkout's primlib when run from a checkout
sys.path.insert(0, str(ROOT / "tests"))  # the stage's helpers

EPS = 0.05
AFTER = 100  # samples of a new path's start left out of its error (bench_realism.py's)
N_SAMPLES = 2000
PIECES = [(0.05, 0.6, 480), (0.30, 0.8, 481), (0.10, 1.0, 481), (0.40, 1.3, 481),
          (0.20, 1.7, 481)]  # fmt: skip


def machines():
    """(nominal XYZ stage, the true machine that runs the inputs)."""
    from bench_warm_start import true_machine

    from primlib.plant import Machine

    nominal = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    return nominal, true_machine(nominal)


def primitive(rng, true):
    """A smooth random 3-D motion from rest to rest (a clamped cubic B-spline of 24 control
    points, ~100 mm, run along a quintic smoothstep in time) and the true machine's exact
    input for it (a motion that starts moving at t = 0 has none: the machine starts at rest)."""
    from primlib.nurbs import Trajectory
    from primlib.plant import invert

    m, p = 24, 3
    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 12.0, axis=0)
    knots = np.concatenate([np.zeros(p), np.linspace(0.0, 1.0, m - p + 1), np.ones(p)])
    shape = Trajectory.from_definition(p, knots, ctrl, None, 1.0)
    t = np.linspace(0.0, 1.0, N_SAMPLES)
    pts = shape.at(t**3 * (10.0 - 15.0 * t + 6.0 * t * t))
    traj = Trajectory.from_samples(pts, true.dt)
    pts = traj.sample(true.dt)
    return traj, invert(true, pts - pts[0])


def build(db: Path, k: int) -> None:
    """The library file of ``k`` primitives."""
    from primlib.pipeline import Library

    nominal, true = machines()
    rng = np.random.default_rng(0)
    with Library(db) as lib:
        lib.add_machine(nominal)
        items = [(*primitive(rng, true), f"r{i}", None) for i in range(k)]
        lib.add_many(items, nominal.name)


def new_path(lib, seed: int):
    """Five pieces of random primitives of the library, rotated and time-scaled."""
    bank = lib.bank("xyz")
    rng = np.random.default_rng(1000 + seed)
    rows = rng.choice(len(bank.ids), size=len(PIECES), replace=False)
    pieces = [(bank.trajectory(int(r)), *piece) for r, piece in zip(rows, PIECES, strict=True)]
    return joined(pieces, rng, bank.dt)


def _timed_warm(lib, path, run, origin=None) -> tuple[float, float]:
    """(seconds of the warm start, its first-trial RMS error on the machine that runs it,
    ``run(u)``, past the first ``AFTER`` samples: a new XYZ path is already moving at t = 0,
    which no input makes)."""
    name = lib.machines()[0]
    t0 = time.perf_counter()
    ws = lib.warm_start(path, name, eps=EPS, origin=origin)
    seconds = time.perf_counter() - t0
    ref = path.sample(lib.machine(name).dt)
    e2 = np.sum((run(ws.u) - (ref - ref[0])) ** 2, axis=1)
    return seconds, float(np.sqrt(np.mean(e2[AFTER:])))


def _xyz_case(lib):
    """(new path j -> (path, origin), run(u, origin), add one primitive) on the XYZ library."""
    _, true = machines()
    rng = np.random.default_rng(99)

    def add(j: int) -> None:
        lib.add(*primitive(rng, true), "xyz", name=f"new{j}")

    return (lambda j: (new_path(lib, j), None)), (lambda u, o: true.simulate(u)), add


def _stage_case(lib):
    """The same on the stage library: loops of other sizes, turned, at random places."""
    from stage_helpers import STAGE, add_loop, loop

    from primlib.nurbs import Trajectory

    rng = np.random.default_rng(99)

    def path(j: int):
        r = np.random.default_rng(1000 + j)
        pts = loop(601, r.uniform(8, 15), r.uniform(0.75, 1.5), r.uniform(0, 3))
        a = r.uniform(0, 2 * np.pi)
        pts = pts @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
        origin = r.uniform(15, 70, 2)
        return Trajectory.from_samples(pts + origin, STAGE.dt), origin

    def add(j: int) -> None:
        origin = tuple(rng.uniform(10, 75, 2))
        pts = loop(401, rng.uniform(8, 15), rng.uniform(0.75, 1.5), rng.uniform(0, 3))
        add_loop(lib, pts, origin, f"new{j}")

    return path, (lambda u, o: STAGE.simulate(u, start=o)), add


def worker(arg: str) -> dict:
    """One tree's figures on a copy of the library (``arg``: JSON of db, kind, paths,
    ingests)."""
    import primlib
    from primlib.pipeline import Library

    job = json.loads(arg)
    with tempfile.TemporaryDirectory(prefix="bench_growing_") as folder:
        db = Path(folder) / "lib.duckdb"
        shutil.copy(job["db"], db)
        with Library(db) as lib:
            path, run, add = (_stage_case if job["kind"] == "stage" else _xyz_case)(lib)

            def timed(j: int) -> tuple[float, float]:
                p, origin = path(j)
                return _timed_warm(lib, p, lambda u: run(u, origin), origin)

            first = timed(0)
            paths = [timed(1 + j) for j in range(job["paths"])]
            after = []
            for j in range(job["ingests"]):
                add(j)
                after.append(timed(100 + j)[0])
    return {"first": first[0], "paths": [p[0] for p in paths], "errors": [p[1] for p in paths],
            "after": after, "primlib": primlib.__file__}  # fmt: skip


def _row(label: str, values: list[float], base: list[float] | None, unit: str = "s") -> str:
    med, worst = statistics.median(values), max(values)
    text = f"{label:<38} {med:10.3g} {worst:10.3g} {unit}"
    if base:
        text += f"   baseline {statistics.median(base):10.3g} {max(base):10.3g}"
        text += f"   ratio {med / statistics.median(base):.3g}"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--primitives", type=int, default=1000)
    ap.add_argument(
        "--stage",
        action="store_true",
        help="the example stage (friction, ripple): loops learned on it by ILC",
    )
    ap.add_argument("--samples", type=int, default=401, help="samples per loop (--stage)")
    ap.add_argument("--paths", type=int, default=5, help="new paths asked for")
    ap.add_argument("--ingests", type=int, default=3, help="primitives taken in, one by one")
    ap.add_argument("--baseline", default="918e29b", help="revision to compare with")
    ap.add_argument("--no-baseline", action="store_true")
    ap.add_argument("--rounds", type=int, default=1)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker)))
        return
    with tempfile.TemporaryDirectory(prefix="bench_growing_") as folder:
        db = Path(folder) / "lib.duckdb"
        t0 = time.perf_counter()
        if args.stage:
            from bench_kept import stage_library  # (it puts this checkout first on sys.path)

            db = stage_library(Path(folder), args.primitives, args.samples)[0]
            what = f"loops of {args.samples} samples learned on the example stage"
        else:
            build(db, args.primitives)
            what = f"XYZ motions of {N_SAMPLES} samples, the true machine's exact inputs"
        print(f"library: {args.primitives} {what}, built in {time.perf_counter() - t0:.1f} s")
        kind = "stage" if args.stage else "xyz"
        job = json.dumps({"db": str(db), "kind": kind, "paths": args.paths,
                          "ingests": args.ingests})  # fmt: skip
        if args.no_baseline:
            res = {"this tree": [run_worker(__file__, job, ROOT)]}
        else:
            res = alternated(__file__, job, args.baseline, args.rounds)
    labels = list(res)
    used = {label: {r["primlib"] for r in res[label]} for label in labels}
    if len(labels) == 2 and used[labels[0]] & used[labels[1]]:
        raise SystemExit(f"both trees ran the same primlib ({used[labels[0]]}): not a comparison")
    base = None if len(labels) == 1 else res[labels[1]]
    print(f"{'figure (median, worst)':<38} {'this tree':>21}" + (f"   {labels[1]}" if base else ""))
    for key, label, unit in (("first", "first warm start (fits the models)", "s"),
                             ("paths", "a new path's warm start", "s"),
                             ("after", "a warm start after an ingest", "s"),
                             ("errors", "new paths: error past 100 samples", "mm")):  # fmt: skip
        mine = [v for r in res["this tree"] for v in np.atleast_1d(r[key])]
        theirs = None if base is None else [v for r in base for v in np.atleast_1d(r[key])]
        print(_row(label, mine, theirs, unit))


if __name__ == "__main__":
    main()
