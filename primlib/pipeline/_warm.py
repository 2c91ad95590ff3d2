"""The warm start's data: the splice's view of a bank, and the result, :class:`WarmStart`.

:func:`stored_signals` turns the store's :class:`~primlib.store.Bank` into what
:func:`primlib.splice.splice` needs of each matched primitive, with the versions stored at
other durations (:func:`find_versions`) for the model-free time scaling, eq. (20) of the
primitive-matching paper.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.match import Match
from primlib.splice import Band, RefinedModel, StoredSignal
from primlib.store import Bank

__all__ = ["WarmStart", "find_versions", "stored_signals"]


# normalised-time samples on which two stored paths are compared for "same primitive"
_VERSION_SAMPLES = 64
_VERSION_TOL = 1e-4  # relative to the path's extent
_VERSION_MIN_RATIO = 1.05  # durations closer than this are not a different time scale


@dataclass(frozen=True)
class WarmStart:
    """A first-iteration input for a new path, built from the library.

    Attributes
    ----------
    u : array, shape (n, d)
        The input on the machine's grid t = 0, dt, ..., n = round(T / dt) + 1.
    t : array, shape (n,)
    match : Match
        The segmentation it was built from.
    bands : tuple of Band
        Transition bands at the junctions.
    sample_segment : array of int, shape (n,)
        Segment index of each sample.
    sources : tuple of str
        Per segment, where its input came from (primitive, window, time scale, method, or
        the nominal-model inverse for an unmatched segment).
    methods : tuple of str
        Per segment: "identity", "model", "direct" (eq. (20)) or "inverse".
    notes : tuple of str
    model : RefinedModel or None
        The model refined on the matched primitives (None when not refined).
    spliced : array, shape (n, d) or None
        The transformed pieces joined over the bands, before the residual correction.
    model_u : array, shape (n, d) or None
        The model-only input: the grey-box model's inverse over the whole path, no stored
        signal (None without the grey-box model).
    greybox : GreyBox or None
        The machine's grey-box model, fitted to all of its stored pairs.
    choices : tuple of str
        Per segment "stored" (the stored signal carried over), "model" (the model-only
        input) or "blend" (their least-error mix, in place or translated, where both have
        an error of their own: noise learned into the stored signal, what the model
        misses); empty without the grey-box model.
    predicted : tuple of float
        Per segment the predicted RMS tracking error (Euclidean over the axes, output
        units) of the input used.
    weights : tuple of float
        Per segment the stored signal's share of the input (1 stored, 0 model).
    """

    u: np.ndarray
    t: np.ndarray
    match: Match
    bands: tuple[Band, ...]
    sample_segment: np.ndarray
    sources: tuple[str, ...]
    methods: tuple[str, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    model: RefinedModel | None = None
    spliced: np.ndarray | None = None
    model_u: np.ndarray | None = None
    greybox: Any = None
    choices: tuple[str, ...] = field(default_factory=tuple)
    predicted: tuple[float, ...] = field(default_factory=tuple)
    weights: tuple[float, ...] = field(default_factory=tuple)

    @property
    def n_unmatched(self) -> int:
        """Segments nothing in the library matched (their input is the model inverse)."""
        return sum(m == "inverse" for m in self.methods)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays but the band list)."""
        return {
            "n_samples": int(self.u.shape[0]),
            "duration": float(self.t[-1]) if self.t.size else 0.0,
            "bands": [b.to_dict() for b in self.bands],
            "sources": list(self.sources),
            "methods": list(self.methods),
            "notes": list(self.notes),
            "choices": list(self.choices),
            "predicted": [float(p) for p in self.predicted],
            "weights": [float(w) for w in self.weights],
            "match": self.match.to_dict(),
        }


def _normalised(points: np.ndarray, m: int = _VERSION_SAMPLES) -> np.ndarray:
    n = points.shape[0]
    x = np.linspace(0.0, n - 1.0, m)
    lo = np.minimum(np.floor(x).astype(int), n - 2)
    f = (x - lo)[:, None]
    return points[lo] * (1 - f) + points[lo + 1] * f


def find_versions(bank: Bank, index: int, tol: float = _VERSION_TOL) -> list[int]:
    """Indices of bank primitives that are the primitive ``index`` at another duration.

    Same shape and pose: their paths, sampled at 64 uniform normalised times, agree with
    primitive ``index``'s to ``tol`` times its extent; their durations differ by at least
    5 %. These are what eq. (20) combines.

    Parameters
    ----------
    bank : Bank
        A machine's primitives, as :meth:`primlib.store.Store.bank` returns them.
    index : int
        Position of the primitive in the bank.
    tol : float
        Relative shape tolerance.

    Returns
    -------
    list of int
        Bank positions (not ids), excluding ``index``.
    """
    offs = np.asarray(bank.offsets)
    pts = np.asarray(bank.points)
    durs = np.asarray(bank.durations, dtype=float)
    ref = _normalised(pts[offs[index] : offs[index + 1]])
    extent = float(np.max(np.ptp(ref, axis=0))) or 1.0
    out = []
    for i in range(len(durs)):
        if i == index or offs[i + 1] - offs[i] < 2:
            continue
        ratio = max(durs[i], durs[index]) / min(durs[i], durs[index])
        if ratio < _VERSION_MIN_RATIO:
            continue
        other = _normalised(pts[offs[i] : offs[i + 1]])
        if float(np.max(np.abs(other - ref))) <= tol * extent:
            out.append(i)
    return out


def stored_signals(
    bank: Bank,
    ids: Iterable[int],
    *,
    versions: bool = True,
    adjust: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> dict[int, StoredSignal]:
    """The splice's view of the given primitive ids, read from a bank.

    Parameters
    ----------
    bank : Bank
    ids : iterable of int
        Primitive ids in the bank.
    versions : bool
        Also collect each primitive's versions at other durations (:func:`find_versions`).
    adjust : callable, optional
        ``adjust(i, signal)`` -> the signal to use for bank position ``i`` (each primitive's
        and each version's own), e.g. its linear part
        (:func:`primlib.pipeline._greywarm.linear_parts`).

    Returns
    -------
    dict of int to StoredSignal

    Raises
    ------
    InputError
        An id that is not in the bank.
    """
    ids_arr = np.asarray(bank.ids)
    offs = np.asarray(bank.offsets)
    out: dict[int, StoredSignal] = {}

    def signal(i: int) -> np.ndarray:
        sig = np.asarray(bank.signals)[offs[i] : offs[i + 1]]
        return sig if adjust is None else adjust(i, sig)

    for pid in ids:
        where = np.flatnonzero(ids_arr == pid)
        if where.size == 0:
            raise InputError(f"match: primitive {pid} is not in the library's bank")
        i = int(where[0])
        sl = slice(offs[i], offs[i + 1])
        vers: tuple = ()
        if versions:
            vers = tuple((signal(v), float(bank.durations[v])) for v in find_versions(bank, i))
        out[int(pid)] = StoredSignal(
            signal=signal(i),
            points=np.asarray(bank.points)[sl],
            duration=float(bank.durations[i]),
            name=bank.names[i],
            versions=vers,
        )
    return out
