"""The warm start on a machine that is not its linear model: split, carry, re-evaluate.

A stored input ``u_l`` is what the real machine needed for its path where it ran. The
grey-box model (:mod:`primlib.greybox`, fitted to all of the machine's stored pairs) splits
it into the nonlinear terms the model explains there -- friction of that motion, ripple of
those absolute positions, the bias -- ``N_l``, and the rest, ``L_l = u_l - N_l``, which is
what a *linear* machine would have needed: the part superposition may rotate and time-scale
(:func:`primlib.splice.splice`). The warm start of a new path is then

    u0 = splice(L) + N(new motion, new absolute positions)

so each part is carried exactly as far as the transform preserves it: in place the two
halves add back to the stored input itself; translated, the ripple is re-evaluated where
the path now runs; rotated or time-scaled, friction follows the new velocities. On a linear
machine N = 0 and this is the splice of today. Beside it the pipeline computes the
model-only input ``GreyBox.inverse`` over the whole path, which stored signals must beat:
per segment the warm start keeps whichever has the lower predicted error
(:func:`choose_per_segment`).
"""

from __future__ import annotations

import numpy as np

from primlib.defaults import BAND_SAMPLES
from primlib.greybox import NONLINEAR, POSITION, TERMS, GreyBox, Pair
from primlib.pipeline._warm import stored_signals
from primlib.splice import StoredSignal
from primlib.store import Bank

__all__ = ["bank_origins", "bank_pairs", "choose_per_segment", "linear_parts"]

_NONLINEAR_TERMS = [TERMS.index(t) for t in NONLINEAR + POSITION]
_IN_PLACE_TOL = 1e-6  # rotation, time scale: |R - I|, |k - 1| below this is "not transformed"


def bank_origins(bank: Bank) -> np.ndarray:
    """Absolute start of each primitive, shape (k, d), NaN where the library does not know."""
    return np.asarray(bank.origins, dtype=float).reshape(len(bank.ids), bank.dim)


def bank_pairs(bank: Bank) -> list[Pair]:
    """Every primitive of the bank as a grey-box :class:`~primlib.greybox.Pair`."""
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    sig = np.asarray(bank.signals)
    org = bank_origins(bank)
    out = []
    for i in range(len(bank.ids)):
        sl = slice(offs[i], offs[i + 1])
        if offs[i + 1] - offs[i] < 4:
            continue
        o = org[i] if np.all(np.isfinite(org[i])) else None
        out.append(Pair(sig[sl], pts[sl] - pts[offs[i]], o))
    return out


def linear_parts(gb: GreyBox, bank: Bank, ids, *, versions: bool = True) -> dict[int, StoredSignal]:
    """The stored signals of ``ids`` minus the nonlinear terms the grey-box model gives them
    (:func:`~primlib.pipeline.stored_signals` with that adjustment).

    Versions at other durations (for eq. (20)) lose their own terms, evaluated on their own
    motion where they ran (a version is the same path run faster or slower).
    """
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    org = bank_origins(bank)

    def linear(i: int, signal: np.ndarray) -> np.ndarray:
        p = pts[offs[i] : offs[i + 1]]
        origin = org[i] if np.all(np.isfinite(org[i])) else None
        return signal - gb.terms(p - p[0], origin)[2]

    return stored_signals(bank, ids, versions=versions, adjust=linear)


def _transformed(seg) -> bool:
    R = np.asarray(seg.rotation, dtype=float)
    return (
        float(np.max(np.abs(R - np.eye(R.shape[0])))) > _IN_PLACE_TOL
        or abs(float(seg.time_scale) - 1.0) > _IN_PLACE_TOL
    )


def choose_per_segment(
    gb: GreyBox, segments, sample_segment: np.ndarray, u_stored: np.ndarray, u_model: np.ndarray
) -> tuple[np.ndarray, tuple[str, ...], tuple[tuple[float, float], ...]]:
    """Per segment the input with the lower predicted error: (u, choices, predicted).

    The model-only input's predicted error is the grey-box model's cross-validated input
    error (RMS over axes): what it misses on motion it was not fitted to. The stored
    signal's is zero for a piece neither rotated nor time-scaled (a translation moves every
    term the model has and the rest of the stored input is carried exactly). A rotated or
    time-scaled piece carries by superposition the part of the stored input the model does
    not explain: right if that part is linear, so on a machine where the fit found no
    friction and no ripple its predicted error is the model's (a tie keeps the stored
    signal); where it found them, the unexplained part is likely of their kind and does not
    transform, so the prediction is what the linear model alone misses (``rms_nominal``).
    An unmatched segment has only the model. Where the choice changes between segments the
    two inputs are blended over a band of ``BAND_SAMPLES`` samples. Returns the input, the
    choice per segment ("stored" or "model") and per segment the predicted RMS output
    errors of the stored signal (inf where nothing matched) and of the model-only input.
    """
    model_err = float(np.sqrt(np.mean(gb.cv_rms**2)))
    # what a transformed stored signal may carry wrongly: on a machine the data show to be
    # linear nothing (superposition is exact, it misses what the model misses); where the
    # model needed nonlinear terms, up to all the linear model alone misses
    nonlinear = bool(np.any(gb.coef[:, _NONLINEAR_TERMS] != 0))
    transformed_err = float(np.sqrt(np.mean(gb.rms_nominal**2))) if nonlinear else model_err
    weight = np.zeros(u_model.shape[0])
    choices, predicted = [], []
    for j, seg in enumerate(segments):
        stored_err = np.inf
        if seg.primitive is not None:
            stored_err = transformed_err if _transformed(seg) else 0.0
        use = stored_err <= model_err
        choices.append("stored" if use else "model")
        predicted.append((stored_err, model_err))
        weight[sample_segment == j] = 1.0 if use else 0.0
    if 0.0 < weight.mean() < 1.0:  # switch over a band, like the splice's junctions
        ramp = np.hanning(BAND_SAMPLES + 2)[1:-1]
        weight = np.convolve(np.pad(weight, BAND_SAMPLES, mode="edge"), ramp / ramp.sum(), "same")
        weight = weight[BAND_SAMPLES:-BAND_SAMPLES]
    w = weight[:, None]
    return w * u_stored + (1 - w) * u_model, tuple(choices), tuple(predicted)
