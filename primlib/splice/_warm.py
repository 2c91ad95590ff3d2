"""Warm start: match a new path, splice the stored signals, and learn from there.

``warm_start`` is the library's use (primitive-matching paper, figure 1): match the new path
against the machine's primitives (:func:`primlib.match.match_path`), transform and splice
their converged inputs (:func:`primlib.splice.splice`) into the first-iteration input.
``learn_signal`` closes the loop: ILC on the machine model from that input (or from zero),
whose converged input the library stores as a new primitive.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from primlib._errors import InputError, NoMatchError
from primlib.match import DEFAULT_EPS, default_eps
from primlib.splice._splice import Band, StoredSignal, splice

__all__ = [
    "WarmStart",
    "warm_start",
    "learn_signal",
    "find_versions",
    "stored_signals",
    "DEFAULT_EPS",
]


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
    """

    u: np.ndarray
    t: np.ndarray
    match: Any
    bands: tuple[Band, ...]
    sample_segment: np.ndarray
    sources: tuple[str, ...]
    methods: tuple[str, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    model: Any = None
    spliced: np.ndarray | None = None

    @property
    def n_unmatched(self) -> int:
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
            "match": self.match.to_dict() if hasattr(self.match, "to_dict") else None,
        }


def _normalised(points: np.ndarray, m: int = _VERSION_SAMPLES) -> np.ndarray:
    n = points.shape[0]
    x = np.linspace(0.0, n - 1.0, m)
    lo = np.minimum(np.floor(x).astype(int), n - 2)
    f = (x - lo)[:, None]
    return points[lo] * (1 - f) + points[lo + 1] * f


def find_versions(bank, index: int, tol: float = _VERSION_TOL) -> list[int]:
    """Indices of bank primitives that are the primitive ``index`` at another duration.

    Same shape and pose: their paths, sampled at 64 uniform normalised times, agree with
    primitive ``index``'s to ``tol`` times its extent; their durations differ by at least
    5 %. These are what eq. (20) combines.

    Parameters
    ----------
    bank : Bank
        ``ids``, ``durations``, ``offsets``, ``points`` as :meth:`Library.bank` returns.
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


def stored_signals(bank, ids, *, versions: bool = True) -> dict[int, StoredSignal]:
    """The splice's view of the given primitive ids, read from a bank (one query)."""
    ids_arr = np.asarray(bank.ids)
    offs = np.asarray(bank.offsets)
    out: dict[int, StoredSignal] = {}
    for pid in ids:
        where = np.flatnonzero(ids_arr == pid)
        if where.size == 0:
            raise InputError(f"match: primitive {pid} is not in the library's bank")
        i = int(where[0])
        sl = slice(offs[i], offs[i + 1])
        vers: tuple = ()
        if versions:
            vers = tuple(
                (np.asarray(bank.signals)[offs[v] : offs[v + 1]], float(bank.durations[v]))
                for v in find_versions(bank, i)
            )
        out[int(pid)] = StoredSignal(
            signal=np.asarray(bank.signals)[sl],
            points=np.asarray(bank.points)[sl],
            duration=float(bank.durations[i]),
            name=bank.names[i],
            versions=vers,
        )
    return out


_REFINED: dict = {}
_REFINE_MAX = 24  # primitives a refinement fits on (matched ones first)


def _refined(m, bank, ids):
    """The model refined on the matched primitives, plus others of the bank up to 24, so
    that an axis the matched pieces do not move (a rotation can move it on the new path)
    is refined too. Cached per machine model and primitive set."""
    from primlib.splice._refine import refine_machine

    all_ids = [int(i) for i in np.asarray(bank.ids)]
    chosen = [i for i in ids if i in all_ids]
    chosen += [i for i in all_ids if i not in chosen][: max(0, _REFINE_MAX - len(chosen))]
    stored = stored_signals(bank, chosen, versions=False)
    digest = hashlib.blake2b(digest_size=16)
    for pid in sorted(chosen):
        digest.update(np.ascontiguousarray(stored[pid].signal).tobytes())
        digest.update(np.ascontiguousarray(stored[pid].points).tobytes())
    key = (repr(m.to_dict()), digest.hexdigest())  # the data, not the ids: ids repeat
    hit = _REFINED.get(key)
    if hit is not None:
        return hit
    pairs = [(s.signal, s.points - s.points[0]) for s in stored.values()]
    model = refine_machine(m, pairs)
    if len(_REFINED) > 64:
        _REFINED.clear()
    _REFINED[key] = model
    return model


def _trajectory(path):
    from primlib.nurbs import Trajectory

    if isinstance(path, Trajectory):
        return path
    return Trajectory.from_csv(path)


