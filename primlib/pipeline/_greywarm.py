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
per segment the warm start keeps whichever has the lower predicted error, or in place their
least-error mix (:func:`choose_per_segment`); what a stored signal is worth is the error it
left where it ran, noise that ILC learned into it included (the primitive's ``error_rms``).
"""

from __future__ import annotations

import numpy as np

from primlib.defaults import BAND_SAMPLES
from primlib.greybox import NONLINEAR, POSITION, TERMS, GreyBox, Pair
from primlib.pipeline._warm import stored_signals
from primlib.splice import StoredSignal
from primlib.store import Bank

__all__ = [
    "bank_origins",
    "bank_pairs",
    "choose_per_segment",
    "linear_parts",
    "model_error",
    "stored_errors",
]

_NONLINEAR_TERMS = [TERMS.index(t) for t in NONLINEAR + POSITION]
_IN_PLACE_TOL = 1e-6  # rotation, time scale: |R - I|, |k - 1| below this is "not transformed"


def bank_origins(bank: Bank) -> np.ndarray:
    """Absolute start of each primitive, shape (k, d), NaN where the library does not know."""
    return np.asarray(bank.origins, dtype=float).reshape(len(bank.ids), bank.dim)


def _paired(bank: Bank) -> np.ndarray:
    """The primitives :func:`bank_pairs` gives, in order (those of 4 samples or more)."""
    return np.flatnonzero(np.diff(np.asarray(bank.offsets)) >= 4)


def bank_pairs(bank: Bank) -> list[Pair]:
    """Every primitive of the bank (of 4 samples or more) as a grey-box
    :class:`~primlib.greybox.Pair`."""
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    sig = np.asarray(bank.signals)
    org = bank_origins(bank)
    out = []
    for i in _paired(bank):
        sl = slice(offs[i], offs[i + 1])
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


def _known_errors(bank: Bank) -> np.ndarray:
    """Each primitive's ``error_rms``; where unknown, the median of the machine's known
    ones (its primitives were learned alike), or 0 where none is known (the stored signal
    taken to be exact where it ran, as before the library recorded what it is worth)."""
    errors = np.asarray(bank.errors, dtype=float)
    known = errors[np.isfinite(errors)]
    return np.where(np.isfinite(errors), errors, float(np.median(known)) if known.size else 0.0)


def stored_errors(bank: Bank) -> dict[int, float]:
    """Each primitive's ``error_rms`` by id, unknown ones filled (:func:`_known_errors`)."""
    return {int(i): float(e) for i, e in zip(bank.ids, _known_errors(bank), strict=True)}


def model_error(gb: GreyBox, bank: Bank) -> float:
    """The model-only input's predicted RMS output error (Euclidean over the axes).

    The grey-box model's cross-validated output error compares the model's response to each
    stored input with the stored path, so on each primitive it also holds the error that
    primitive's input left on the machine (noise that ILC learned into it, mostly):
    r_i^2 = m_i^2 + e_i^2, two independent parts. The model-only input makes only the
    first: per primitive max(r_i^2 - e_i^2, 0) (its recorded ``error_rms`` e_i; nothing
    subtracted where the library knows none), averaged over the samples.
    """
    counts = np.diff(np.asarray(bank.offsets)).astype(float)
    errors = _known_errors(bank)
    rows = _paired(bank)
    if gb.cv_pairs is None or gb.cv_pairs.shape[0] != rows.size:  # not fitted on this bank
        own = float(np.sum(counts * errors**2) / max(np.sum(counts), 1.0))
        return float(np.sqrt(max(float(np.sum(gb.cv_rms**2)) - own, 0.0)))
    r2 = np.sum(gb.cv_pairs**2, axis=1)
    fitted = np.isfinite(r2)
    n = counts[rows][fitted]
    m2 = np.maximum(r2[fitted] - errors[rows][fitted] ** 2, 0.0)
    return float(np.sqrt(np.sum(n * m2) / max(np.sum(n), 1.0)))


def _weight(transformed: bool, stored_err: float, model_err: float) -> float:
    """The stored signal's share of a segment's input (1 stored, 0 model).

    In place or translated both predictions estimate independent errors of the same needed
    input (the stored signal's: what it left where it ran; the model's: what it misses), so
    the least-error mix weighs each by the other's variance, m^2 / (s^2 + m^2), whose error
    s m / sqrt(s^2 + m^2) is below both. Rotated or time-scaled, the stored prediction is a
    bound, not an estimate: the lower one is kept whole (a tie keeps the stored signal).
    """
    if not np.isfinite(stored_err):
        return 0.0
    if transformed:
        return 1.0 if stored_err <= model_err else 0.0
    total = stored_err**2 + model_err**2
    return 1.0 if total == 0.0 else model_err**2 / total


def choose_per_segment(
    gb: GreyBox,
    bank: Bank,
    segments,
    sample_segment: np.ndarray,
    u_stored: np.ndarray,
    u_model: np.ndarray,
) -> tuple[np.ndarray, tuple[str, ...], tuple[tuple[float, float], ...], tuple[float, ...]]:
    """Per segment the stored signal, the model-only input or their mix, by predicted error.

    Predicted RMS output errors (Euclidean over the axes): the model-only input's is
    :func:`model_error`. The stored signal's, in place or translated, is the error its
    primitive's input left where it ran (``error_rms``; a translation moves every term the
    model has and the rest of the stored input is carried exactly). A rotated or time-scaled
    piece carries by superposition the part of the stored input the model does not explain:
    right if that part is linear, so on a machine where the fit found no friction and no
    ripple its prediction is the larger of the model's and its own; where the fit found
    them, the unexplained part is likely of their kind and does not transform, so the
    prediction is what the linear model alone misses (``rms_nominal``), or its own error if
    larger. An unmatched segment has only the model. The shares are :func:`_weight`'s; where
    they change between segments the inputs are blended over a band of ``BAND_SAMPLES``.

    Returns
    -------
    u : array, shape (n, d)
    choices : tuple of str
        Per segment "stored" (share 1), "model" (share 0) or "blend".
    predicted : tuple of (float, float)
        Per segment the predicted errors of the stored signal (inf where nothing matched)
        and of the model-only input.
    weights : tuple of float
        Per segment the stored signal's share.
    """
    model_err = model_error(gb, bank)
    own = stored_errors(bank)
    # what a transformed stored signal may carry wrongly: on a machine the data show to be
    # linear what the model misses (superposition goes through it); where the model needed
    # nonlinear terms, up to all the linear model alone misses
    nonlinear = bool(np.any(gb.coef[:, _NONLINEAR_TERMS] != 0))
    transformed_err = float(np.sqrt(np.sum(gb.rms_nominal**2))) if nonlinear else model_err
    weight = np.zeros(u_model.shape[0])
    choices, predicted, shares = [], [], []
    for j, seg in enumerate(segments):
        stored_err, moved = np.inf, _transformed(seg)
        if seg.primitive is not None:
            e = own.get(int(seg.primitive), 0.0)
            stored_err = max(e, transformed_err) if moved else e
        share = _weight(moved, stored_err, model_err)
        choices.append("stored" if share == 1.0 else "model" if share == 0.0 else "blend")
        predicted.append((stored_err, model_err))
        shares.append(share)
        weight[sample_segment == j] = share
    if np.ptp(weight) > 0:  # the share changes: over a band, like the splice's junctions
        ramp = np.hanning(BAND_SAMPLES + 2)[1:-1]
        weight = np.convolve(np.pad(weight, BAND_SAMPLES, mode="edge"), ramp / ramp.sum(), "same")
        weight = weight[BAND_SAMPLES:-BAND_SAMPLES]
    w = weight[:, None]
    return w * u_stored + (1 - w) * u_model, tuple(choices), tuple(predicted), tuple(shares)
