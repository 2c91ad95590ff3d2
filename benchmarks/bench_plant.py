"""Benchmark: Machine.simulate, 3 axes x 20,000 samples, against scipy.signal.dlsim.

Run:  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_plant.py [--long-only]

Prints the median time of ``Machine.simulate`` on the XYZ machine of the primitive-matching
paper (eq. 24, open loop) and on the same machine inside a PID loop, beside the median of
``scipy.signal.dlsim`` on each axis's state-space realisation (the slow path) and of a plain
``lfilter`` on the expanded transfer function, measured in the same run, and asserts that the
outputs agree. Goal: simulate <= 1 ms.

Long trials (``--long-only`` runs just this): norm-optimal ILC, 3 axes x 20,000 samples
(100 s at 5 ms), 5 iterations, by the CG path (FFT operators, banded preconditioner); the
baseline is the dense Cholesky path at the largest n it allows (5,000), measured in the same
run and scaled by (20,000 / 5,000)^3 = 64 (its Cholesky and G^T G products are O(n^3); the
measured exponent between n = 2,500 and 5,000 is printed beside it). The two paths' results
at n = 5,000 are asserted equal.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy import linalg, signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _timing import median_time  # noqa: E402

from primlib.ilc import NORM_OPTIMAL_MAX_N, NormOptimal, check_learning, learn  # noqa: E402
from primlib.plant import (  # noqa: E402
    Machine,
    max_singular_value,
    pid_polynomials,
    toeplitz_operator,
)

N = 20_000
REPEAT_FAST = 50
REPEAT_SLOW = 5
GOAL_S = 1e-3


def _dlsim_all(machine, u):
    """Slow path: per-axis dlsim of the ZOH state space (closed loop built as in the tests)."""
    out = np.empty_like(u)
    for i, (nu, _, den) in enumerate(machine.closed_loop()):
        A, B, C, D = signal.tf2ss(np.trim_zeros(nu, "f"), den)
        _, y, _ = signal.dlsim((A, B, C, D, machine.dt), u[:, i])
        out[:, i] = y[:, 0]
    return out


def _lfilter_all(machine, u):
    out = np.empty_like(u)
    for i, (nu, _, den) in enumerate(machine.closed_loop()):
        out[:, i] = signal.lfilter(nu, den, u[:, i])
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--long-only", action="store_true",
                    help="only the long-path figures (ILC on 20,000 samples)")  # fmt: skip
    long_only = ap.parse_args().long_only
    root = Path(__file__).resolve().parents[1]
    xyz = Machine.from_json(root / "data" / "machines" / "xyz.json")
    if long_only:
        _bench_long(xyz)
        return 0
    pid = {a: {"kp": 20.0, "ki": 5.0, "kd": 0.2, "tf": 0.01} for a in xyz.axes}
    xyz_pid = Machine("xyz-pid", xyz.dt, xyz.axes, xyz.plants, pid)
    rng = np.random.default_rng(0)
    u = np.cumsum(rng.standard_normal((N, 3)), axis=0) * 1e-3
    ok = True
    print(f"Machine.simulate, 3 axes x {N} samples (median)")
    print(f"{'machine':10s} {'simulate':>10s} {'lfilter':>10s} {'dlsim':>10s} {'dlsim/sim':>10s}")
    for m in (xyz, xyz_pid):
        t_sim, y = median_time(lambda m=m: m.simulate(u), REPEAT_FAST)
        t_lf, y_lf = median_time(lambda m=m: _lfilter_all(m, u), REPEAT_FAST)
        t_dl, y_dl = median_time(lambda m=m: _dlsim_all(m, u), REPEAT_SLOW)
        scale = np.max(np.abs(y_dl))
        # dlsim runs the expanded polynomial's realisation, whose rounding (see
        # primlib.plant._machine) bounds the agreement, not simulate's
        np.testing.assert_allclose(y, y_dl, rtol=0, atol=1e-8 * scale)
        np.testing.assert_allclose(y, y_lf, rtol=0, atol=1e-8 * scale)
        print(
            f"{m.name:10s} {t_sim * 1e3:8.3f}ms {t_lf * 1e3:8.3f}ms {t_dl * 1e3:8.2f}ms "
            f"{t_dl / t_sim:9.0f}x"
        )
        ok &= t_sim <= GOAL_S
    print(f"goal simulate <= {GOAL_S * 1e3:.0f} ms: {'met' if ok else 'NOT met'}")

    # largest singular value of a lifted matrix: FFT operator + Lanczos vs dense SVD
    n_sv = 3000
    h = xyz.impulse_response(n_sv)[:, 0]
    dense = xyz.lifted(n_sv)[0]
    t_dense, s_dense = median_time(lambda: np.linalg.norm(dense, 2), 3)
    op = toeplitz_operator(h)
    t_fft, s_fft = median_time(lambda: max_singular_value(op, method="lanczos"), 3)
    np.testing.assert_allclose(s_fft, s_dense, rtol=1e-7)
    print(
        f"sigma_max of the {n_sv}x{n_sv} lifted matrix: Lanczos on FFT operator "
        f"{t_fft * 1e3:.1f} ms vs dense SVD {t_dense * 1e3:.0f} ms ({t_dense / t_fft:.0f}x), "
        f"sigma {s_fft:.6g}"
    )
    n_big = 20_000
    op_big = toeplitz_operator(xyz.impulse_response(n_big)[:, 0])
    t_big, s_big = median_time(lambda: max_singular_value(op_big, method="lanczos"), 3)
    print(f"sigma_max at n = {n_big} (no dense baseline, 3.2 GB): {t_big * 1e3:.0f} ms")
    _bench_learn(xyz)
    _bench_long(xyz)
    return 0


def _dense_learn(machine, ref, law, gains, iterations):
    """Slow path: the textbook lifted iteration with dense matrices, u_r += L (y_r - G u_r)."""
    n = ref.shape[0]
    T = machine.lifted(n)
    u = np.zeros_like(ref)
    for i in range(machine.dim):
        r = int(machine.relative_degree[i])
        G = T[i][r:, : n - r]
        if law == "norm-optimal":
            L = np.linalg.solve(G.T @ G + gains["w"][i] * np.eye(n - r), G.T)
        else:
            c, den = pid_polynomials(gains["kp"][i], 0.0, gains["kd"][i], 0.0, machine.dt)
            imp = np.zeros(n - r)
            imp[0] = 1.0
            ell = signal.lfilter(c, den, imp)
            L = linalg.toeplitz(ell, np.r_[ell[0], np.zeros(n - r - 1)])
        ur = np.zeros(n - r)
        for _ in range(iterations):
            ur = ur + L @ (ref[r:, i] - G @ ur)
        u[: n - r, i] = ur
        u[n - r :, i] = ur[-1]
    return u


def _bench_learn(xyz):
    n = 2401  # a 12 s path at 5 ms
    s = np.linspace(0, 1, n)
    ref = np.column_stack(
        [
            10 * np.sin(np.pi * s) ** 2,
            10 * (10 * s**3 - 15 * s**4 + 6 * s**5),
            np.sin(2 * np.pi * s),
        ]
    )
    print(f"learn, 3 axes x {n} samples, 10 iterations (median of 3), vs dense lifted loop")
    for law in ("pd", "norm-optimal"):
        t_fast, res = median_time(lambda law=law: learn(xyz, ref, law=law, iterations=10), 3)
        t_slow, u_slow = median_time(
            lambda law=law, g=res.gains, k=res.iterations: _dense_learn(xyz, ref, law, g, k), 1
        )
        scale = np.max(np.abs(u_slow))
        np.testing.assert_allclose(res.u, u_slow, rtol=0, atol=1e-7 * scale)
        print(
            f"{law:13s} learn {t_fast * 1e3:7.0f} ms (check included)  "
            f"dense {t_slow * 1e3:7.0f} ms "
            f"({t_slow / t_fast:.1f}x)  rms {res.rms_total[0]:.3g} -> {res.rms_total[-1]:.3g}"
        )


def _long_reference(n):
    s = np.linspace(0, 1, n)
    bump = 10 * s**3 - 15 * s**4 + 6 * s**5
    ref = np.column_stack(
        [
            10 * np.sin(np.pi * s) ** 2 * np.cos(2 * np.pi * s),
            10 * bump,
            5 * np.sin(2 * np.pi * s) ** 3 * bump,
        ]
    )
    return ref - ref[0]


def _bench_long(xyz):
    n_long, n_dense, iters = 20_000, NORM_OPTIMAL_MAX_N, 5
    kw = dict(iterations=iters, contour=False)
    dense_law, cg_law = NormOptimal(solver="dense"), NormOptimal(solver="cg")
    ref = _long_reference(n_long)
    t_chk, chk = median_time(lambda: check_learning(xyz, n_long, "norm-optimal"), 3)
    t_cg, res = median_time(lambda: learn(xyz, ref, law="norm-optimal", **kw), 3)
    cg_steps = [max(i.iterations for i in upd) for upd in res.cg]
    print(
        f"norm-optimal ILC, 3 axes x {n_long} samples, {iters} iterations, CG path "
        f"(median of 3): {t_cg:.2f} s, of which the check {t_chk:.2f} s "
        f"(sigma_max {chk.max_singular_value:.10f}, monotonic {chk.monotonic})"
    )
    print(f"  CG steps per solve (largest over axes, per update): {cg_steps}")
    print("  RMS per trial (x, y, z | total):")
    for j, (row, tot) in enumerate(zip(res.rms, res.rms_total, strict=True)):
        print(f"    trial {j}: " + " ".join(f"{v:.3e}" for v in row) + f" | {tot:.3e}")
    # baseline: the dense Cholesky path at the largest n it allows, scaled by n^3
    ref_d = _long_reference(n_dense)
    t_half, _ = median_time(
        lambda: learn(xyz, _long_reference(n_dense // 2), law=dense_law, **kw), 1
    )
    t_dense, dense = median_time(lambda: learn(xyz, ref_d, law=dense_law, **kw), 1)
    t_cg_d, cg_d = median_time(lambda: learn(xyz, ref_d, law=cg_law, **kw), 3)
    scale = np.max(np.abs(dense.u))
    np.testing.assert_allclose(cg_d.u, dense.u, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(cg_d.rms_total, dense.rms_total, rtol=1e-6)
    factor = (n_long / n_dense) ** 3
    exponent = np.log(t_dense / t_half) / np.log(2)
    t_meas = t_dense * (n_long / n_dense) ** exponent
    print(
        f"  dense path at n = {n_dense}: {t_dense:.1f} s (n = {n_dense // 2}: {t_half:.2f} s, "
        f"measured exponent {exponent:.2f}); CG at n = {n_dense}: {t_cg_d * 1e3:.0f} ms "
        f"({t_dense / t_cg_d:.0f}x), same inputs"
    )
    print(
        f"  dense scaled to n = {n_long} (x {factor:.0f}, n^3): {t_dense * factor:.0f} s "
        f"(and 3 x {8 * n_long**2 / 1e9:.1f} GB) vs CG {t_cg:.2f} s: "
        f"ratio {t_dense * factor / t_cg:.0f}x; at the measured exponent "
        f"{t_meas:.0f} s, ratio {t_meas / t_cg:.0f}x"
    )


if __name__ == "__main__":
    raise SystemExit(main())
