"""The composed-path case of ``bench_match.py``, importable with any revision's primlib.

A library of k random primitives (1,000 of 2,000 samples), a 2,400-sample path composed of
5 rotated, translated, time-scaled pieces of them, and the first-call and warm timings of
``Library.match`` on it. Run as a script (``--worker SPEC``) it times the primlib found on
``PYTHONPATH`` — so ``bench_match.py --composed --baseline REV`` can time another
revision's tree in the same run (it never puts this repository on ``sys.path``).
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _pieces import joined

from primlib.match import BankIndex, match_path
from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.plant import Machine

__all__ = ["N_SAMPLES", "EPS", "PIECES", "random_primitive", "build_library", "first_call",
           "build_path", "worker"]  # fmt: skip

N_SAMPLES = 2000
EPS = 0.05
# (primitive, start v, time scale k, samples of the new path) for the 5 pieces
PIECES = [(0, 0.05, 0.6, 480), (1, 0.30, 0.8, 481), (2, 0.10, 1.0, 481), (3, 0.40, 1.3, 481),
          (4, 0.20, 1.7, 481)]  # fmt: skip


def random_primitive(rng: np.random.Generator, dt: float) -> Trajectory:
    """A smooth random 3-D motion: clamped cubic B-spline, 24 control points, ~100 mm wide."""
    m, p = 24, 3
    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 12.0, axis=0)
    knots = np.concatenate([np.zeros(p), np.linspace(0.0, 1.0, m - p + 1), np.ones(p)])
    return Trajectory.from_definition(p, knots, ctrl, None, (N_SAMPLES - 1) * dt)


def build_library(k: int, machine: Machine, seed: int = 0, db: Path | None = None) -> Library:
    """k random primitives (the first k of one seeded sequence), in memory or in ``db``."""
    rng = np.random.default_rng(seed)
    lib = Library(db)
    lib.add_machine(machine)
    zeros = np.zeros((N_SAMPLES, 3))
    items = [(random_primitive(rng, machine.dt), zeros, f"r{i}", None) for i in range(k)]
    lib.add_many(items, machine.name)
    return lib


def first_call(db: Path, machine: str, path: Trajectory, repeat: int = 3):
    """Median time of the first ``match`` on a freshly opened library file (DuckDB read,
    index build, segmentation) and of its bank read alone; the last Match; the median CPU
    seconds of the first match (all of the process's threads: DuckDB reads with several)."""
    times, reads, cpus, mt = [], [], [], None
    for _ in range(repeat):
        with Library(db) as lb:
            c0, t0 = time.process_time(), time.perf_counter()
            mt = lb.match(path, machine=machine, eps=EPS)
            times.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        with Library(db) as lb:
            t0 = time.perf_counter()
            lb.bank(machine)
            reads.append(time.perf_counter() - t0)
    return statistics.median(times), statistics.median(reads), mt, statistics.median(cpus)


def build_path(lib: Library, machine: Machine, seed: int = 1):
    """The 5 pieces, each rotated at random, joined end to start, fitted as one path."""
    bank = lib.bank(machine.name)
    pieces = [(bank.trajectory(row), v0, k, n) for row, v0, k, n in PIECES]
    path = joined(pieces, np.random.default_rng(seed), machine.dt)
    return path, [int(bank.ids[row]) for row, *_ in PIECES]


def worker(spec: dict) -> dict:
    """First calls (fresh opens of a library file written here) and warm calls of the
    composed path against ``spec["k"]`` primitives: medians (wall and CPU seconds), and
    the segments' keys."""
    machine = Machine.from_json(Path(spec["root"]) / "data" / "machines" / "xyz.json")
    with tempfile.TemporaryDirectory(prefix="bench_composed_") as folder:
        db = Path(folder) / "lib.duckdb"
        build_library(spec["k"], machine, db=db).close()
        with Library(db) as lb:
            path, _ = build_path(lb, machine)
            bank = lb.bank(machine.name)
        first, _, mt, first_cpu = first_call(db, machine.name, path, spec["first"])
    index = BankIndex(bank)
    match_path(index, path, eps=EPS)
    warm, warm_cpu = [], []
    for _ in range(spec["warm"]):
        c0, t0 = time.process_time(), time.perf_counter()
        match_path(index, path, eps=EPS)
        warm.append(time.perf_counter() - t0)
        warm_cpu.append(time.process_time() - c0)
    keys = [(round(s.end, 9), s.primitive) for s in mt.segments]
    return {"first": first, "warm": statistics.median(warm), "first_cpu": first_cpu,
            "warm_cpu": statistics.median(warm_cpu), "segments": keys}  # fmt: skip


if __name__ == "__main__" and len(sys.argv) == 3 and sys.argv[1] == "--worker":
    print(json.dumps(worker(json.loads(sys.argv[2]))))
