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


def smooth_walk(rng, n: int, speed: float, width: int = 15, rest: slice | None = None,
                spread: float = 50.0) -> np.ndarray:  # fmt: skip
    """A smooth random 3-D curve of n samples moving ~``speed`` a sample (random directions
    smoothed over ``width`` samples), at rest over the samples ``rest``, at a random place
    ~``spread`` from the origin."""
    v = np.cumsum(rng.normal(size=(n, 3)), axis=0)
    w = min(width, n)
    v = np.apply_along_axis(lambda c: np.convolve(c, np.ones(w) / w, "same"), 0, v)
    v /= np.linalg.norm(v, axis=1, keepdims=True) + 1e-12
    pace = np.full((n, 1), speed)
    if rest is not None:
        pace[rest] = 0.0
    return np.cumsum(v * pace, axis=0) + rng.normal(size=3) * spread
