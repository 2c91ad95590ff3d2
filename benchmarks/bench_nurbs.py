"""Trajectory speed: evaluation against geomdl, fitting against the 10 ms goal and geomdl.

Run: ``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_nurbs.py``

Figures are medians over repeated runs; every baseline is measured in the same run, and
every fast path is checked against the slow one before it is timed:

* ``at`` on 100,000 normalised times vs geomdl's ``evaluate_list``. geomdl evaluates point
  by point in pure Python, so it is timed on a 2,000-point subset and scaled by 50
  (its cost is linear in the number of points); the results agree to 1e-9 relative.
* fitting 1,000 samples to the default tolerance (1e-4 of twice the radius), whole control-point
  search included, vs the 10 ms goal and vs one call of geomdl's own least-squares
  ``fitting.approximate_curve`` with the count our search chose (its parameter is
  centripetal, not time, so only its speed is compared; geomdl's
  ``interpolate_curve`` took about 48 s for 1,000 points on this machine: not rerun here).
* reading a 100,000-row path CSV with every check vs a bare ``np.loadtxt`` of the same file.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from geomdl import fitting

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too

from primlib.defaults import FIT_RTOL  # noqa: E402
from primlib.io import read_path_csv, write_path_csv  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402

N_EVAL = 100_000
N_GEOMDL = 2_000
N_FIT = 1_000
FIT_GOAL_S = 10e-3


def _median_time(fn, repeat: int, number: int = 1) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return statistics.median(times)


def _path(n: int) -> np.ndarray:
    """A 3-D test path in mm: a Lissajous figure climbing a ramp, 1 s of motion."""
    v = np.linspace(0.0, 1.0, n)
    return np.column_stack(
        [40 * np.sin(2 * np.pi * 1.5 * v), 25 * np.sin(2 * np.pi * 2.0 * v + 0.4), 10 * v**2]
    )


def bench_evaluation(tr: Trajectory, label: str) -> list[tuple]:
    rng = np.random.default_rng(0)
    v = np.sort(rng.uniform(0.0, 1.0, N_EVAL))
    sub = v[:: N_EVAL // N_GEOMDL][:N_GEOMDL]
    curve = tr.nurbs
    ours_sub = tr.at(sub)
    theirs_sub = np.array(curve.evaluate_list(sub.tolist()))
    scale = np.abs(theirs_sub).max()
    err = np.abs(ours_sub - theirs_sub).max() / scale
    assert err <= 1e-9, f"at() disagrees with geomdl by {err:.2e} relative"
    tr.at(v)  # warm the cached BSpline
    t_ours = _median_time(lambda: tr.at(v), repeat=15)
    t_geomdl_sub = _median_time(lambda: curve.evaluate_list(sub.tolist()), repeat=3)
    t_geomdl = t_geomdl_sub * (N_EVAL / N_GEOMDL)
    return [
        (
            f"at() on {N_EVAL:,} params, {label}",
            f"{t_ours * 1e3:.2f} ms",
            f"geomdl evaluate_list {t_geomdl * 1e3:.0f} ms (2,000 timed x50)",
            f"{t_geomdl / t_ours:.0f}x faster",
            f"max rel. diff {err:.1e}",
        )
    ]


def bench_fit() -> tuple[list[tuple], Trajectory]:
    pts = _path(N_FIT)
    dt = 1.0 / (N_FIT - 1)
    tr = Trajectory.from_samples(pts, dt)
    centred = pts - pts.mean(axis=0)
    tol = FIT_RTOL * 2.0 * np.sqrt((centred**2).sum(axis=1).max())  # the default's size
    dev = np.linalg.norm(tr.sample(dt) - pts, axis=1).max()
    assert dev <= tol, f"fit misses the tolerance: {dev:.3g} > {tol:.3g}"
    t_fit = _median_time(lambda: Trajectory.from_samples(pts, dt), repeat=51)
    m = tr.n_ctrlpts
    t0 = time.perf_counter()
    fitting.approximate_curve(pts.tolist(), 3, ctrlpts_size=m)
    t_geomdl = time.perf_counter() - t0
    rows = [
        (
            f"fit {N_FIT:,} samples to 1e-4 size",
            f"{t_fit * 1e3:.2f} ms (m={m}, dev {dev:.1e} <= {tol:.1e})",
            f"goal {FIT_GOAL_S * 1e3:.0f} ms",
            f"{FIT_GOAL_S / t_fit:.1f}x under goal",
            "PASS" if t_fit <= FIT_GOAL_S else "MISS",
        ),
        (
            f"fit {N_FIT:,} samples, same count m",
            f"{t_fit * 1e3:.2f} ms (whole search)",
            f"geomdl approximate_curve {t_geomdl * 1e3:.0f} ms (one fit at m)",
            f"{t_geomdl / t_fit:.0f}x faster",
            "",
        ),
    ]
    return rows, tr


def bench_rational_seed(tr: Trajectory) -> Trajectory:
    """The fitted curve with weights != 1 (exercises the homogeneous path)."""
    w = 1.0 + 0.5 * np.sin(np.arange(tr.n_ctrlpts))
    return Trajectory.from_definition(tr.degree, tr.knots, tr.ctrlpts, w, tr.duration)


def bench_csv() -> list[tuple]:
    """read_path_csv (all checks, exact error lines) vs bare np.loadtxt on 100,000 rows."""
    n = 100_000
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "big.csv"
        write_path_csv(f, np.arange(n) * 0.001, rng.normal(size=(n, 3)))
        t, pts = read_path_csv(f)
        raw = np.loadtxt(f, delimiter=",", skiprows=1)
        np.testing.assert_array_equal(np.column_stack([t, pts]), raw)
        t_ours = _median_time(lambda: read_path_csv(f), repeat=5)
        t_raw = _median_time(lambda: np.loadtxt(f, delimiter=",", skiprows=1), repeat=5)
    return [
        (
            f"read_path_csv, {n:,} rows x 4",
            f"{t_ours * 1e3:.0f} ms",
            f"bare np.loadtxt {t_raw * 1e3:.0f} ms",
            f"{t_ours / t_raw:.2f}x its time",
            "arrays equal",
        )
    ]


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()
    fit_rows, tr = bench_fit()
    rows = fit_rows
    rows += bench_evaluation(tr, f"m={tr.n_ctrlpts}")
    rows += bench_evaluation(bench_rational_seed(tr), f"rational m={tr.n_ctrlpts}")
    rows += bench_csv()
    header = ("figure", "value (median)", "baseline (same run)", "ratio", "check")
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    line = "| " + " | ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)) + " |"
    print(line)
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)) + " |")


if __name__ == "__main__":
    main()
