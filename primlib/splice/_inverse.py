"""The model inverse the splice uses: exact at the samples, bounded for any sampled zeros."""

from __future__ import annotations

import numpy as np

from primlib.plant import invert

__all__ = ["model_inverse", "LIFTED_MAX_N"]

# longest horizon inverted by the regularised lifted solve (O(n^3)); longer ones use the
# stable non-causal filter inverse
LIFTED_MAX_N = 2000


def _has_outside_zero(machine) -> bool:
    """True when some axis's sampled plant has a zero outside the unit circle."""
    for b, _ in machine.discrete():
        b = np.trim_zeros(np.asarray(b, dtype=float), "f")
        if b.size > 1 and np.any(np.abs(np.roots(b)) > 1.0 + 1e-9):
            return True
    return False


def model_inverse(machine, y, reference=None) -> np.ndarray:
    """The model's input for output ``y`` from rest (:func:`primlib.plant.invert`).

    Where a sampled plant has a zero outside the unit circle — every axis of relative
    degree 3 or more, e.g. the XYZ model once refinement has found a lag — the stable
    filter inverse needs input before t = 0; truncated there, it leaves a state error that
    an integrating axis keeps as a drift (measured: 0.12 mm on a time-scaled piece whose
    stored path has a NURBS-fit ripple at its start). So up to ``LIFTED_MAX_N`` samples the
    regularised lifted solve is used there (error 4e-4 mm on the same piece); the filter
    inverse otherwise.

    Parameters
    ----------
    machine : Machine
    y : array, shape (n, d)
        Desired output relative to the start.
    reference : array, shape (n, d), optional
        PID reference (feedback machines).

    Returns
    -------
    u : array, shape (n, d)
    """
    n = np.shape(y)[0]
    if n <= LIFTED_MAX_N and _has_outside_zero(machine):
        return invert(machine, y, reference=reference, method="lifted")
    return invert(machine, y, reference=reference)
