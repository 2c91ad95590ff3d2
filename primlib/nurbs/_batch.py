"""Sampling many trajectories at once on their dt grids.

Curves fitted at one sample count share their knot vector (clamped uniform knots depend only
on m and p), and curves of one duration share the grid v = i / (n - 1). Grouping by
(degree, knots, n, rational) lets one sparse basis matrix B (n, m) evaluate the whole group:
the homogeneous control points (w P, w) of the g curves side by side form one (m, g (d + 1))
matrix, and ``B @ C`` is a single sparse-dense product instead of g spline evaluations.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.interpolate import BSpline

__all__ = ["sample_many"]

# curves per sparse product (keeps the product a few MB for n of a few thousand)
_CHUNK = 32
# smaller groups are sampled curve by curve (Trajectory.sample): measured break-even ~3
_MIN_GROUP = 3


def sample_many(trajectories: Sequence[Any], dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Positions of many trajectories at t = 0, dt, ..., T_i, concatenated.

    Equal to ``np.concatenate([tr.sample(dt) for tr in trajectories])`` up to rounding in
    the last bits (the same basis values, summed in another order), with the first and last
    rows of each curve exactly its end control points, as in ``Trajectory.sample``.

    Parameters
    ----------
    trajectories : sequence of Trajectory, length k
        All of one dimension d.
    dt : float
        Sample time, seconds; must divide every duration (as for ``Trajectory.sample``).

    Returns
    -------
    points : array, shape (N, d)
        Curve i occupies rows ``offsets[i]:offsets[i + 1]``.
    offsets : array of int64, shape (k + 1,)
        ``offsets[i + 1] - offsets[i] = round(T_i / dt) + 1``.

    Raises
    ------
    InputError
        If dt does not divide a duration (the message of ``Trajectory.sample``), or the
        trajectories differ in dimension.
    """
    from primlib._errors import InputError

    k = len(trajectories)
    counts = np.array([tr._count(dt) for tr in trajectories], dtype=np.int64)
    offsets = np.zeros(k + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    dims = {tr.dim for tr in trajectories}
    if len(dims) > 1:
        raise InputError(f"trajectories: expected one dimension, got {sorted(dims)}")
    d = dims.pop() if dims else 0
    out = np.empty((int(offsets[-1]), d))

    groups: dict[tuple, list[int]] = {}
    for i, tr in enumerate(trajectories):
        key = (tr.degree, int(counts[i]), bool(tr.rational), tr.knots.tobytes())
        groups.setdefault(key, []).append(i)

    for (p, n, rational, _), members in groups.items():
        if len(members) < _MIN_GROUP:
            # building the sparse basis costs more than one spline evaluation
            for i in members:
                out[offsets[i] : offsets[i + 1]] = trajectories[i].sample(dt)
            continue
        knots = trajectories[members[0]].knots
        v = np.arange(n) / (n - 1)
        basis = BSpline.design_matrix(v, knots, p)  # sparse (n, m), p + 1 entries a row
        m = len(knots) - p - 1
        # a few curves at a time: the (n, g, d + 1) product stays in cache for the copy out
        for start in range(0, len(members), _CHUNK):
            chunk = members[start : start + _CHUNK]
            ctrl = np.stack([trajectories[i].ctrlpts for i in chunk], axis=1)  # (m, g, d)
            if rational:
                w = np.stack([trajectories[i].weights for i in chunk], axis=1)[:, :, None]
                homog = np.concatenate([ctrl * w, w], axis=2)  # (w P, w)
                raw = (basis @ homog.reshape(m, -1)).reshape(n, len(chunk), d + 1)
            else:
                raw = (basis @ ctrl.reshape(m, -1)).reshape(n, len(chunk), d)
            for j, i in enumerate(chunk):
                block = out[offsets[i] : offsets[i + 1]]
                if rational:
                    np.divide(raw[:, j, :d], raw[:, j, d:], out=block)  # C = A / W
                else:
                    block[:] = raw[:, j, :]
                # a clamped curve starts and ends exactly on its end control points
                block[0] = ctrl[0, j]
                block[-1] = ctrl[-1, j]
    return out, offsets
