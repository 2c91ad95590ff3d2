"""The grey-box model: a machine's linear model plus the terms fitted beside it.

:class:`GreyBox` is what :func:`~._fit.fit_greybox` returns; :class:`Pair` is one stored
primitive as the fit sees it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.greybox._features import LINEAR, NONLINEAR, POSITION, TERMS, axis_features
from primlib.greybox._robust import replaced
from primlib.plant import Machine, invert

__all__ = ["GreyBox", "Pair", "model_inverse", "model_gap", "checked_origin"]

LIN = [TERMS.index(t) for t in LINEAR]
NONLIN = [TERMS.index(t) for t in NONLINEAR + POSITION]


@dataclass(frozen=True)
class Pair:
    """One stored primitive as the fit sees it.

    Attributes
    ----------
    u : array, shape (n, d)
        Its stored input.
    y : array, shape (n, d)
        Its path relative to its first point.
    origin : array, shape (d,) or None
        Where the path started on the machine (absolute), None when unknown.
    """

    u: np.ndarray
    y: np.ndarray
    origin: np.ndarray | None = None


@dataclass(frozen=True)
class GreyBox:
    """A machine's linear model plus friction, ripple and bias, fitted to stored pairs.

    Attributes
    ----------
    machine : Machine
        The linear model whose inverse the terms correct.
    coef : array, shape (d, 8)
        Per axis the coefficients of :data:`primlib.greybox.TERMS` (input units per unit
        of each regressor).
    w : array, shape (d,)
        Ripple spatial frequency per axis (rad per user unit; 0 = none found).
    speed : array, shape (d,)
        The typical speed per axis the friction terms are scaled by.
    cv_rms, cv_rms_linear : array, shape (d,)
        Cross-validated RMS output error per axis (user length units) of the model and of
        its linear terms alone: the tracking error each input will leave on motion like
        the data's, as the linear model propagates the input error, beside the gap its
        inverse leaves of the path (:meth:`inverse_gap`, not in these).
    rms_nominal : array, shape (d,)
        The same for the linear model's inverse alone (no terms).
    n_samples : int
    notes : tuple of str
    cv_pairs : array, shape (k, d) or None
        Per pair given to :func:`fit_greybox` (in that order) and axis, the RMS of the
        cross-validated output error over that pair's samples; NaN for a pair the fit left
        out (beyond its row budget).
    gap_pairs : array, shape (k, d) or None
        Per pair and axis the RMS of :meth:`inverse_gap` on that pair's path: what no
        coefficient can change, left out of ``cv_pairs`` (NaN for a pair left out).
    hard : array of bool, shape (d,) or None
        Per axis whether the Coulomb and Stribeck terms have the hard sign (0 at rest)
        rather than the smooth one (:mod:`._features`); None: smooth everywhere.
    robust_coef : array, shape (d, 8) or None
        Per axis the robust input-domain fit (:mod:`._robust`, hard-sign regressors) that
        says which rows of a stored input its path does not determine, and what stands
        there instead; NaN on an axis the fit did not clean (no friction found).
    robust_scale : array, shape (d,) or None
        Its residual scale per axis (input units; NaN likewise).
    """

    machine: Machine
    coef: np.ndarray
    w: np.ndarray
    speed: np.ndarray
    cv_rms: np.ndarray
    cv_rms_linear: np.ndarray
    rms_nominal: np.ndarray
    n_samples: int
    notes: tuple[str, ...] = field(default_factory=tuple)
    cv_pairs: np.ndarray | None = None
    gap_pairs: np.ndarray | None = None
    hard: np.ndarray | None = None
    robust_coef: np.ndarray | None = None
    robust_scale: np.ndarray | None = None

    def _hard(self, i: int) -> bool:
        return self.hard is not None and bool(self.hard[i])

    def inverse_gap(self, y: np.ndarray, u_lin: np.ndarray | None = None) -> np.ndarray:
        """What the linear model's own inverse leaves of the path ``y``, shape (n, d):
        ``G G^-1 y - y`` on the model.

        The inverse leaves out the band its sampling zeros would amplify
        (:func:`primlib.plant.invert`), so on a path with content there every input built
        on it -- the model-only input -- misses that content by this much even where the
        model is the machine. It depends on the path, not on the fit.
        """
        y = np.asarray(y, dtype=float)
        if u_lin is None:
            u_lin = model_inverse(self.machine, y)
        return model_gap(self.machine, y, u_lin)

    def terms(
        self, y: np.ndarray, origin: Any = None, u_lin: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(u_lin, linear, nonlinear)`` for the path ``y`` (relative, shape (n, d)).

        ``u_lin`` is the linear model's inverse, ``linear`` its correction (velocity,
        acceleration, lag terms), ``nonlinear`` the friction, bias and -- where ``origin``
        (the absolute start, shape (d,)) is given -- ripple terms. Their sum is
        :meth:`inverse`.
        """
        y = np.asarray(y, dtype=float)
        if u_lin is None:
            u_lin = model_inverse(self.machine, y)
        org = checked_origin(origin, self.machine.dim)
        lin = np.zeros_like(y)
        non = np.zeros_like(y)
        for i in range(self.machine.dim):
            pos = None if org is None else y[:, i] + org[i]
            F = axis_features(y[:, i], u_lin[:, i], self.machine.dt, self.speed[i], pos,
                              self.w[i], self._hard(i), from_rest=True)  # fmt: skip
            lin[:, i] = F[:, LIN] @ self.coef[i, LIN]
            non[:, i] = F[:, NONLIN] @ self.coef[i, NONLIN]
        return u_lin, lin, non

    def clean(self, u: np.ndarray, y: np.ndarray, u_lin: np.ndarray | None = None) -> np.ndarray:
        """The stored input ``u`` of the path ``y`` (relative, shape (n, d)) with the rows
        the path does not determine replaced as the fit replaced them (:mod:`._robust`):
        what a linear model is fitted to beside this one. ``u_lin``: the linear model's
        inverse of ``y``, as :meth:`terms` takes it."""
        u = np.array(u, dtype=float)
        if self.robust_coef is None:
            return u
        axes = [
            i
            for i in range(self.machine.dim)
            if self.speed[i] > 0 and np.all(np.isfinite(self.robust_coef[i]))
        ]
        if not axes:  # no axis was cleaned (no friction found): nothing to replace
            return u
        y = np.asarray(y, dtype=float)
        if u_lin is None:
            u_lin = model_inverse(self.machine, y)
        for i in axes:
            dt, v = self.machine.dt, self.speed[i]
            F = axis_features(y[:, i], u_lin[:, i], dt, v, None, 0.0, hard=True)
            fit = (self.robust_coef[i], float(self.robust_scale[i]))
            u[:, i] = u_lin[:, i] + replaced(F, u[:, i] - u_lin[:, i], v, fit)[0]
        return u

    def linear_inverse(self, y: np.ndarray) -> np.ndarray:
        """The linear model's inverse of ``y`` as an input to run: its start corrected
        (:func:`primlib.plant.invert`'s ``correct_start``, which the fit's regressors do
        without)."""
        return model_inverse(self.machine, np.asarray(y, dtype=float), corrected=True)

    def inverse(self, y: np.ndarray, origin: Any = None) -> np.ndarray:
        """The input the fitted model says makes the machine follow ``y`` from ``origin``
        (on :meth:`linear_inverse`)."""
        u_lin = self.linear_inverse(y)
        _, lin, non = self.terms(y, origin, u_lin)
        return u_lin + lin + non

    def describe(self) -> str:
        """One line per axis: the terms found, in the machine's units."""
        lines = []
        for i, axis in enumerate(self.machine.axes):
            c = dict(zip(TERMS, self.coef[i], strict=True))
            ripple = np.hypot(c["ripple_sin"], c["ripple_cos"])
            pitch = f"{2 * np.pi / self.w[i]:.4g}" if self.w[i] > 0 else "-"
            # without linear terms (beside a refined model) there is no "linear only" fit
            fitted = self.cv_rms_linear[i] != self.rms_nominal[i]
            linear = f"linear terms only {self.cv_rms_linear[i]:.3g}, " if fitted else ""
            lines.append(
                f"{axis}: Coulomb {c['coulomb']:.3g}, Stribeck {c['stribeck']:.3g}, "
                f"bias {c['bias']:.3g}, ripple {ripple:.3g} (pitch {pitch}), "
                f"CV output error {self.cv_rms[i]:.3g} ({linear}no terms "
                f"{self.rms_nominal[i]:.3g})"
            )
        return "; ".join(lines)


def checked_origin(origin: Any, d: int, label: str = "origin") -> np.ndarray | None:
    """None, or the absolute start as (d,) floats; an InputError for anything else (a
    position-dependent term evaluated at a wrong place would be silently wrong)."""
    if origin is None:
        return None
    try:
        o = np.asarray(origin, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        o = None
    if o is None or o.shape != (d,) or not np.all(np.isfinite(o)):
        raise InputError(f"{label}: expected {d} finite coordinates, got {origin!r:.60}")
    return o


def model_inverse(machine: Machine, y: np.ndarray, corrected: bool = False) -> np.ndarray:
    """The linear model's inverse of ``y``; ``corrected``: with the stable inverse's start
    correction (an input that is the answer, not a fit's regressor)."""
    ref = y if machine.feedback else None
    return invert(machine, y, reference=ref, correct_start=corrected)


def model_gap(machine: Machine, y: np.ndarray, u_lin: np.ndarray) -> np.ndarray:
    """What the model's inverse ``u_lin`` leaves of ``y`` on the model, ``G u_lin - y``."""
    return machine.simulate(u_lin, reference=y if machine.feedback else None) - y
