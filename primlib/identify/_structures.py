"""Model structures an axis is identified in: continuous transfer functions from input to
position, each a small vector of coefficients theta with bounds that keep every pole in the
closed left half plane.

=============  ==========================  ======================  ======================
structure      P(s)                        theta                   bounds
=============  ==========================  ======================  ======================
integrator     b0 / s                      (b0,)                   none
first-order    b0 / (s + a0)               (b0, a0)                a0 >= 0
second-order   (b1 s + b0) /               (b1, b0, a1, a0)        a1 >= 0, a0 >= 0
               (s^2 + a1 s + a0)
=============  ==========================  ======================  ======================

A structure is named by its number of poles; the integrator is the one-pole model with the
pole fixed at 0. A second-order polynomial is Hurwitz (or has roots on the imaginary axis)
exactly when its coefficients are >= 0, so the box bounds are the whole stable set and the
integrating stage ``K / (s (T s + 1))`` is the face a0 = 0. The second-order numerator
carries a zero (minimum or non-minimum phase), as the papers' stages need.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError

__all__ = ["Structure", "STRUCTURES", "structure"]


@dataclass(frozen=True)
class Structure:
    """One model structure: how theta maps to (num, den) and where theta may lie.

    Attributes
    ----------
    name : str
    n_num : int
        Number of numerator coefficients (the leading ones of theta).
    poles : int
        Number of poles (the denominator's degree; its leading coefficient is 1).
    free_den : int
        Number of free denominator coefficients (the rest of theta); the integrator has 0.
    """

    name: str
    n_num: int
    poles: int
    free_den: int

    @property
    def size(self) -> int:
        """Length of theta."""
        return self.n_num + self.free_den

    @property
    def names(self) -> tuple[str, ...]:
        """Coefficient names, ``b<i>`` for s^i in the numerator, ``a<i>`` in the
        denominator, in theta's order (descending powers)."""
        b = tuple(f"b{i}" for i in range(self.n_num - 1, -1, -1))
        a = tuple(f"a{i}" for i in range(self.free_den - 1, -1, -1))
        return b + a

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of theta (denominator coefficients >= 0)."""
        lo = np.concatenate([np.full(self.n_num, -np.inf), np.zeros(self.free_den)])
        return lo, np.full(self.size, np.inf)

    def tf(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(num, den) in descending powers of s, ``den[0] == 1``."""
        theta = np.asarray(theta, dtype=float)
        num = theta[: self.n_num]
        if self.free_den == 0:  # the pole is fixed at s = 0
            den = np.concatenate([[1.0], np.zeros(self.poles)])
        else:
            den = np.concatenate([[1.0], theta[self.n_num :]])
        return num, den

    def theta(self, num: np.ndarray, den: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`tf` for a (num, den) of this structure (den monic)."""
        num = np.asarray(num, dtype=float)
        num = np.concatenate([np.zeros(max(0, self.n_num - len(num))), num])[-self.n_num :]
        den = np.asarray(den, dtype=float) / den[0]
        return np.concatenate([num, den[1 : 1 + self.free_den]])


STRUCTURES: dict[str, Structure] = {
    "integrator": Structure("integrator", n_num=1, poles=1, free_den=0),
    "first-order": Structure("first-order", n_num=1, poles=1, free_den=1),
    "second-order": Structure("second-order", n_num=2, poles=2, free_den=2),
}
"""The structures, simplest first (the order ``auto`` prefers them in)."""


def structure(name: str) -> Structure:
    """The :class:`Structure` called ``name``; raises InputError for an unknown one."""
    if name not in STRUCTURES:
        raise InputError(
            f"structure: expected one of {', '.join(STRUCTURES)} or auto, got {name!r}"
        )
    return STRUCTURES[name]
