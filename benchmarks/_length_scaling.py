"""Match time and peak memory against path length (issue 13: 2,400 -> 24,000 samples x12 or
less; 100,000 samples in <= 30 s and <= 1 GB).

Two kinds of path, both on the machine's dt grid:

* ``composed``: pieces of the library's primitives (a random primitive, a random stretch
  of 40-100 % of it, time-scaled by 0.6-1.7, rotated at random) joined end to start;
* ``novel``: a smooth random 3-D walk the library does not hold (``bench_match_novel``'s
  paths: a clamped cubic B-spline through a random walk of control points, one per 200
  samples);
* ``rests`` (``bench_match.py --length ... --rests``): the same walk held still 3 times per
  2,400 samples for ``rest`` samples (200, 1 s on the bundled machine: dwells of a part
  program; ``bench_match_novel._with_rests``), the walk shortened so the path has the same
  samples. A piece at rest has no arc length for the index: the time-uniform grid searches
  it (``primlib/match/_grid.py``).

Each (kind, length) runs in its own subprocess, so its peak resident memory
(``ru_maxrss``: the interpreter, numpy and the library included) is the match's alone.
``segment_path`` is timed on a fresh :class:`~primlib.match.BankIndex` (a first call: the
index is built inside), wall and CPU seconds (the process's own, single-threaded BLAS: what
a shared machine's load does not inflate as much), with a progress callback that records
when each cut was found.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

__all__ = ["composed_path", "novel_path", "rest_path", "worker", "run", "bank_of"]


def bank_of(kind: str):
    """The bundled library's bank, or 1,000 random primitives' (``bench_match_novel``)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_match_novel import _library

    return _library(kind)


def composed_path(bank, n: int, seed: int) -> np.ndarray:
    """``n`` samples of stored pieces joined end to start (module notes), shape (n, 3)."""
    from scipy.spatial.transform import Rotation

    from primlib.match._interp import cubic_at  # the matcher's own interpolant

    rng = np.random.default_rng(seed)
    out, last, total = [], np.zeros(bank.points.shape[1]), 0
    counts = np.diff(bank.offsets)
    while total < n:
        i = int(rng.integers(counts.size))
        frac, k = rng.uniform(0.4, 1.0), rng.uniform(0.6, 1.7)
        v0 = rng.uniform(0.0, 1.0 - frac)
        m = max(int(round(frac * (counts[i] - 1) / k)), 8) + 1
        x = np.linspace(v0, v0 + frac, m) * (counts[i] - 1)
        pts = cubic_at(bank.points, bank.offsets[i], counts[i], x)
        pts = pts @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T
        pts += last - pts[0]
        last = pts[-1]
        out.append(pts if not out else pts[1:])
        total += out[-1].shape[0]
    return np.concatenate(out)[:n]


def novel_path(n: int, dt: float, seed: int) -> np.ndarray:
    """``n`` samples of a smooth random walk no library piece was made from, shape (n, 3)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_match_novel import _walk

    path = _walk(np.random.default_rng(100 + seed), n, dt, max(8, n // 200))
    return path.at(np.linspace(0.0, 1.0, n))


def rest_path(n: int, dt: float, seed: int, rest: int = 200) -> np.ndarray:
    """``n`` samples of :func:`novel_path`'s walk (shortened) with 3 rests of ``rest``
    samples per 2,400 (at least 3), shape (n, 3)."""
    from bench_match_novel import _with_rests

    rests = 3 * max(1, n // 2400)
    if rests * rest >= n:
        raise ValueError(f"{rests} rests of {rest} samples leave no motion in {n} samples")
    return _with_rests(novel_path(n - rests * rest, dt, seed), rests, rest)


def worker(spec: dict) -> dict:
    """Match one path of ``spec`` (kind, samples, library, seed); JSON-able figures."""
    from primlib.match import BankIndex, segment_path

    bank, dt = bank_of(spec["library"])
    n, seed = int(spec["samples"]), int(spec.get("seed", 0))
    if spec["kind"] == "composed":
        pts = composed_path(bank, n, seed)
    elif spec["kind"] == "rests":
        pts = rest_path(n, dt, seed, int(spec.get("rest", 200)))
    else:
        pts = novel_path(n, dt, seed)
    extent = float(np.sqrt(((pts - pts.mean(axis=0)) ** 2).sum(axis=1)).max())
    eps = 3e-4 * extent  # primlib.defaults.EPS_FRACTION of the extent, as match's default
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    cuts: list[tuple[float, int]] = []
    t0, c0 = time.perf_counter(), time.process_time()
    segs, info = segment_path(
        BankIndex(bank), pts, dt, eps,
        progress=lambda done, total, *found: cuts.append((time.perf_counter() - t0, done)),
    )  # fmt: skip
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {
        "seconds": seconds,
        "cpu_seconds": cpu,  # on a shared machine the wall time measures the others too
        "segments": len(segs),
        "matched": sum(s.end - s.start for s in segs if s.primitive is not None),
        "probes": info["probes"],
        "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "setup_mb": before,
        "half_seconds": next((t for t, d in cuts if d >= (n - 1) / 2), seconds),
        "cuts": [[round(s.end, 9), s.primitive] for s in segs],
        "rmsds": [s.rmsd for s in segs if s.primitive is not None],
    }


def run(spec: dict, tree: Path = ROOT, timeout: float | None = None) -> dict:
    """:func:`worker` in a subprocess with ``tree``'s primlib (single-threaded BLAS)."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    cmd = [sys.executable, __file__, json.dumps(spec)]
    try:
        res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"timeout": timeout}
    if res.returncode != 0:
        raise RuntimeError(f"worker {spec} failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    sys.path.insert(0, str(Path(os.environ.get("PYTHONPATH", ROOT)).resolve()))
    print(json.dumps(worker(json.loads(sys.argv[1]))))
