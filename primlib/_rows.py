"""Passes over many concatenated curves a group of whole curves at a time."""

from __future__ import annotations

import numpy as np

__all__ = ["row_groups"]


def row_groups(offsets: np.ndarray, rows: int = 1 << 16) -> list[tuple[int, int]]:
    """Consecutive ranges [g0, g1) of whole primitives of about ``rows`` samples each (at
    least one primitive each), covering all of them: passes over the samples a group at a
    time keep their temporaries in cache. ``offsets``: each primitive's first row, and the
    total last."""
    k = len(offsets) - 1
    cuts = np.searchsorted(offsets, np.arange(0, int(offsets[-1]), rows), side="right") - 1
    cuts = np.unique(np.concatenate([[0], np.minimum(cuts, k), [k]]))
    return list(zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True))
