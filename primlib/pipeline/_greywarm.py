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

from dataclasses import replace

import numpy as np

from primlib.defaults import BAND_SAMPLES
from primlib.greybox import NONLINEAR, POSITION, TERMS, GreyBox, Pair
from primlib.pipeline._warm import stored_signals
from primlib.splice import StoredSignal
from primlib.store import Bank

__all__ = [
    "pairs_on",
    "bank_origins",
    "bank_pairs",
    "choose_per_segment",
    "linear_parts",
    "model_error",
    "pair_errors",
    "pair_mismatch",
    "ripple_shifts",
    "stored_errors",
]

_NONLINEAR_TERMS = [TERMS.index(t) for t in NONLINEAR + POSITION]
# samples of a path's start where the model-only input's gap is the start's own, missed by
# every input (choose_per_segment). A path already moving at t = 0 asks a model with a zero
# outside the unit circle (the XYZ axes once a lag is found) for input before t = 0, which no
# input has; the model-only input's start is corrected by least squares over its first
# samples (primlib.plant.invert's correct_start, whose span is 256 at most), so what it still
# misses there a stored signal misses as much (on a 12 s novel path that starts moving, 0.055
# mm RMS over the first segment, which its stored signal was predicted to make at 7e-5 and
# did not). On a path that starts at rest the gap there is the sampling zeros' band, ~1e-5 mm
_START_SAMPLES = 256
_POSITION_TERMS = [TERMS.index(t) for t in POSITION]
# a translation that moves the ripple's phase by more than this (rad) carries the ripple
# model's error from where the piece ran to where it runs (:func:`choose_per_segment`)
_MOVED_PHASE = 0.1
_IN_PLACE_TOL = 1e-6  # rotation, time scale: |R - I|, |k - 1| below this is "not transformed"
# How far a recorded error_rms may understate the true error: the trial learner's estimate was
# 0.69-3.11x the truth on benchmarks/bench_realism.py's libraries learned anew at stop 40
# (noise 0.91-1.17, friction 0.69-3.11, ripple 0.91-1.00, resonance 0.79-0.92), so the truth
# is at most 1/0.69 = 1.45x the estimate; the shares use this bound (:func:`_weight`). Under a
# trial-varying disturbance it is not one (0.40-3.26 all together, 0.60-2.92 alone: a few
# degrees of freedom a draw): there a record 0.40x its truth gets a path 1.07x the model-only
# input's first trial (README, "On a realistic machine").
ERROR_SPREAD = 1.5
MIX_RATIO = 3.0  # a stored signal predicted this many times worse than the model is not mixed


def bank_origins(bank: Bank) -> np.ndarray:
    """Absolute start of each primitive, shape (k, d), NaN where the library does not know."""
    return np.asarray(bank.origins, dtype=float).reshape(len(bank.ids), bank.dim)


def _paired(bank: Bank) -> np.ndarray:
    """The primitives :func:`bank_pairs` gives, in order (those of 4 samples or more)."""
    return np.flatnonzero(np.diff(np.asarray(bank.offsets)) >= 4)


def pairs_on(gb: GreyBox, fitted: Bank, bank: Bank) -> GreyBox:
    """``gb``, fitted on ``fitted`` (the first primitives of ``bank``: :meth:`Bank.head`),
    with its per-pair arrays on ``bank``'s pairs: NaN for the primitives the fit has not
    seen, as for a pair it left out."""
    if fitted is bank:
        return gb
    extra = _paired(bank).size - _paired(fitted).size

    def pad(a: np.ndarray | None) -> np.ndarray | None:
        return None if a is None else np.vstack([a, np.full((extra, a.shape[1]), np.nan)])

    return replace(gb, cv_pairs=pad(gb.cv_pairs), gap_pairs=pad(gb.gap_pairs))


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


def pair_errors(bank: Bank) -> np.ndarray:
    """The recorded ``error_rms`` of each primitive :func:`bank_pairs` gives, in its order
    (NaN where unknown)."""
    return np.asarray(bank.errors, dtype=float)[_paired(bank)]


def linear_parts(
    gb: GreyBox, bank: Bank, ids, *, versions: bool = True, clean: bool = False
) -> dict[int, StoredSignal]:
    """The stored signals of ``ids`` minus the nonlinear terms the grey-box model gives them
    (:func:`~primlib.pipeline.stored_signals` with that adjustment).

    ``clean``: first replace the rows their paths do not determine as the grey-box fit did
    (:meth:`~primlib.greybox.GreyBox.clean`) -- for fitting a model to them, not for carrying
    them over (where the machine ran, the stored input itself is what worked).

    Versions at other durations (for eq. (20)) lose their own terms, evaluated on their own
    motion where they ran (a version is the same path run faster or slower).
    """
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    org = bank_origins(bank)

    def linear(i: int, signal: np.ndarray) -> np.ndarray:
        p = pts[offs[i] : offs[i + 1]]
        origin = org[i] if np.all(np.isfinite(org[i])) else None
        u_lin, _, non = gb.terms(p - p[0], origin)
        if clean:
            signal = gb.clean(signal, p - p[0], u_lin)
        return signal - non

    return stored_signals(bank, ids, versions=versions, adjust=linear)


