"""A path joined from pieces of stored primitives, each turned at random: the query of
``bench_serve.py`` and ``bench_growing.py``."""

from __future__ import annotations

import numpy as np


def joined(pieces, rng: np.random.Generator, dt: float):
    """The path (a :class:`primlib.nurbs.Trajectory` on the ``dt`` grid) of ``pieces``, each
    ``(trajectory, start v, time scale k, samples)``: the stretch from v of that many samples
    run k times faster, turned by a random rotation (drawn from ``rng``) and moved to start
    where the last ended."""
    from scipy.spatial.transform import Rotation

    from primlib.nurbs import Trajectory

    out, last = [], np.zeros(3)
    for traj, v0, scale, n in pieces:
        v1 = v0 + scale * (n - 1) * dt / traj.duration
        pts = traj.at(np.linspace(v0, v1, n))
        pts = pts @ Rotation.random(random_state=int(rng.integers(2**31))).as_matrix().T
        pts += last - pts[0]
        last = pts[-1]
        out.append(pts if not out else pts[1:])
    return Trajectory.from_samples(np.concatenate(out), dt)
