"""Random smooth 3-D primitives for the matcher's CLI and min-segment tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from primlib.nurbs import Trajectory
from primlib.plant import Machine
from primlib.store import Bank

ROOT = Path(__file__).resolve().parents[1]


def bundled_bank() -> Bank:
    """The bundled example library's 14 paths, sampled on the xyz machine's grid."""
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    pieces = [
        Trajectory.from_csv(f).sample(machine.dt)
        for f in sorted((ROOT / "data" / "library").glob("*.csv"))
        if not f.name.endswith(".signal.csv")
    ]
    return Bank.from_samples(pieces, machine.dt)


def random_primitive(rng, dt: float, n: int = 401) -> Trajectory:
    """A cubic NURBS through a random walk of 12 control points, n samples at dt."""
    m, p = 12, 3
    ctrl = np.cumsum(rng.normal(size=(m, 3)) * 10.0, axis=0)
    knots = np.concatenate([np.zeros(p), np.linspace(0, 1, m - p + 1), np.ones(p)])
    return Trajectory.from_definition(p, knots, ctrl, None, (n - 1) * dt)