def _transformed(seg) -> bool:
    R = np.asarray(seg.rotation, dtype=float)
    return (
        float(np.max(np.abs(R - np.eye(R.shape[0])))) > _IN_PLACE_TOL
        or abs(float(seg.time_scale) - 1.0) > _IN_PLACE_TOL
    )


def ripple_shifts(gb: GreyBox, bank: Bank, segments, origin, path_start) -> np.ndarray:
    """Per segment, how far the ripple's phase moves between where the stored piece ran and
    where the new one runs: max over the axes with a ripple of |shift_a| w_a, rad.

    A piece neither rotated nor time-scaled sits at ``origin + (p - path_start)`` on the
    machine (``p`` a point of the path in the frame it was matched in) and its stored
    counterpart at ``o_i + (P - P_i(0))`` (``o_i`` the primitive's recorded origin); the
    match says ``p = P + translation``. 0 without a ripple or for unmatched and transformed
    segments (they are judged otherwise); inf where either absolute place is unknown.
    """
    on = (gb.w > 0) & np.any(gb.coef[:, _POSITION_TERMS] != 0, axis=1)
    out = np.zeros(len(segments))
    if not np.any(on):
        return out
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    org = bank_origins(bank)
    where = {int(i): k for k, i in enumerate(np.asarray(bank.ids))}
    for j, seg in enumerate(segments):
        if seg.primitive is None or _transformed(seg):
            continue
        k = where.get(int(seg.primitive))
        if k is None or origin is None or not np.all(np.isfinite(org[k])):
            out[j] = np.inf
            continue
        shift = (
            np.asarray(origin, float) - np.asarray(path_start, float)
            + np.asarray(seg.translation, float)
            - (org[k] - pts[offs[k]])
        )  # fmt: skip
        out[j] = float(np.max(np.abs(shift[on]) * gb.w[on]))
    return out


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


def pair_mismatch(gb: GreyBox, bank: Bank, spread: float = 1.0) -> np.ndarray:
    """Per primitive of the bank (its row), the model's mismatch on that primitive's own
    motion where it ran: sqrt(max(r_l^2 - (spread e_l)^2, 0)) from its pair's
    cross-validated output error r_l (:func:`model_error`'s terms before the average); NaN
    where the fit left the pair out or the primitive gave none.

    A piece reused in place repeats that motion at that place, so this -- not the machine's
    average over every primitive -- is what the model-only input misses there: on a library
    learned on a friction 2 % machine (seed 11) the model-only input left 4.6e-7 mm on one
    primitive and 1.1e-5 on another, where the average said 1e-5 for both.
    """
    out = np.full(len(bank.ids), np.nan)
    if gb.cv_pairs is None:
        return out
    rows = _paired(bank)
    out[rows] = np.sqrt(_mismatch2(gb, bank, rows, spread))  # NaN stays NaN
    return out


def _mismatch2(gb: GreyBox, bank: Bank, rows: np.ndarray, spread: float) -> np.ndarray:
    """Per pair (bank ``rows``, :func:`_paired`) max(r_l^2 - (spread e_l)^2, 0), NaN where
    the fit left the pair out: :func:`pair_mismatch` squared, and :func:`model_error`'s
    terms."""
    errors = spread * _known_errors(bank)[rows]
    r2 = np.sum(gb.cv_pairs**2, axis=1)
    return np.where(np.isfinite(r2), np.maximum(r2 - errors**2, 0.0), np.nan)


def model_error(gb: GreyBox, bank: Bank, spread: float = 1.0) -> float:
    """The model-only input's predicted RMS output error (Euclidean over the axes) from what
    the model gets wrong, the gap its inverse leaves aside.

    The grey-box model's cross-validated output error compares the model's response to each
    stored input with the stored path, so on each primitive it holds two independent parts:
    what the model gets wrong about the machine (m_i) and the error that primitive's input
    left on the machine (noise that ILC learned into it, mostly: its recorded ``error_rms``
    e_i; none where the library knows none): r_i^2 = m_i^2 + e_i^2. (What the linear
    model's own inverse leaves of that path, ``GreyBox.gap_pairs``, is not in it: the fit's
    target leaves it out; a new path has its own gap, added where it is used.) This is
    max(r_i^2 - e_i^2, 0) averaged over the samples. With ``spread`` > 1 each e_i is taken
    ``spread`` times larger: a lower bound where the recorded errors understate the truth by
    at most that factor.
    """
    rows = _paired(bank)
    counts = np.diff(np.asarray(bank.offsets)).astype(float)[rows]
    m2 = _mismatch2(gb, bank, rows, spread)
    fitted = np.isfinite(m2)
    n = counts[fitted]
    return float(np.sqrt(np.sum(n * m2[fitted]) / max(np.sum(n), 1.0)))


