"""Load benchmark of ``primlib serve``: concurrent warm starts while one client ingests.

    python benchmarks/bench_serve.py [--duration 60] [--primitives 1000] [--clients 8]
    python benchmarks/bench_serve.py --duration 3 --primitives 6 --clients 2 --samples 400  # smoke

A library file of ``--primitives`` random smooth 3-D primitives (2,000 samples each, as in
bench_match.py) is served by ``primlib serve`` started as its own process. For
``--duration`` seconds, ``--clients`` threads (each a :class:`primlib.client.Client`) ask
for the warm start of a 2,400-sample path made of 5 rotated, time-scaled pieces of stored
primitives, while one more client ingests new primitives one at a time. Printed:

* warm-start latency over HTTP, p50 and p99 (and the request rate), beside the same warm
  start computed in-process on the same file (median of 3, after one warm-up call): the
  ratio p50 / in-process is what serving costs under this load;
* ingest latency p50 / p99 and the number acknowledged;
* checks: no request failed, every acknowledged ingest is in the library afterwards, and
  the warm start over HTTP (asked once before the load) equals the in-process one.

Run on a machine with as many cores as the server has readers to see the service, not the
queue: with 8 clients on 2 cores, p50 is mostly waiting for a core.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout too
sys.path.insert(0, str(ROOT / "tests"))

from _pieces import joined  # noqa: E402
from serve_helpers import Server  # noqa: E402

import primlib as pl  # noqa: E402
from primlib.client import Client  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402

MACHINE = ROOT / "data" / "machines" / "xyz.json"
N_SAMPLES = 2000
EPS = 0.05
# (primitive row, start v, time scale k, samples of the new path): 2,400 samples in all
PIECES = [(0, 0.05, 0.6, 480), (1, 0.30, 0.8, 481), (2, 0.10, 1.0, 481), (3, 0.40, 1.3, 481),
          (4, 0.20, 1.7, 481)]  # fmt: skip


def random_primitive(rng: np.random.Generator, dt: float) -> tuple[Trajectory, np.ndarray]:
    """A smooth random 3-D motion (clamped cubic B-spline, 24 control points, ~100 mm) and a
    smooth random input for it."""
    m, p = 24, 3
    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 12.0, axis=0)
    knots = np.concatenate([np.zeros(p), np.linspace(0.0, 1.0, m - p + 1), np.ones(p)])
    traj = Trajectory.from_definition(p, knots, ctrl, None, (N_SAMPLES - 1) * dt)
    u = traj.sample(dt) - ctrl[0]
    return traj, u


def build(db: Path, k: int, samples: int = 2400, seed: int = 0) -> Trajectory:
    """The library file with k primitives; the query path (``samples`` long, 5 pieces)."""
    machine = pl.Machine.from_json(MACHINE)
    rng = np.random.default_rng(seed)
    with pl.Library(db) as lib:
        lib.add_machine(machine)
        items = [(*random_primitive(rng, machine.dt), f"r{i}", None) for i in range(k)]
        lib.add_many(items, machine.name)
    pieces = [(items[row][0], v0, scale, max(8, round(n * samples / 2400)))
              for row, v0, scale, n in PIECES]  # fmt: skip
    return joined(pieces, rng, machine.dt)


def in_process(db: Path, path: Trajectory, repeat: int = 3) -> tuple[float, np.ndarray]:
    """Median seconds of ``Library.warm_start`` on the file (after a warm-up call), and u."""
    with pl.Library(db) as lib:
        ws = lib.warm_start(path, machine="xyz", eps=EPS)
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            ws = lib.warm_start(path, machine="xyz", eps=EPS)
            times.append(time.perf_counter() - t0)
    return statistics.median(times), ws.u


class Load:
    """The clients: warm-start readers and one ingester, until ``stop`` is set."""

    def __init__(self, url: str, path: Trajectory, clients: int, seed: int = 1) -> None:
        self.url, self.path = url, path
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.warm: list[float] = []
        self.ingest: list[float] = []
        self.acked: list[int] = []
        self.failures: list[str] = []
        self.rng = np.random.default_rng(seed)
        self.threads = [threading.Thread(target=self.reader) for _ in range(clients)]
        self.threads.append(threading.Thread(target=self.ingester))

    def reader(self) -> None:
        c = Client(self.url)
        while not self.stop.is_set():
            t0 = time.perf_counter()
            try:
                c.warm_start(self.path, machine="xyz", eps=EPS)
            except Exception as exc:  # every failure is counted and printed, none hidden
                with self.lock:
                    self.failures.append(f"warm start: {type(exc).__name__}: {exc}")
                continue
            with self.lock:
                self.warm.append(time.perf_counter() - t0)

    def ingester(self) -> None:
        c = Client(self.url)
        dt = 0.005
        i = 0
        while not self.stop.is_set():
            with self.lock:
                traj, u = random_primitive(self.rng, dt)
            t0 = time.perf_counter()
            try:
                pid = c.add(traj, u, machine="xyz", name=f"ingest-{i}")
            except Exception as exc:
                with self.lock:
                    self.failures.append(f"ingest: {type(exc).__name__}: {exc}")
                continue
            with self.lock:
                self.ingest.append(time.perf_counter() - t0)
                self.acked.append(pid)
            i += 1

    def run(self, seconds: float) -> None:
        for t in self.threads:
            t.start()
        time.sleep(seconds)
        self.stop.set()
        for t in self.threads:
            t.join()


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of load")
    ap.add_argument("--primitives", type=int, default=1000, help="library size (>= 5)")
    ap.add_argument("--clients", type=int, default=8, help="concurrent warm-start clients")
    ap.add_argument("--readers", type=int, default=2, help="the server's reader threads")
    ap.add_argument("--samples", type=int, default=2400, help="query path length (smoke: less)")
    ap.add_argument("--repeat", type=int, default=3, help="in-process warm starts timed")
    args = ap.parse_args(argv)
    if args.primitives < len(PIECES):
        ap.error(f"--primitives: expected at least {len(PIECES)}, got {args.primitives}")
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "bench.duckdb"
        t0 = time.perf_counter()
        path = build(db, args.primitives, args.samples)
        n = path.sample(0.005).shape[0]
        built = time.perf_counter() - t0
        print(f"library: {args.primitives} primitives x {N_SAMPLES} samples, built in "
              f"{built:.1f} s; query path {n} samples")  # fmt: skip
        local_s, local_u = in_process(db, path, args.repeat)
        server = Server(db, "--readers", str(args.readers))
        try:
            # before the ingests change the library: the same answer as in-process
            first_u = Client(server.url).warm_start(path, machine="xyz", eps=EPS).u
            load = Load(server.url, path, args.clients)
            load.run(args.duration)
            held = {p.id for p in Client(server.url).primitives(machine="xyz")}
        finally:
            server.stop()
        log = server.log.read_text(errors="replace") if load.failures else ""
    code = report(args, load, held, local_s, np.array_equal(first_u, local_u))
    if log:  # what the failed requests raised, from the server's log (gone with the folder)
        print("server log, last lines:\n" + "\n".join(log.splitlines()[-40:]))
    return code


def report(args, load: Load, held: set[int], local_s: float, same: bool) -> int:
    w, g = load.warm, load.ingest
    p50 = pct(w, 50)
    print(f"{args.clients} clients warm-starting + 1 ingesting for {args.duration:g} s, "
          f"server with {args.readers} readers, {os.cpu_count()} cores")  # fmt: skip
    print(f"{'figure':<38}{'value':>12}{'baseline':>12}{'ratio':>8}")
    print(f"{'warm start in-process (median) [s]':<38}{local_s:>12.3f}")
    print(f"{'warm start over HTTP p50 [s]':<38}{p50:>12.3f}{local_s:>12.3f}{p50 / local_s:>8.2f}")
    p99 = pct(w, 99)
    print(f"{'warm start over HTTP p99 [s]':<38}{p99:>12.3f}{local_s:>12.3f}{p99 / local_s:>8.2f}")
    print(f"{'warm starts answered':<38}{len(w):>12d}   ({len(w) / args.duration:.2f}/s)")
    print(f"{'ingest p50 / p99 [s]':<38}{pct(g, 50):>12.3f}{pct(g, 99):>12.3f}")
    missing = sorted(set(load.acked) - held)
    print(f"{'ingests acknowledged / missing after':<38}{len(load.acked):>12d}{len(missing):>12d}")
    print(f"{'failed requests':<38}{len(load.failures):>12d}")
    for f in load.failures[:5]:
        print("   ", f)
    print(f"{'HTTP warm start == in-process':<38}{str(same):>12}")
    ok = not load.failures and not missing and len(w) > 0 and len(load.acked) > 0 and same
    print("OK" if ok else "FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
