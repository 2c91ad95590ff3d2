"""The example stage (a nonlinear linear-motor table) and converged pairs learned on it,
shared by the grey-box and warm-start tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from primlib.greybox import Pair
from primlib.plant import Machine, invert

ROOT = Path(__file__).resolve().parents[1]
STAGE = Machine.from_json(ROOT / "examples" / "stage" / "stage.json")


def nominal(stage=STAGE) -> Machine:
    plants = {
        a: ([p["K"] / stage.length_unit], [p["M"], p["B"], 0.0]) for a, p in stage.motors.items()
    }
    return Machine(stage.name, stage.dt, stage.axes, plants)


def loop(n: int, size: float, turns: float, phase: float) -> np.ndarray:
    """A smooth rest-to-rest 2-D path relative to its start (mm)."""
    s = np.linspace(0.0, 1.0, n)
    s = s**3 * (10 - 15 * s + 6 * s**2)
    a = 2 * np.pi * turns * s + phase
    return np.c_[size * (np.cos(a) - np.cos(phase)) + 20 * s, size * (np.sin(a) - np.sin(phase))]


def stage_pair(path: np.ndarray, origin, iterations: int = 12) -> Pair:
    """The stage's converged pair for ``path`` at ``origin``: ILC (P-type on the nominal
    inverse, as the library's inputs are learned) until the stage follows it."""
    nom = nominal()
    u = invert(nom, path)
    for _ in range(iterations):
        e = path - STAGE.simulate(u, start=origin)
        u = u + invert(nom, e)
    return Pair(u, path, np.asarray(origin, float))


def add_loop(lib, path: np.ndarray, origin, name: str, iterations: int = 12) -> Pair:
    """Learn ``path`` on the stage at ``origin`` (:func:`stage_pair`) and store it in ``lib``
    (machine ``stage``) with where it ran; the pair."""
    from primlib.nurbs import Trajectory

    pair = stage_pair(path, origin, iterations)
    traj = Trajectory.from_samples(pair.y + pair.origin, STAGE.dt)
    lib.add(traj, pair.u, "stage", name=name, origin=origin)
    return pair


def run_learner(model: Machine, runner, ref: np.ndarray, trials: int):
    """The noise-aware trial learner on ``model`` from the model's inverse, ``trials`` runs of
    ``runner`` (a machine's :meth:`trials`): the learner, the inputs run and the outputs
    measured, stacked."""
    from primlib.ilc import TrialLearner

    learner = TrialLearner(model, ref)
    u, inputs, outputs = invert(model, ref), [], []
    for _ in range(trials):
        outputs.append(runner.run(u))
        inputs.append(u)
        u = learner.update(np.stack(inputs), np.stack(outputs)).u
    return learner, np.stack(inputs), np.stack(outputs)
