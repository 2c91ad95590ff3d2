"""Benchmark: identification from one noisy experiment, and ILC designed on the result.

Run:  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/bench_identify.py [--quick]

Per case, a multisine from ``primlib.identify.excite`` is run on the true machine, noise is
added to the measured positions, and ``identify(structure="auto")`` fits one model per axis
on the first 70 % of the record. Printed per axis, beside each other:

- the identified model's held-out normalised RMS error, rms(y - y_hat) / std(y) over the
  last 30 % (goal <= 5 %), and the same figure for the true linear model (the machine
  itself, or the nominal ``K / (M s^2 + B s)`` of a nonlinear motor) given its best output
  offset on the same record: the baseline measured in the same run (ratio);
- the norm-optimal ILC (primlib.ilc.learn, 10 iterations, default weight) designed on the
  identified model, run on the true (simulated, noise-free) machine: RMS error of the first
  and the last trial, and the same with the law designed on the true linear model.

Cases: the papers' plants with 1 % output noise (the XYZ stage of the primitive-matching
paper eq. (24), open loop; the PDCCILC stage eq. (33) in its PID of Table 1), the linear motor
of the CEE-MFAC paper (friction, force ripple) in a PID loop with 10 um noise, and the
example stage of examples/stage (nonlinear, open loop, 10 um noise) when it is on this
checkout. ``--quick`` runs the first case on a 4 s record (the suite's smoke test).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from primlib.identify import excite, identify  # noqa: E402
from primlib.ilc import learn  # noqa: E402
from primlib.plant import Machine  # noqa: E402

GOAL_NRMSE = 0.05
ILC_ITERATIONS = 10
# converged: the RMS error never grows, ends below half the first trial's, and within 25 % of
# where the law designed on the true linear model ends (a nonlinear stage's floor is its own)
ILC_GOAL = (0.5, 1.25)
# PID of the linear motor (V per mm): crossover near 30 Hz, the ripple's largest stiffness
# (C_c w0 = 0.47 N/mm on x) a twentieth of the loop's (kp K = 8.4 N/mm)
MOTOR_PID = {"kp": 0.7, "ki": 13.0, "kd": 0.0035, "tf": 0.001}


def _cases() -> list[dict]:
    data = ROOT / "data" / "machines"
    motor = Machine.from_json(data / "linear-motor.json").to_dict()
    motor["feedback"] = {"x": MOTOR_PID, "y": MOTOR_PID}
    cases = [
        {"name": "xyz, eq. (24), open loop, 1 % noise",
         "machine": Machine.from_json(data / "xyz.json"), "relative": 0.01,
         "amplitude": 1.0, "duration": 15.0, "travel": 0.2},
        {"name": "xy-pdccilc, eq. (33) in its PID, 1 % noise",
         "machine": Machine.from_json(data / "xy-pdccilc.json"), "relative": 0.01,
         "amplitude": 1.0, "duration": 15.0, "travel": 0.2},
        {"name": "linear motor (CEE-MFAC) in a PID, 10 um noise",
         "machine": Machine.from_dict(motor), "sigma": 0.01, "amplitude": 2.0,
         "duration": 10.0, "travel": 2.0},
    ]  # fmt: skip
    stage = ROOT / "examples" / "stage" / "stage.json"
    if stage.exists():
        cases.append(
            {"name": "example stage (nonlinear, open loop), 10 um noise",
             "machine": Machine.from_json(stage), "sigma": 0.01, "amplitude": 2.0,
             "duration": 10.0, "travel": 30.0, "start": (40.0, 25.0)}
        )  # fmt: skip
    return cases


def _linear(machine: Machine) -> Machine:
    """The true machine's linear model (the nominal part of a nonlinear motor)."""
    return machine.nominal() if hasattr(machine, "nominal") else machine


def _simulate(machine: Machine, u: np.ndarray, start) -> np.ndarray:
    return machine.simulate(u) if start is None else machine.simulate(u, start=start)