def _weight(transformed: bool, stored_err: float, model_err: float) -> float:
    """The stored signal's share of a segment's input (1 stored, 0 model), from an upper
    bound on the stored signal's error and a lower bound on the model's.

    In place or translated both estimate independent errors of the same needed input (the
    stored signal's: what it left where it ran; the model's: what it misses), so the mix
    w u_s + (1 - w) u_m leaves (1 - w)^2 m^2 + w^2 s^2, least at w* = m^2 / (s^2 + m^2) and
    below m^2 for every w in [0, 2 w*]. The estimates are uncertain (where learned noise
    dominates, r_l^2 - s_l^2 is a small difference of large numbers), so the share is w* of
    the bounds -- never above the true w*, so the mix never does worse than the model-only
    input while the bounds hold. Rotated or time-scaled, the stored prediction is a bound,
    not an estimate: the stored signal is kept whole only where its bound is at most the
    model's (a tie keeps it).
    """
    if not np.isfinite(stored_err):
        return 0.0
    if transformed:
        return 1.0 if stored_err <= model_err else 0.0
    if stored_err > MIX_RATIO * model_err:
        # w* < 0.1 here: the mix would gain at most 10 % in power on average, while the
        # realized cross term 2 w (1 - w) rho s m of two errors of a few independent samples
        # (correlation rho) outweighs that gain once rho > m / (2 s), about 0.17: a coin toss
        return 0.0
    total = stored_err**2 + model_err**2
    return 1.0 if total == 0.0 else model_err**2 / total


def _in_place(e: float, mismatch: float) -> tuple[float, float]:
    """(prediction, upper bound) of a stored signal neither rotated nor time-scaled, its
    own error ``e``; ``mismatch`` > 0 where a translation moved the ripple's phase: the
    ripple the model got wrong where the piece ran stays in its stored signal and the
    model's error where it runs now comes in, two draws of (at most) the mismatch."""
    moved = np.sqrt(2.0) * mismatch
    return float(np.hypot(e, moved)), float(np.hypot(ERROR_SPREAD * e, moved))


