"""Acceptance benchmark of trial series on a stage (issue 11): noise, warm start, step time.

    python benchmarks/bench_trials.py [--seeds 3] [--quick]

1. Noise. The example stage's linear part (examples/stage/stage.json) runs the glyph of the
   walk-through from the data-sheet model's inverse (mass 20 % light, damping 15 % low);
   its measured output carries sigma = 10 um of noise. The plain law (norm-optimal from the
   last error) runs 16 trials; its true (noise-free) error settles where the noise it learns
   puts it (the mean over trials 6..15). The noise-aware law (primlib.ilc.TrialLearner
   defaults) runs until its stop rule says converged. Reported per seed and as medians: the
   true error at the stop, its ratio to the plain law's, the stop trial and the trial where
   the true error first came within the margin of the noise floor. Goals: ratio <= 0.5,
   |stop - reached| <= 2.
2. Warm start. On the nonlinear stage (friction, ripple, disturbance, noise) a series learns
   the glyph and is finished; the glyph rotated by 35 degrees and moved starts a new series.
   Reported: the true RMS error of its first trial from the warm start and from the model
   inverse, and their ratio. Goal: <= 0.5.
3. Time of one step (record a measured trial, next input; library in memory) beside one
   trial of primlib.ilc.learn on the model (baseline, same law). The plain step's input is
   checked equal to learn's second input (the fast path returns what the loop returns).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "examples" / "stage"))

import paths as example_paths  # noqa: E402

from benchmarks._timing import median_time  # noqa: E402
from primlib.ilc import TrialLearner, learn  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402
from primlib.pipeline import Library  # noqa: E402
from primlib.plant import Machine, invert  # noqa: E402
from primlib.trials import TrialSeries  # noqa: E402

SIGMA = 0.01
STAGE = Machine.from_json(ROOT / "examples" / "stage" / "stage.json")


def datasheet(stage: Machine = STAGE) -> Machine:
    """The data-sheet model of examples/stage/stage.py (mass x 0.8, damping x 0.85)."""
    plants = {
        a: ([p["K"] / stage.length_unit], [0.8 * p["M"], 0.85 * p["B"], 0.0])
        for a, p in stage.motors.items()
    }
    return Machine(stage.name, stage.dt, stage.axes, plants)


def _true_rms(ref: np.ndarray, y: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((ref - y) ** 2, axis=1))))


def run_law(law: TrialLearner, plant, trials: int, seed: int, stop: bool):
    """True errors per trial (and the stop trial) of a learner on a noisy linear plant."""
    rng = np.random.default_rng(seed)
    ref = law.reference
    inputs, outputs, true = [invert(law.model, ref)], [], []
    for k in range(trials):
        y = plant.simulate(inputs[-1])
        true.append(_true_rms(ref, y))
        outputs.append(y + SIGMA * rng.standard_normal(y.shape))
        step = law.update(np.array(inputs), np.array(outputs))
        if stop and step.converged:
            return np.array(true), k
        inputs.append(step.u)
    return np.array(true), None


def noise_figures(seeds: int, ref: np.ndarray, plain_trials: int = 16, max_trials: int = 30):
    model, plant = datasheet(), STAGE.nominal()
    floor = SIGMA * np.sqrt(ref.shape[1])
    rows = []
    for seed in range(seeds):
        plain = TrialLearner(model, ref, noise_aware=False, average=1)
        true_plain, _ = run_law(plain, plant, plain_trials, seed, stop=False)
        reached = float(np.mean(true_plain[6:]))
        aware = TrialLearner(model, ref)
        true_aware, stop = run_law(aware, plant, max_trials, seed, stop=True)
        hit = np.flatnonzero(true_aware <= aware.margin * floor)
        at_floor = int(hit[0]) if hit.size else None
        final = float(true_aware[-1])
        rows.append((seed, reached, final, final / reached, stop, at_floor))
    return rows


class NoisyStage:
    """The nonlinear example stage as a Plant, with seeded measurement noise."""

    def __init__(self, start: np.ndarray, seed: int = 0) -> None:
        self.start = np.asarray(start, dtype=float)
        self.rng = np.random.default_rng(seed)
        self.true: list[np.ndarray] = []

    def run(self, u: np.ndarray) -> np.ndarray:
        y = STAGE.simulate(u, start=self.start)
        self.true.append(y)
        return y + SIGMA * self.rng.standard_normal(y.shape)


def warm_figures(trials: int, duration: float = 2.0):
    t, pts = example_paths.glyph()
    n = round(duration / STAGE.dt) + 1
    with Library() as lib:
        lib.add_machine(datasheet())
        series = TrialSeries.start(lib, Trajectory.from_samples(pts[:n], STAGE.dt), "stage")
        series.run(NoisyStage(pts[0]), max_trials=trials)
        pid = series.finish(force=True)
        _, moved = example_paths.glyph((120.0, 60.0), 35.0)
        moved = moved[:n]
        ref = moved - moved[0]
        new = TrialSeries.start(lib, Trajectory.from_samples(moved, STAGE.dt), "stage")
        start_kind = new.status().record.start
        u_warm = new.pending()[2]
    warm = _true_rms(ref, STAGE.simulate(u_warm, start=moved[0]))
    inverse = _true_rms(ref, STAGE.simulate(invert(datasheet(), ref), start=moved[0]))
    return pid, start_kind, warm, inverse


def step_times(ref: np.ndarray, repeat: int):
    model, plant = datasheet(), STAGE.nominal()
    rng = np.random.default_rng(0)
    u0 = invert(model, ref)
    y0 = plant.simulate(u0) + SIGMA * rng.standard_normal(ref.shape)
    base, res = median_time(
        lambda: learn(model, ref, u0, law="norm-optimal", iterations=1, contour=False), repeat
    )
    plain = TrialLearner(model, ref, noise_aware=False, average=1)
    # learn runs on the model, so its error is the model's: feed the same to the step
    y_model = model.simulate(u0)
    np.testing.assert_allclose(
        plain.update(u0[None], y_model[None]).u, res.inputs[1], rtol=1e-9, atol=1e-12
    )
    pts = ref + 10.0

    def one_step():
        with Library() as lib:
            lib.add_machine(model)
            s = TrialSeries.start(lib, Trajectory.from_samples(pts, model.dt), "stage")
            t0 = time.perf_counter()
            s.step(y0 + pts[0])
            return time.perf_counter() - t0

    fast = statistics.median(one_step() for _ in range(repeat))
    return fast, base


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="one seed, short runs (smoke test)")
    args = p.parse_args(argv)
    _, pts = example_paths.glyph()
    ref = pts - pts[0]
    seeds = 1 if args.quick else args.seeds
    rows = noise_figures(seeds, ref, *((8, 10) if args.quick else (16, 30)))
    print("1. noise, sigma = 10 um: true RMS error / sigma")
    print(" seed  plain   aware@stop  ratio  stop  at-floor")
    for seed, reached, final, ratio, stop, at_floor in rows:
        print(
            f" {seed:>4}  {reached / SIGMA:5.3f}   {final / SIGMA:8.3f}  {ratio:5.2f}  {stop}  "
            f"{at_floor}"
        )
    ratio = statistics.median(r[3] for r in rows)
    print(f" median ratio {ratio:.2f} (goal <= 0.5)")
    pid, kind, warm, inverse = warm_figures(4 if args.quick else 12, 0.6 if args.quick else 2.0)
    print("2. moved glyph's first trial on the nonlinear stage: true RMS error, mm")
    print(
        f" warm ({kind}, from primitive {pid}) {warm:.4g}  inverse {inverse:.4g}  ratio "
        f"{warm / inverse:.2f} (goal <= 0.5)"
    )
    fast, base = step_times(ref[: 201 if args.quick else None], 1 if args.quick else 5)
    print("3. one step vs one learn trial (median seconds)")
    print(f" step {fast:.3f}  learn {base:.3f}  ratio {fast / base:.2f}")
    return {"noise": rows, "noise_ratio": ratio, "warm": warm, "inverse": inverse, "kind": kind}


if __name__ == "__main__":
    main()