def _reference(machine: Machine, travel: float, duration: float = 2.0) -> np.ndarray:
    """A rest-to-rest loop (the example stage's glyph shape) relative to its start."""
    s = np.arange(round(duration / machine.dt) + 1) * machine.dt / duration
    s = s**3 * (10 - 15 * s + 6 * s**2)
    cols = [
        s + 0.4 * np.sin(2 * np.pi * s),
        0.5 * (1 - np.cos(2 * np.pi * s)) - 0.2 * np.sin(4 * np.pi * s),
        0.3 * np.sin(2 * np.pi * s) ** 2,
    ]
    return travel * np.stack(cols[: machine.dim], axis=1)


def _baseline_nrmse(linear: Machine, u, y, n_est) -> np.ndarray:
    y_lin = linear.simulate(u)
    offset = np.mean(y[:n_est] - y_lin[:n_est], axis=0)  # its best output offset
    err = y[n_est:] - y_lin[n_est:] - offset
    return np.sqrt(np.mean(err**2, axis=0)) / np.std(y[n_est:], axis=0)


def _ilc(true: Machine, model: Machine, ref: np.ndarray) -> np.ndarray:
    res = learn(true, ref, model=model, law="norm-optimal", iterations=ILC_ITERATIONS,
                contour=False)  # fmt: skip
    return res.rms_total


def run_case(case: dict, duration: float | None = None, seed: int = 0) -> dict:
    """Identify one case and run ILC on it; returns the figures (see the module docstring)."""
    true = case["machine"]
    rng = np.random.default_rng(seed)
    u = excite(duration or case["duration"], case["amplitude"], true.dim, true.dt)
    y = _simulate(true, u, case.get("start"))
    sigma = case.get("sigma", 0.0) + case.get("relative", 0.0) * np.std(y, axis=0)
    y = y + sigma * rng.standard_normal(y.shape)
    y = y - y[0]  # the deviation from the (noisy) first sample, as a user measures it
    t0 = time.perf_counter()
    res = identify(u, y, true.dt, pid=true.feedback)
    seconds = time.perf_counter() - t0
    linear = _linear(true)
    ref = _reference(true, case["travel"])
    return {
        "nrmse": res.nrmse,
        "baseline": _baseline_nrmse(linear, u, y, res.n_est),
        "structures": [f.structure for f in res.fits],
        "seconds": seconds,
        "samples": len(u),
        "ilc": _ilc(true, res.machine, ref),
        "ilc_baseline": _ilc(true, linear, ref),
    }


def _report(case: dict, out: dict) -> bool:
    print(f"\n{case['name']}: {out['samples']} samples, identify {out['seconds']:.2f} s")
    print(f"  {'axis':<5}{'structure':<14}{'held-out NRMSE':>15}{'true model':>12}{'ratio':>8}")
    for a, s, e, b in zip(
        case["machine"].axes, out["structures"], out["nrmse"], out["baseline"], strict=True
    ):
        print(f"  {a:<5}{s:<14}{100 * e:>13.2f} %{100 * b:>10.2f} %{e / b:>8.2f}")
    ok_fit = bool(np.all(out["nrmse"] <= GOAL_NRMSE))
    lines = []
    ok_ilc = True
    for label, rms in (("identified", out["ilc"]), ("true model", out["ilc_baseline"])):
        grew = bool(np.any(np.diff(rms) > 0))
        ratio = rms[-1] / rms[0]
        lines.append(
            f"  ILC on the {label:<10}: RMS {rms[0]:.4g} -> {rms[-1]:.4g} in "
            f"{len(rms) - 1} trials (x{ratio:.2g}){' GREW' if grew else ''}"
        )
        if label == "identified":
            ok_ilc = not grew and ratio <= ILC_GOAL[0]
            ok_ilc &= rms[-1] <= ILC_GOAL[1] * out["ilc_baseline"][-1]
    print("\n".join(lines))
    print(
        f"  goal: held-out NRMSE <= {100 * GOAL_NRMSE:g} % {'met' if ok_fit else 'MISSED'}; "
        f"ILC on the identified model converges {'yes' if ok_ilc else 'NO'}"
    )
    return ok_fit and ok_ilc


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="the first case on a 4 s record only")
    quick = ap.parse_args(argv).quick
    cases = _cases()[:1] if quick else _cases()
    ok = True
    for case in cases:
        ok &= _report(case, run_case(case, duration=4.0 if quick else None))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
