"""Benchmark of the kept models: ``primlib match --out`` in a fresh process, the models the
warm start fits (grey-box and refined, :mod:`primlib.pipeline._fitted`) kept in the library
file against fitted anew.

Each round copies the library, drops its kept models, and runs the command twice in fresh
processes: the first fits the models (and keeps them: the baseline, what every process
paid before they were kept), the second reads them. It prints the median and worst wall
time of each and their ratio, and asserts that both wrote the same warm start, byte for byte.

The library: ``--db FILE --machine NAME --path CSV`` (e.g. one of ``bench_realism.py
--save-libraries``'s, where the fit took 50 s), or by default a stage library built here:
``--primitives`` loops of ``--samples`` samples learned by ILC on the example stage (Coulomb
friction and force ripple, ``examples/stage``), and a new path (a loop of another size,
rotated and moved).

Run: ``python benchmarks/bench_kept.py [--rounds 3] [--samples 1001] [--primitives 3]``,
``python benchmarks/bench_kept.py --db lib.duckdb --machine xyz --path new.csv``.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _revisions import checkout_env, without_kept

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the stage's helpers: a stage library by its own ILC
sys.path.insert(0, str(ROOT))  # this checkout's primlib, as in the processes it times


def stage_library(folder: Path, primitives: int, samples: int) -> tuple[Path, str, Path]:
    """A library of loops learned on the example stage, and a new path's CSV."""
    from stage_helpers import STAGE, add_loop, loop, nominal

    from primlib.pipeline import Library

    db = folder / "stage.duckdb"
    rng = np.random.default_rng(0)
    with Library(db) as lib:
        lib.add_machine(nominal())
        for k in range(primitives):
            size, turns, phase = rng.uniform(8, 15), rng.uniform(0.75, 1.5), rng.uniform(0, 3)
            origin = tuple(rng.uniform(10, 75, 2))
            add_loop(lib, loop(samples, size, turns, phase), origin, f"loop-{k}")
    pts = loop(601, 9.0, 1.2, 0.8)
    a = np.deg2rad(30.0)
    new = (pts - pts[0]) @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    new += np.array([60.0, 30.0])
    csv = folder / "new.csv"
    t = np.arange(len(new)) * STAGE.dt
    np.savetxt(csv, np.column_stack([t, new]), delimiter=",", header="t,x,y", comments="")
    return db, "stage", csv


def _match(db: Path, machine: str, path: Path, out: Path) -> float:
    """Wall seconds of one fresh ``primlib match --out`` process."""
    args = ["--db", str(db), "match", str(path), "--machine", machine, "--out", str(out)]
    t0 = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-m", "primlib", *args], env=checkout_env(), capture_output=True, text=True
    )
    seconds = time.perf_counter() - t0
    if run.returncode != 0:
        sys.exit(f"primlib match failed: {run.stderr.strip()}")
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--db", type=Path, help="a library file (default: build a stage library)")
    ap.add_argument("--machine", default="stage", help="its machine (with --db)")
    ap.add_argument("--path", type=Path, help="the new path's CSV (with --db)")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of (fit, read) (default 3)")
    ap.add_argument("--primitives", type=int, default=3, help="stage library: primitives")
    ap.add_argument("--samples", type=int, default=1001, help="stage library: samples each")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.db is None:
            db, machine, path = stage_library(folder, args.primitives, args.samples)
        else:
            if args.path is None:
                ap.error("--db needs --path (the new path's CSV)")
            db, machine, path = Path(args.db), args.machine, args.path
            from primlib.store import Store

            work = folder / "lib.duckdb"
            shutil.copyfile(db, work)
            Store(work).close()  # an older library migrated here, never the caller's file
            db = work
        fit, read = [], []
        for r in range(args.rounds):
            lib = folder / f"round{r}.duckdb"
            without_kept(db, lib)
            fit.append(_match(lib, machine, path, folder / "fit.csv"))
            read.append(_match(lib, machine, path, folder / "read.csv"))
            same = (folder / "fit.csv").read_bytes() == (folder / "read.csv").read_bytes()
            assert same, "the warm start from the kept models differs from the fitted one"
    f, k = statistics.median(fit), statistics.median(read)
    print(f"primlib match --out, fresh process, {args.rounds} rounds (machine {machine}):")
    print(f"  models fitted (the baseline): median {f:.2f} s, worst {max(fit):.2f} s")
    print(f"  models kept, read back:       median {k:.2f} s, worst {max(read):.2f} s")
    print(f"  ratio {f / k:.1f}x faster; the same warm start, byte for byte, in every round")


if __name__ == "__main__":
    main()