def warm_start(
    library,
    path,
    machine: str,
    eps: float,
    *,
    band: float | None = None,
    method: str = "auto",
    refine: bool = True,
    correction: str = "error",
    match=None,
    **kw,
):
    """First-iteration ILC input for a new path from the library's primitives.

    Parameters
    ----------
    library : Library
    path : Trajectory or str
        The new path (a CSV file name is read).
    machine : str
        Machine name; only its primitives are used.
    eps : float
        RMSD tolerance of the match (user units, > 0).
    band : float, optional
        Transition band width in seconds (default 8 dt).
    method : {"auto", "model", "direct"}
        Time-scaling method, see :func:`primlib.splice.splice`.
    refine : bool
        Refine the machine model on stored (input, path) pairs — the matched primitives',
        then others of the machine up to 24 — before
        transforming (:func:`primlib.splice.refine_machine`): the stored signals were
        learned on the real machine, so they say how it differs from its model; the time
        scale, the axis mixing and the residual correction then use the refined model.
    correction : {"error", "input", "output", "junction", "none"}
        Residual correction (:func:`primlib.splice.splice`). Default ``"error"``: the
        inverse of the model in use of the path minus the model's error that the matched
        pieces' stored pairs measured (time-scaled, rotated, accumulated along the path),
        so the model's error only enters through what the library does not already know;
        unmatched segments then get that model's inverse of the path. The others are kept
        for comparison (benchmarks/bench_warm_start.py).
    match : Match, optional
        A match already computed for this path and machine (skips matching).
    **kw
        Passed to :func:`primlib.match.match_path` (``rotation``, ``time_scale``...).

    Returns
    -------
    WarmStart

    Raises
    ------
    NoMatchError
        When the machine has no primitives (or nothing matches at all).
    NotFoundError
        For an unknown machine.

    Examples
    --------
    >>> ws = lib.warm_start(path, machine="xyz", eps=0.05)
    >>> ws.u.shape == (round(path.duration / 0.005) + 1, 3)
    True
    """
    traj = _trajectory(path)
    m = library.machine(machine)
    if match is None:
        match = library.match(traj, machine=machine, eps=eps, **kw)
    ids = sorted({s.primitive for s in match.segments if s.primitive is not None})
    stored = stored_signals(library.bank(machine), ids) if ids else {}
    pts = traj.sample(m.dt)
    model = None
    used = m
    if refine and stored and not m.feedback:
        model = _refined(m, library.bank(machine), ids)
        used = model.machine
    res = splice(
        used,
        pts,
        traj.duration,
        match.segments,
        stored,
        band=band,
        method=method,
        inverse_machine=m,
        correction=correction,
    )
    notes = res.notes
    if model is not None:
        th = ", ".join(
            f"{a}: gain {g:.4g}, time scale {c:.4g}, lag {tau * 1e3:.3g} ms"
            for a, (g, c, tau) in zip(m.axes, model.theta, strict=True)
        )
        notes = (*notes, f"model refined on the library's stored pairs: {th}")
    t = np.arange(pts.shape[0]) * m.dt
    return WarmStart(
        u=res.u,
        t=t,
        match=match,
        bands=res.bands,
        sample_segment=res.sample_segment,
        sources=res.sources,
        methods=res.methods,
        notes=notes,
        model=model,
        spliced=res.spliced,
    )


def learn_signal(
    library,
    trajectory,
    machine: str,
    iterations: int = 30,
    cold: bool = False,
    *,
    eps: float | None = None,
    tol: float | None = None,
    law: str = "norm-optimal",
) -> np.ndarray:
    """Converged ILC input for a path on a machine's model, warm-started from the library.

    Parameters
    ----------
    library : Library
    trajectory : Trajectory or str
    machine : str
    iterations : int
        ILC trials at most.
    cold : bool
        Start from zero instead of the library's warm start.
    eps : float, optional
        Match tolerance; default ``DEFAULT_EPS`` (3e-4) times the path's extent.
    tol : float, optional
        Stop when the RMS tracking error falls below this (user units).
    law : str
        ILC law (:func:`primlib.ilc.learn`).

    Returns
    -------
    u : array, shape (n, d)
        The last input, on the machine's grid for the path.
    """
    from primlib.ilc import learn

    traj = _trajectory(trajectory)
    m = library.machine(machine)
    pts = traj.sample(m.dt)
    ref = pts - pts[0]
    u0 = None
    if not cold:
        e = eps if eps is not None else default_eps(traj)
        try:
            u0 = warm_start(library, traj, machine, e).u
        except NoMatchError:
            u0 = None
    res = learn(m, ref, u0, law=law, iterations=int(iterations), tol=tol, contour=False)
    return np.asarray(res.u)
