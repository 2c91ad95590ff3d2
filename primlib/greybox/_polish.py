"""The model-only input polished on the grey-box model run as a machine.

:meth:`GreyBox.inverse` adds the friction the model expects at the path's own velocity,
``c_c sgn(v)`` over each sample interval, to the linear model's inverse. That is the exact
inverse only where the axis slides one way through the whole interval. Where it reverses
inside an interval, or stops, the force that acts is not that: at rest Coulomb friction is
whatever the other forces need, up to the static level (the axis sticks), and a reversal
between two samples switches the force part-way through a held input. The input the model
gives then leaves an error even on a machine that *is* the model. Measured on issue 9's
friction 5 % machine with its own true parameters (``true_machine`` of the realism benchmark,
the exact Coulomb levels, 4 rotated paths): 0.0021-0.011 mm of RMS error, the same as the
fitted model-only input there (0.0066 mm median), where the linear part alone leaves
2.5e-5-4.9e-5 mm. So it is the inverse's shape, not the fit, that the rotated friction
paths paid for.

:func:`polish` removes it: the grey-box model is built as a :class:`RealisticMachine`
(:func:`forward_model`: the model's linear machine, each hard-sign axis with its Coulomb
level, Stribeck term and ripple as forces at the input, integrated with the set-valued
stick/slip step), the input is run on it, and the model's own error is corrected through
the linear model's inverse, ``u += g G^-1 e``, a few times, keeping the input with the lowest
error on the model (so it is never worse there than the analytic one) and halving g after a
step that did not lower it, until the error is rounding or two steps in a row failed. ``G^-1``
there is the start-corrected inverse (:func:`primlib.plant.invert`'s ``correct_start``): on a
model with a lag the stable inverse's pre-actuation, cut at t = 0, leaves an offset on an
integrating axis, and each correction put it back -- the polish stalled at 1.7e-4 mm on the
model itself on a rotated path of the friction 5 % library (3e-8 with the start corrected),
and on the lagged model's own machine of tests/test_greybox_polish.py kept no step at all. On a
machine that is the model (tests/test_greybox_polish.py) two to four steps reach rounding:
the input is then the exact inverse of the stick/slip machine. On the true-parameter machine
above: 2.5e-5-2.3e-4 mm. What is left on a real machine is then the model's parameters'
error, not its shape -- and that can dominate: on an integrating axis a level 0.1 % off, or a
gain 1e-4 off, integrates to micrometres over a path (the fitted friction 5 % library of the
realism benchmark: its Coulomb levels within 0.1-0.7 %, its linear model's output within
2.6e-3 mm of the machine's on a rotated path), so the polish there takes the model-only input
from 2.95e-3 / 3.82e-3 / 5.38e-3 to 1.83e-3 / 3.07e-3 / 1.73e-3 mm in place, and rotated
7.85e-3 / 5.72e-3 / 9.32e-3 to 6.99e-3 / 5.74e-3 / 1.02e-2 mm; at 2 % rotated 1.94e-3 /
1.18e-3 / 3.15e-3 to 1.57e-3 / 1.18e-3 / 0.94e-3 mm (scratch runs on stored libraries).

Where it acts: axes with the hard sign (:mod:`._features`) and friction. A smooth-sign axis
(a machine whose friction rises smoothly through zero velocity) keeps its analytic terms:
they are taken out of the input before the run on the model, so the correction there only
sees what the linear model sees. The constant term likewise. Machines under feedback (PID)
and models with linear terms (``linear=True`` fits) are returned unchanged.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from primlib.greybox._features import LINEAR, STRIBECK_FRACTION, TERMS
from primlib.plant import RealisticMachine, invert

if TYPE_CHECKING:
    from primlib.greybox._model import GreyBox

__all__ = ["forward_model", "model_residual", "polish", "POLISH_STEPS", "MAX_SAMPLES"]

# corrections at most (module notes: on the model's own machine two to four reach rounding)
POLISH_STEPS = 8
# the whole polish costs ~100 us a path sample (runs on the model and inverses: 2,000 samples
# 0.28 s, 20,000 1.85 s, 100,000 10.6 s); longer paths keep the analytic input
MAX_SAMPLES = 100_000
_GIVE_UP = 2  # corrections in a row that did not lower the error on the model: stop
_LIN = [TERMS.index(t) for t in LINEAR]
_C, _S = TERMS.index("coulomb"), TERMS.index("stribeck")
_RS, _RC = TERMS.index("ripple_sin"), TERMS.index("ripple_cos")


def _simulated(gb: GreyBox) -> tuple[list[int], np.ndarray]:
    """The axes whose friction the model run simulates (hard sign, a Coulomb level > 0), and
    per axis the coefficients of the terms it simulates as forces, shape (d, 8): Coulomb, a
    Stribeck term that raises the static level (one that lowers it, which the run's friction
    law cannot hold, stays analytic), ripple; zero elsewhere."""
    d = gb.machine.dim
    axes = [i for i in range(d) if gb._hard(i) and gb.speed[i] > 0 and gb.coef[i, _C] > 0]
    coef = np.zeros((d, len(TERMS)))
    for i in axes:
        coef[i, [_C, _RS, _RC]] = gb.coef[i, [_C, _RS, _RC]]
        coef[i, _S] = max(float(gb.coef[i, _S]), 0.0)
    return axes, coef


def forward_model(gb: GreyBox, ripple: bool = True) -> RealisticMachine | None:
    """The grey-box model as a machine that can be run, or None where :func:`polish` does
    not apply (feedback, linear terms, no simulated axis).

    Each simulated axis (hard sign, friction) gets its Coulomb level and, from the Stribeck
    term ``c_s sgn(v) exp(-|v| / v_s)``, a static level ``c_c + c_s`` with the Gaussian
    decay of :class:`RealisticMachine` of the same area (``v_s' = 2 v_s / sqrt(pi)``); its
    ripple ``c_1 sin(w x) + c_2 cos(w x)`` becomes amplitude ``hypot(c_1, c_2)``, pitch
    ``2 pi / w`` and phase ``atan2(c_2, c_1)``, where ``ripple`` (an absolute start known).
    """
    m = gb.machine
    if m.feedback or np.any(gb.coef[:, _LIN] != 0):
        return None
    axes, coef = _simulated(gb)
    plants = m.plants
    # friction acts as a force: a plant of relative degree < 2 has no velocity it could see
    if not axes or any(len(plants[m.axes[i]][1]) - len(plants[m.axes[i]][0]) < 2 for i in axes):
        return None
    deps = {}
    for i, a in enumerate(m.axes):
        if i not in axes:
            deps[a] = {}
            continue
        c, s = float(coef[i, _C]), float(coef[i, _S])
        dep = {"coulomb": c, "static_ratio": 1.0 + s / c}
        if s > 0:
            dep["stribeck_velocity"] = 2.0 * STRIBECK_FRACTION * gb.speed[i] / math.sqrt(math.pi)
        amp = math.hypot(coef[i, _RS], coef[i, _RC])
        if ripple and gb.w[i] > 0 and amp > 0:
            dep["ripple"] = amp
            dep["ripple_pitch"] = 2.0 * math.pi / float(gb.w[i])
            dep["ripple_phase"] = math.atan2(coef[i, _RC], coef[i, _RS])
        deps[a] = dep
    return RealisticMachine(m.name, m.dt, m.axes, plants, None, deps)


def polish(
    gb: GreyBox,
    ref: np.ndarray,
    u: np.ndarray,
    origin: np.ndarray | None = None,
    steps: int = POLISH_STEPS,
) -> tuple[np.ndarray, tuple[float, float]]:
    """The model-only input ``u`` of the path ``ref`` (relative, shape (n, d)) corrected on
    the model run as a machine (module notes); and the model's RMS error (user units) of the
    analytic input and of the one returned.

    ``origin``: the absolute start (the ripple is simulated only where it is known, as
    :meth:`GreyBox.inverse` evaluates it only then). ``u`` comes back as it is, with NaN
    errors, where the polish does not apply (:func:`forward_model`) or the path is longer than
    :data:`MAX_SAMPLES` samples.
    """
    u = np.asarray(u, dtype=float)
    run = _runner(gb, ref, origin)
    if run is None or steps <= 0 or not 3 <= ref.shape[0] <= MAX_SAMPLES:
        return u, (math.nan, math.nan)

    def error(x: np.ndarray) -> tuple[np.ndarray, float]:
        e = run(x)
        return e, float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

    e, r0 = error(u)
    best, r_best, gain, failed = u, r0, 1.0, 0
    done = 1e-9 * float(np.max(np.abs(ref)))  # rounding: nothing left
    for _ in range(steps):
        if r_best <= done or failed >= _GIVE_UP:
            break
        trial = best + gain * invert(gb.machine, e, correct_start=True)
        e_t, r_t = error(trial)
        if r_t < r_best:
            best, r_best, e, failed = trial, r_t, e_t, 0
        else:
            gain, failed = 0.5 * gain, failed + 1
    return best, (r0, r_best)


def _runner(gb: GreyBox, ref: np.ndarray, origin):
    """``x -> ref - (the model run as a machine on x)``, or None where :func:`forward_model`
    does not apply."""
    model = forward_model(gb, ripple=origin is not None)
    if model is None:
        return None
    # what the run on the model does not simulate is taken out as the analytic input put it
    # in: the bias, a Stribeck term below the Coulomb level, every term of the other axes --
    # the nonlinear terms of the coefficients less the simulated ones (the terms are linear
    # in them)
    rest = dataclasses.replace(gb, coef=gb.coef - _simulated(gb)[1])
    fixed = rest.terms(ref, origin)[2]
    start = np.zeros(ref.shape[1]) if origin is None else np.asarray(origin, dtype=float)
    return lambda x: ref - model.simulate(np.asarray(x, dtype=float) - fixed, start=start)


def model_residual(
    gb: GreyBox, ref: np.ndarray, u: np.ndarray, origin: np.ndarray | None = None
) -> np.ndarray | None:
    """What the input ``u`` leaves of the path ``ref`` (relative, shape (n, d)) on the
    grey-box model run as a machine, shape (n, d): the error of a polished model-only input
    where the model is the machine; None where :func:`polish` does not apply (it then
    leaves the analytic input, whose own shortfall is :meth:`GreyBox.inverse_gap`)."""
    run = _runner(gb, np.asarray(ref, dtype=float), origin)
    if run is None or not 3 <= ref.shape[0] <= MAX_SAMPLES:
        return None
    return run(u)
