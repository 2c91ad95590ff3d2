"""Lifted analysis and one learning iteration of the master–slave PDCCILC (paper's study).

1. Largest singular value of the lifted composite M (eq. 30) of PDCCILC on the paper's
   semicircle (12 s at 5 ms, N = 2,400 learnable samples per axis: M is 4,800 x 4,800),
   fast (Lanczos on M^T M, and ``svds``, on the FFT operator) against the dense
   ``numpy.linalg.norm(M, 2)`` (one run: it takes tens of seconds). Goal: >= 1,000x,
   relative agreement <= 1e-6.
   Power iteration is timed too: the top two singular values of this M are nearly equal,
   so it needs thousands of steps and is reported, not asserted. Then the fast method
   alone at N = 4,800 per axis (9,600 x 9,600).
2. One ILC iteration of the two-axis system at 2,400 samples (simulate both PID loops, the
   contour error, the law and the Q-filter) against the same iteration done with the dense
   lifted matrix (u <- M u + N), asserting both give the same input.

Run: ``python benchmarks/bench_lifted.py`` (single-threaded BLAS for a fair comparison).
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.sparse.linalg import svds  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too

from _timing import median_time  # noqa: E402

from primlib.ilc import lifted_master_slave, master_slave_law  # noqa: E402
from primlib.reproduce import contour_reference, paper_machine  # noqa: E402


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args()
    machine = paper_machine()
    r = contour_reference("semicircle")
    r = r - r[0]
    law = master_slave_law(r, machine.dt, "pdccilc", q_cutoff=1.0)
    lifted = lifted_master_slave(law, machine, r)
    size = 2 * lifted.n_learn
    print(f"PDCCILC, semicircle, Q 1 Hz: composite M is {size} x {size}")

    t_lz, s_lz = median_time(lambda: lifted.max_singular_value("lanczos", tol=1e-8), 5)
    t_svds, s_svds = median_time(lambda: lifted.max_singular_value("svds", tol=1e-8), 3)
    top2 = svds(
        lifted.operator,
        k=2,
        tol=1e-8,
        v0=np.random.default_rng(0).standard_normal(size),
        return_singular_vectors=False,
    )
    gap = float(top2.min() / top2.max())
    t_power, s_power = median_time(lambda: lifted.max_singular_value("power", tol=1e-9), 1)
    t0 = time.perf_counter()
    dense = lifted.dense()
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    s_dense = float(np.linalg.norm(dense, 2))
    t_dense = time.perf_counter() - t0
    rel_lz = abs(s_lz - s_dense) / s_dense
    rel_svds = abs(s_svds - s_dense) / s_dense
    rel_power = abs(s_power - s_dense) / s_dense
    print("\n| figure | value | baseline | ratio |")
    print("|---|---|---|---|")
    print(
        f"| sigma_max, Lanczos (eigsh on M^T M) on the FFT operator (median of 5) "
        f"| {t_lz * 1e3:.1f} ms | dense norm(M, 2) {t_dense:.1f} s (assembly {t_build:.1f} s "
        f"more) | {t_dense / t_lz:,.0f}x |"
    )
    print(
        f"| sigma_max, svds on the FFT operator (median of 3) | {t_svds * 1e3:.1f} ms "
        f"| dense {t_dense:.1f} s | {t_dense / t_svds:,.0f}x |"
    )
    print(
        f"| sigma_max, power iteration on M^T M (one run) | {t_power * 1e3:.0f} ms "
        f"| dense {t_dense:.1f} s | {t_dense / t_power:,.0f}x |"
    )
    print(
        f"| sigma_max | Lanczos {s_lz:.12f}, svds {s_svds:.12f} | dense {s_dense:.12f} "
        f"| rel. diff {rel_lz:.1e} / {rel_svds:.1e} |"
    )
    print(
        f"| sigma_max, power | {s_power:.12f} | dense {s_dense:.12f} | rel. diff {rel_power:.1e}"
        f" (sigma_2 / sigma_1 = {gap:.6f}: no gap, power iteration crawls) |"
    )
    assert rel_lz <= 1e-6, f"Lanczos disagrees with the dense SVD: {rel_lz:.2e}"
    assert rel_svds <= 1e-6, f"svds disagrees with the dense SVD: {rel_svds:.2e}"

    # the fast method alone at N = 4,800 per axis (24 s at 5 ms)
    r2 = contour_reference("semicircle", duration=24.0)
    r2 = r2 - r2[0]
    big = lifted_master_slave(
        master_slave_law(r2, machine.dt, "pdccilc", q_cutoff=1.0), machine, r2
    )
    t_big, s_big = median_time(lambda: big.max_singular_value("lanczos", tol=1e-8), 3)
    print(
        f"| sigma_max at N = {big.n_learn} per axis ({2 * big.n_learn} x {2 * big.n_learn}), "
        f"Lanczos | {t_big * 1e3:.1f} ms (sigma {s_big:.6f}) | - | - |"
    )

    # one learning iteration at 2,400 samples
    u = np.zeros_like(r)

    def iteration(u=u):
        e = r - machine.simulate(u, reference=r)
        return law.update(u, e)

    t_iter, u1 = median_time(iteration, 50)
    offset = lifted.offset
    x0 = u[: lifted.n_learn].T.ravel()
    t_dense_iter, x1 = median_time(lambda: dense @ x0 + offset, 20)
    np.testing.assert_allclose(u1[: lifted.n_learn].T.ravel(), x1, atol=1e-9 * np.abs(x1).max())
    print(
        f"| one PDCCILC iteration, 2 axes x {len(r)} samples (median of 50) "
        f"| {t_iter * 1e3:.2f} ms | dense lifted u <- M u + N {t_dense_iter * 1e3:.2f} ms "
        f"(+ {t_build:.1f} s to assemble M) | {t_dense_iter / t_iter:.1f}x |"
    )


if __name__ == "__main__":
    main()
