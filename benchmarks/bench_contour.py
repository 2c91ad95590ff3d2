"""Benchmark: exact contour error of 100,000 points against a NURBS path, vs brute force.

Run:  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_contour.py

The path is a three-turn spiral with a ripple (extent ~230 mm, 20 s), fitted by
``Trajectory.from_samples`` to a NURBS; the 100,000 "actual" points lag the path by 5 ms and
scatter 50 um across it. ``contour_error(path, t, actual, "exact")`` (polyline search in an
arc-length window, then safeguarded Newton on the NURBS) is timed over the 100,000 points
(median of 3). The slow path is ``brute_force_contour_error``: the globally closest of
200,000 dense samples, refined by 2,001 more between its neighbours; it runs on a random
subset of 1,000 points and its time is scaled per point (it is linear in the number of
points). Printed: both times, the ratio, and the largest difference on the subset as a
fraction of the path extent. Goals: difference <= 1e-6 of the extent, ratio >= 100.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _timing import median_time  # noqa: E402

from primlib.contour import brute_force_contour_error, contour_error  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402

N_POINTS = 100_000
N_SUBSET = 1_000
DURATION = 20.0
DT = 0.002
GOAL_ERR = 1e-6
GOAL_RATIO = 100.0


def _path() -> Trajectory:
    t = np.arange(int(round(DURATION / DT)) + 1) * DT
    tau = 6 * np.pi * t / DURATION
    r = 20.0 + 5.0 * tau
    pts = np.c_[r * np.cos(tau) + 2 * np.sin(9 * tau), r * np.sin(tau) + 2 * np.cos(7 * tau)]
    return Trajectory.from_samples(pts, DT)


def main() -> int:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()
    path = _path()
    rng = np.random.default_rng(0)
    T = path.duration
    t = np.sort(rng.uniform(0.01, T - 0.01, N_POINTS))
    lagged = path.at(np.clip(t - 0.005, 0, T) / T)
    actual = lagged + rng.normal(scale=0.05, size=lagged.shape)
    extent = path.extent

    fast_s, e_fast = median_time(lambda: contour_error(path, t, actual, "exact"), 3)
    lin_s, _ = median_time(lambda: contour_error(path, t, actual, "linear"), 3)
    circ_s, _ = median_time(lambda: contour_error(path, t, actual, "circular"), 3)

    sub = np.sort(rng.choice(N_POINTS, N_SUBSET, replace=False))
    t0 = time.perf_counter()
    e_brute = brute_force_contour_error(path, t[sub], actual[sub], samples=200_000)
    brute_s = (time.perf_counter() - t0) * N_POINTS / N_SUBSET

    diff = np.max(np.abs(e_fast[sub] - e_brute)) / extent
    ratio = brute_s / fast_s
    print(f"path: {path.n_ctrlpts} control points, extent {extent:.1f} mm, {N_POINTS} points")
    print(f"{'figure':<44}{'value':>14}{'baseline':>14}{'ratio':>10}")
    print(
        f"{'exact contour error, 100k points (s)':<44}{fast_s:>14.3f}{brute_s:>14.1f}{ratio:>9.0f}x"
    )
    print(f"{'  linear estimate, 100k points (s)':<44}{lin_s:>14.3f}")
    print(f"{'  circular estimate, 100k points (s)':<44}{circ_s:>14.3f}")
    print(f"{'max |exact - brute force| / extent':<44}{diff:>14.2e}{GOAL_ERR:>14.0e}")
    print(
        f"(brute force timed on {N_SUBSET} points, scaled to {N_POINTS}; "
        f"goals: difference <= {GOAL_ERR:g} of the extent, ratio >= {GOAL_RATIO:g})"
    )
    assert diff <= GOAL_ERR, f"exact differs from brute force by {diff:.3g} of the extent"
    assert np.all(np.isfinite(e_fast))
    ok = ratio >= GOAL_RATIO
    print("goal met" if ok else "goal NOT met: ratio below 100")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
