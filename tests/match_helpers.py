"""Random smooth 3-D primitives for the matcher's tests, and the grid's every-window scorer."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from primlib.match._kabsch import rmsd_from_moments
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


def every_window_score(rotation: str, k: int):
    """The pruned grid's scoring, for ``every_window_seeds`` (``_reference_search``) on
    every window of K = ``k`` points: each centred on its own mean, its RMSD from its moments
    (ties, as a slow piece against stopped primitives, rank alike)."""

    def score(pts: np.ndarray, q: np.ndarray) -> np.ndarray:
        w = pts.transpose(0, 2, 1)
        w = w - w.mean(axis=2, keepdims=True)
        qc = q - q.mean(axis=0)
        sp, sq = np.einsum("mdk,mdk->md", w, w), (qc * qc).sum(axis=0)
        if rotation != "z":
            sp, sq = sp.sum(axis=1), sq.sum()
        return rmsd_from_moments(w @ qc, sp, np.broadcast_to(sq, sp.shape), k, rotation)

    return score