def choose_per_segment(
    gb: GreyBox,
    bank: Bank,
    segments,
    sample_segment: np.ndarray,
    u_stored: np.ndarray,
    u_model: np.ndarray,
    gap: np.ndarray | None = None,
    shifts: np.ndarray | None = None,
    nominal: bool = False,
) -> tuple[np.ndarray, tuple[str, ...], tuple[tuple[float, float], ...], tuple[float, ...]]:
    """Per segment the stored signal, the model-only input or their mix, by predicted error.

    Predicted RMS output errors (Euclidean over the axes): the model-only input's is
    sqrt(m^2 + g^2), m the model's mismatch and g the segment's RMS of ``gap``
    (what the model-only input leaves of the new path where the model is the machine, shape
    (n, d): :meth:`GreyBox.inverse_gap`, or for a polished input
    :func:`primlib.greybox.model_residual`; None: none). On a piece in
    place, or translated where no ripple's phase moves, m is the mismatch on its primitive's
    own motion (:func:`pair_mismatch`): the model-only input repeats that motion there;
    elsewhere it is the machine's average (:func:`model_error`). The
    stored signal's, in place, is the error its primitive's input left where it ran
    (``error_rms``); translated where the model has a ripple (``shifts``, per segment the
    phase it moves, :func:`ripple_shifts`; None: none moved), that error and twice the
    mismatch in power -- the ripple re-evaluated at the new place is right only as far as
    the model is, and the stored signal keeps the correction of the model's ripple error
    where it ran. A rotated or time-scaled piece carries by superposition the part of the
    stored input the model does not explain: right if that part is linear, so on a machine
    where the fit found no friction and no ripple its prediction is the larger of the
    model's mismatch (not the gap: the stored signal learned that band) and its own; where
    the fit found them, the unexplained part is likely of their kind and does not transform,
    so the prediction is what the linear model alone misses (``rms_nominal``), or its own
    error if larger. An unmatched segment has only the model. The shares are
    :func:`_weight`'s of bounds: the recorded errors taken :data:`ERROR_SPREAD` times larger
    and the mismatch (``model_error`` or ``pair_mismatch`` with ``spread=ERROR_SPREAD``) then
    left; where the shares change between segments the inputs are blended over a band of
    ``BAND_SAMPLES``. Over the path's first ``_START_SAMPLES`` samples the gap is the
    start's own, left whatever the input: the stored signal's prediction carries it too,
    unless the piece is its primitive from its first sample, neither rotated nor time-scaled.
    ``nominal``: the splice used the unrefined model (transformed: ``rms_nominal``).

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
    gap2 = np.zeros(u_model.shape[0]) if gap is None else np.sum(gap**2, axis=1)
    floor2 = gap2.copy()  # the start's own part of the gap (_START_SAMPLES)
    floor2[_START_SAMPLES:] = 0.0
    weight = np.zeros(u_model.shape[0])
    choices, predicted, shares = [], [], []
    for j, (stored_err, stored_hi, m, m_lo, moved) in enumerate(
        _predictions(gb, bank, segments, shifts, nominal)
    ):
        on = sample_segment == j
        g2 = float(np.mean(gap2[on])) if np.any(on) else 0.0
        f = float(np.sqrt(np.mean(floor2[on]))) if np.any(on) else 0.0
        model_err, model_lo = np.sqrt(m**2 + g2), np.sqrt(m_lo**2 + g2)
        # the path's own start, missed by every input (floor2): the stored signal too,
        # unless it made this very start where it ran (its primitive from its first sample,
        # neither rotated nor time-scaled: its recorded error holds it)
        if moved or segments[j].primitive_start > 1e-9:
            stored_err, stored_hi = np.hypot(stored_err, f), np.hypot(stored_hi, f)
        share = _weight(moved, stored_hi, model_lo)
        choices.append("stored" if share == 1.0 else "model" if share == 0.0 else "blend")
        predicted.append((stored_err, model_err))
        shares.append(share)
        weight[on] = share
    if np.ptp(weight) > 0:  # the share changes: over a band, like the splice's junctions
        ramp = np.hanning(BAND_SAMPLES + 2)[1:-1]
        weight = np.convolve(np.pad(weight, BAND_SAMPLES, mode="edge"), ramp / ramp.sum(), "same")
        weight = weight[BAND_SAMPLES:-BAND_SAMPLES]
    w = weight[:, None]
    return w * u_stored + (1 - w) * u_model, tuple(choices), tuple(predicted), tuple(shares)


def _predictions(gb: GreyBox, bank: Bank, segments, shifts, nominal: bool = False):
    """Per segment (stored signal's predicted error, its upper bound, the model's mismatch,
    its lower bound, transformed) as :func:`choose_per_segment` says, the gap left out;
    ``nominal``: the splice carries the stored signals through the unrefined model."""
    mismatch = model_error(gb, bank)
    mismatch_lo = model_error(gb, bank, ERROR_SPREAD)
    own = stored_errors(bank)
    # a library that records no stored signal's worth (primitives added without error_rms)
    # says nothing a transformed one could earn its place by: the model-only input is kept
    # there (taken to be exact, they had made novel paths' warm starts 3-52x the model-only
    # input past their start on bench_warm_start.py's machine)
    recorded = bool(np.any(np.isfinite(np.asarray(bank.errors, dtype=float))))
    # in place, the model's mismatch on the primitive's own motion (pair_mismatch)
    here, here_lo = pair_mismatch(gb, bank), pair_mismatch(gb, bank, ERROR_SPREAD)
    row = {int(i): k for k, i in enumerate(np.asarray(bank.ids))}
    # what a transformed stored signal may carry wrongly: on a machine the data show to be
    # linear what the model misses (superposition goes through it); where the model needed
    # nonlinear terms, up to all the linear model alone misses
    # (and where the splice carries them through the unrefined model, what that model
    # misses: judged by the grey-box model's mismatch instead, the composed paths of
    # bench_warm_start.py kept stored signals that left 0.287 mm for a model-only input's
    # 0.00125)
    wide = nominal or bool(np.any(gb.coef[:, _NONLINEAR_TERMS] != 0))
    lin_err = float(np.sqrt(np.sum(gb.rms_nominal**2)))
    out = []
    for j, seg in enumerate(segments):
        m, m_lo = mismatch, mismatch_lo
        stored_err, stored_hi, moved = np.inf, np.inf, _transformed(seg)
        if seg.primitive is not None:
            e = own.get(int(seg.primitive), 0.0)
            if moved and not recorded:
                pass  # worth unknown: inf, the model-only input
            elif moved:  # superposition carries the model's mismatch, not its inverse's gap
                stored_err = max(e, lin_err if wide else mismatch)
                stored_hi = max(ERROR_SPREAD * e, lin_err if wide else mismatch_lo)
            else:
                shifted = shifts is not None and shifts[j] > _MOVED_PHASE
                stored_err, stored_hi = _in_place(e, mismatch if shifted else 0.0)
                k = row.get(int(seg.primitive))
                if not shifted and k is not None and np.isfinite(here[k]):
                    m, m_lo = here[k], here_lo[k]  # the same motion at the same place
        out.append((stored_err, stored_hi, m, m_lo, moved))
    return out
