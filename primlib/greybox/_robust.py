"""Which rows of a stored input its path does not determine, and what to fit there instead.

A stored input is what ILC found makes the real machine follow the path; on a machine with
Coulomb friction that is not the same as "the input the path needs" everywhere:

- where an axis rests (the path does not move it), any input within the static friction
  leaves it at rest, and ILC leaves whatever it had there (on issue 9's friction bench the
  y input of a straight line along x wandered over +-0.35, the whole Coulomb level);
- where it reverses, or creeps, the carriage may stick for part of a sample, and what ILC
  learned there compensates the stick, not the friction;
- at the very end of a trial the last inputs act after the trial and are never learned.

Fitted as they are, those rows drove the friction level 1-2 % off and, through the linear
model's integrator, put every later sample of an output-error fit off with it (the
model-only input of issue 9's rotated friction paths: 0.018 mm median; with these rows
left out 0.003 mm). So before the least-squares fit each axis gets a robust fit in the
input domain -- the linear-correction, Coulomb and bias regressors, Tukey's bisquare by
iteratively reweighted least squares, its scale the median absolute deviation of the
moving rows -- and the rows that fit gives zero weight, or where the axis rests, are
replaced by that fit's own prediction: they then say nothing, rather than something wrong.
Only slow rows are candidates (a fast row the fit rejects is model error, which the fit and
its cross-validation must see: allowed everywhere, 15 % of the moving rows went, at all
speeds, and the cross-validated error no longer said what the model misses), and only
within :data:`HOLD` times the robust fit's Coulomb level of its prediction (what static
friction can hold still: a row further off moved the machine, or failed to against more
than friction). Without that band a linear machine's slow rows, where the robust fit of a
noise-free library rejects any structured model error, were replaced too and friction terms
appeared (issue 9's linear setting: rotated warm start 1.8e-5 -> 0.0021 mm). The fit
(:mod:`._fit`) cleans only an axis on which it finds friction in the first place.
The rows kept are the stored input itself.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HOLD", "REST", "SLOW", "moving", "replaced", "robust_fit", "undetermined"]

SLOW = 0.05  # below this fraction of its speed an axis may stick (scratch: 0.01-0.1 alike)
REST = 1e-6  # an axis rests where |v| <= REST x its typical speed (rounding, not motion)
HOLD = 2.0  # static friction up to this multiple of the Coulomb level
_CUT = 4.685  # Tukey bisquare: 95 % efficiency on Gaussian residuals
_MAD = 1.4826  # MAD -> standard deviation for Gaussian residuals
_ITERATIONS = 30
_FLOOR = 1e-9  # the scale at least this fraction of the RMS input residual: rounding is no outlier


def moving(v: np.ndarray, speed: float) -> np.ndarray:
    """Rows where the axis moves: interval velocity above :data:`REST` of its speed."""
    return np.abs(v) > REST * speed


def _lstsq(A: np.ndarray, r: np.ndarray, w: np.ndarray) -> np.ndarray:
    s = np.sqrt(w)
    return np.linalg.lstsq(A * s[:, None], r * s, rcond=None)[0]


def robust_fit(F: np.ndarray, r: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, float]:
    """Bisquare fit of ``r`` on the columns of ``F`` over ``rows``: (coef, scale).

    Columns that are zero on those rows get coefficient 0. The scale is the MAD-based
    standard deviation of the final residuals, at least a rounding floor (0 when fewer rows
    than columns move).
    """
    coef = np.zeros(F.shape[1])
    A, b = F[rows], r[rows]
    live = np.sqrt(np.mean(A**2, axis=0)) > 0 if len(b) else np.zeros(F.shape[1], bool)
    if len(b) <= np.count_nonzero(live):
        return coef, 0.0
    A = A[:, live]
    floor = _FLOOR * float(np.sqrt(np.mean(b**2)))
    w = np.ones(len(b))
    c = _lstsq(A, b, w)
    for _ in range(_ITERATIONS):
        res = b - A @ c
        scale = max(_MAD * float(np.median(np.abs(res))), floor)
        if scale == 0.0:
            break
        t = res / (_CUT * scale)
        w_new = np.where(np.abs(t) < 1.0, (1.0 - t**2) ** 2, 0.0)
        if np.allclose(w_new, w, rtol=0.0, atol=1e-9):
            break
        w = w_new
        c = _lstsq(A, b, w)
    coef[live] = c
    return coef, max(_MAD * float(np.median(np.abs(b - A @ c))), floor)


def undetermined(
    F: np.ndarray, r: np.ndarray, coef: np.ndarray, scale: float, speed: float
) -> np.ndarray:
    """Rows where the axis rests, or moves slowly (below :data:`SLOW` of its speed: where
    it may stick) and the robust fit gives the row no weight (residual beyond the
    bisquare's cut-off) -- and that lie within :data:`HOLD` times the fit's Coulomb level
    of it. ``F[:, 0]`` is the interval velocity, ``F[:, 3]`` the Coulomb column."""
    v = np.abs(F[:, 0])
    res = np.abs(r - F @ coef)
    out = ~moving(F[:, 0], speed)
    if scale > 0:
        out |= (v < SLOW * speed) & (res >= _CUT * scale)
    # only what static friction can hold is undetermined: a row further from the fit than
    # HOLD x the Coulomb level moved the machine (or did not, against more than friction),
    # so the path does determine it; on a machine without friction nothing is replaced
    return out & (res <= HOLD * abs(coef[3]))


def replaced(
    F: np.ndarray, r: np.ndarray, speed: float, fit: tuple[np.ndarray, float] | None = None
) -> tuple[np.ndarray, tuple[np.ndarray, float]]:
    """``(r, (coef, scale))``: the residual ``r`` with its :func:`undetermined` rows
    replaced by the robust fit's prediction; ``fit`` given, that fit, else one made here
    on the moving rows."""
    coef, scale = robust_fit(F, r, moving(F[:, 0], speed)) if fit is None else fit
    bad = undetermined(F, r, coef, scale, speed)
    return np.where(bad, F @ coef, r), (coef, scale)
