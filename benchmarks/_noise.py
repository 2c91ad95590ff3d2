"""White measurement noise on sampled paths: the noisy queries of ``bench_match_noisy.py`` and
the noisy novel paths of ``bench_match_novel.py --noise`` (importable with any revision's
primlib: it imports none)."""

from __future__ import annotations

import numpy as np


def white_noise(points: np.ndarray, level: float, rng: np.random.Generator):
    """``points`` (n, d) with white noise of σ = ``level`` × their largest extent on an axis
    drawn from ``rng``, and the noise's RMS over the d axes, σ√d."""
    sigma = level * float(np.ptp(points, axis=0).max())
    noisy = points + rng.normal(scale=sigma, size=points.shape)
    return noisy, sigma * float(np.sqrt(points.shape[1]))
