"""Stage 3 of the splice: blend the placed pieces across the transition bands.

Each sample takes its own segment's value; inside a band the value goes linearly from the
earlier piece's to the later piece's (the paper's bumpless switch, "无扰切换"):
``(1 - λ) x_j + λ x_{j+1}``, ``λ = (t - start) / (end - start)``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from primlib.splice._plan import JunctionPlan

__all__ = ["blend"]


def blend(parts: Sequence[np.ndarray], plan: JunctionPlan) -> np.ndarray:
    """One signal from per-segment signals, linearly interpolated over the bands.

    Parameters
    ----------
    parts : sequence of array, shape (n, d)
        One per segment of ``plan``, each defined at least on its segment's samples and,
        around a junction, on the band.
    plan : JunctionPlan

    Returns
    -------
    array, shape (n, d)
    """
    t, dt = plan.t, plan.dt
    seg = plan.sample_segment
    out = np.empty((plan.n, parts[0].shape[1]))
    for j, part in enumerate(parts):
        sel = seg == j
        out[sel] = part[sel]
    for j, bd in enumerate(plan.bands):
        if bd.end - bd.start <= 0:
            continue
        sel = (t >= bd.start - 1e-9 * dt) & (t <= bd.end + 1e-9 * dt)
        lam = ((t[sel] - bd.start) / (bd.end - bd.start))[:, None]
        out[sel] = (1.0 - lam) * parts[j][sel] + lam * parts[j + 1][sel]
    return out
