"""A trial series: learning a path's input on a real stage, one recorded trial at a time.

``start`` writes the first input (the library's warm start, or the model inverse where
nothing matches) and records the series; ``step`` records the measured output of the
pending trial and computes the next input (:class:`primlib.ilc.TrialLearner`: trial
averaging, the Q-filter's band and the noise floor from the trials); ``status`` says how
far it got; ``finish`` stores the converged input as a primitive. Every function takes an
open :class:`primlib.store.Library` and leaves the series consistent after each call: the
next input is a function of the recorded trials only, so a series resumes in any process.

Positions in and out are absolute (the machine's coordinates); the learning works on
positions relative to the series' origin, the path's first point, where the stage starts.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from primlib._errors import InputError, NoMatchError

__all__ = [
    "start",
    "step",
    "status",
    "finish",
    "pending",
    "learner",
    "StartResult",
    "StepResult",
    "SeriesStatus",
    "LEARN_OPTIONS",
]

# options of a series' learning law, with their defaults (primlib.ilc.TrialLearner)
LEARN_OPTIONS: dict[str, Any] = {
    "law": "norm-optimal",
    "noise_aware": True,
    "average": 32,
    "margin": 0.1,
    "q_cutoff": None,
}
# A measured output must start within this fraction of the path's extent of its first point.
_START_TOL = 0.05


@dataclass(frozen=True)
class StartResult:
    """A new series and its first input.

    Attributes
    ----------
    series : int
    t : array, shape (n,)
    u : array, shape (n, d)
        Trial 0's input.
    start : str
        ``"warm"`` (the library's warm start), ``"inverse"`` (nothing matched: the model
        inverse) or ``"cold"`` (zeros, asked for).
    notes : tuple of str
    """

    series: int
    t: np.ndarray
    u: np.ndarray
    start: str
    notes: tuple[str, ...]


@dataclass(frozen=True)
class StepResult:
    """What one step recorded and the input it wrote.

    Attributes
    ----------
    series, trial : int
        The trial just recorded.
    rms, contour_rms : float
        Its measured RMS tracking error (Euclidean) and RMS contour error (None in 1-D).
    noise_floor, q_cutoff : float or None
        The learner's estimates after it.
    converged, diverging : bool
    t : array, shape (n,)
    u : array, shape (n, d)
        The next trial's input.
    """

    series: int
    trial: int
    rms: float
    contour_rms: float | None
    noise_floor: float | None
    q_cutoff: float | None
    converged: bool
    diverging: bool
    t: np.ndarray
    u: np.ndarray


@dataclass(frozen=True)
class SeriesStatus:
    """Where a series stands.

    Attributes
    ----------
    record : SeriesRecord
    trials : list of TrialRecord
    noise_floor : float or None
        The latest estimate.
    converged, diverging : bool
    verdict : str
        ``"converged"``, ``"diverging"``, ``"learning"``, ``"finished"`` or ``"started"``.
    input_error : float or None
        The true (noise-free) RMS tracking error the last measured trial's input is
        estimated to leave (:meth:`primlib.ilc.TrialLearner.input_error`); None for a single
        measured trial. :func:`finish` stores the best trial's
        (:meth:`primlib.ilc.TrialLearner.best_input`) as the primitive's ``error_rms``.
    """

    record: Any
    trials: list
    noise_floor: float | None
    converged: bool
    diverging: bool
    verdict: str
    input_error: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays)."""
        r = self.record
        return {
            "series": r.id,
            "machine": r.machine,
            "name": r.name,
            "state": r.state,
            "start": r.start,
            "origin": r.origin.tolist(),
            "options": r.options,
            "notes": r.notes,
            "primitive": r.primitive,
            "verdict": self.verdict,
            "noise_floor": self.noise_floor,
            "input_error": self.input_error,
            "trials": [
                {
                    "trial": t.trial,
                    "rms": t.rms,
                    "contour_rms": t.contour_rms,
                    "noise_floor": t.noise_floor,
                    "q_cutoff": t.q_cutoff,
                    "pending": t.pending,
                }
                for t in self.trials
            ],
        }


def _store(lib):
    from primlib.store import TrialStore

    return TrialStore(lib)


def _options(options: dict[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(options) - set(LEARN_OPTIONS))
    if unknown:
        raise InputError(
            f"options: expected among {', '.join(LEARN_OPTIONS)}, got unknown {unknown[0]!r}"
        )
    return {**LEARN_OPTIONS, **options}


def learner(model, reference: np.ndarray, options: dict[str, Any]):
    """The :class:`primlib.ilc.TrialLearner` of a series' options."""
    from primlib.ilc import TrialLearner

    return TrialLearner(model, reference, **_options(options))


_FIRST = ("warm", "inverse", "cold")


def first_input(
    lib, traj, machine: str, *, first: str = "warm", eps: float | None = None
) -> tuple[np.ndarray, str, list[str]]:
    """The first input of a new path's trials, as :func:`start` records it.

    Parameters
    ----------
    lib : Library
    traj : Trajectory
        The path, absolute coordinates.
    machine : str
    first : {"warm", "inverse", "cold"}
        The library's warm start (where nothing matches, the inverse of the model fitted
        to the library's stored pairs, else of the machine's model), the machine model's
        inverse, or zero.
    eps : float, optional
        Match tolerance (default: 3e-4 of the path's extent).

    Returns
    -------
    u0 : ndarray, shape (n, d)
    kind : str
        ``"warm"``, ``"inverse"`` (also where nothing matched) or ``"cold"``.
    notes : list of str
        What was used and why.

    Raises
    ------
    InputError
        A path of another number of axes than the machine's, or an unknown ``first``.
    """
    model = _checked(lib, traj, machine, first)
    return _first_input(lib, traj, machine, model, traj.sample(model.dt), first, eps)


def _checked(lib, traj, machine: str, first: str):
    """The machine's model, once the path's axes and ``first`` are known to fit it."""
    model = lib.machine(machine)
    if traj.dim != model.dim:
        raise InputError(f"path: expected {model.dim} axes for machine {machine!r}, got {traj.dim}")
    if first not in _FIRST:
        raise InputError(f"first: expected one of {', '.join(_FIRST)}, got {first!r}")
    return model


def _first_input(lib, traj, machine: str, model, points: np.ndarray, first: str, eps):
    """:func:`first_input` on checked arguments and the path's samples ``points``."""
    from primlib.plant import invert

    ref = points - points[0]
    if first == "cold":
        return np.zeros_like(ref), "cold", ["cold start: the first input is zero"]
    if first == "inverse":
        return invert(model, ref), "inverse", ["the first input is the model inverse (asked for)"]
    from primlib.match import default_eps

    origin = points[0]  # a series' path is in absolute coordinates
    try:
        ws = lib.warm_start(traj, machine=machine, eps=eps or default_eps(traj), origin=origin)
    except NoMatchError as exc:
        return _model_only(lib, traj, machine, model, ref, origin, exc)
    notes = list(ws.notes)
    if ws.n_unmatched == len(ws.methods):
        notes.insert(
            0,
            "nothing in the library matches; the first input is the model inverse (the "
            "model fitted to the library's stored pairs)",
        )
        return ws.u, "inverse", notes
    if ws.n_unmatched:
        notes.insert(
            0,
            f"{ws.n_unmatched} of {len(ws.methods)} segments matched nothing; "
            "they start from the model inverse",
        )
    return ws.u, "warm", [*notes, *ws.sources]


def _model_only(lib, traj, machine: str, model, ref, origin, exc):
    """(u0, "inverse", notes) where nothing matched: the inverse of the model fitted to the
    library's stored pairs where it has any, else of the machine's model."""
    from primlib.plant import invert

    try:
        u, gb = lib.model_input(traj, machine, origin)
    except NoMatchError:
        note = f"nothing in the library matches ({exc}); the first input is the model inverse"
        return invert(model, ref), "inverse", [note]
    note = (
        f"nothing in the library matches ({exc}); the first input is the inverse of the "
        f"model fitted to the library's stored pairs: {gb.describe()}"
    )
    return u, "inverse", [note]


def start(
    lib,
    path,
    machine: str,
    *,
    first: str = "warm",
    eps: float | None = None,
    name: str | None = None,
    **options: Any,
) -> StartResult:
    """Start a trial series: record it and return its first input.

    Parameters
    ----------
    lib : Library
        Open for writing.
    path : Trajectory or str
        The path, absolute coordinates (a CSV file name is read).
    machine : str
        The machine (its model designs the law; its primitives give the warm start).
    first : {"warm", "inverse", "cold"}
        The first input: the library's warm start (default; where nothing matches, the
        model inverse), the model inverse, or zero.
    eps : float, optional
        Match tolerance (default: 3e-4 of the path's extent).
    name : str, optional
        The series' name (and the primitive's, when finished).
    **options
        The learning law: ``law``, ``noise_aware``, ``average``, ``margin``, ``q_cutoff``
        (:data:`LEARN_OPTIONS`, :class:`primlib.ilc.TrialLearner`).

    Returns
    -------
    StartResult
    """
    from primlib.nurbs import Trajectory

    traj = path if isinstance(path, Trajectory) else Trajectory.from_csv(path)
    model = _checked(lib, traj, machine, first)
    opts = _options(options)
    points = traj.sample(model.dt)
    learner(model, points - points[0], opts)  # checks the options before anything is written
    u0, kind, notes = _first_input(lib, traj, machine, model, points, first, eps)
    sid = _store(lib).create(
        traj, points, u0, machine=machine, start=kind, options=opts, notes=notes, name=name
    )
    return StartResult(sid, np.arange(len(points)) * model.dt, u0, kind, tuple(notes))


def pending(lib, series: int) -> tuple[int, np.ndarray, np.ndarray]:
    """The trial to run next: (trial number, t (n,), u (n, d)).

    Raises
    ------
    InputError
        The series is finished (no trial pending).
    """
    store = _store(lib)
    rec = store.series(series)
    trials = store.trials(series)
    if rec.state != "running" or not trials[-1].pending:
        raise InputError(f"trial series {series} is {rec.state}; no trial is pending")
    return trials[-1].trial, np.arange(rec.n_samples) * rec.dt, trials[-1].input


def _check_measured(rec, trials, measured: Any, label: str) -> tuple[np.ndarray, str]:
    y = np.asarray(measured, dtype=float)
    if y.shape != (rec.n_samples, rec.dim):
        raise InputError(
            f"{label}: expected a trial of {rec.n_samples} samples on {rec.dim} axes, got "
            f"shape {y.shape}"
        )
    if not np.isfinite(y).all():
        raise InputError(f"{label}: expected finite positions, got NaN or inf")
    digest = hashlib.sha256(np.ascontiguousarray(y).tobytes()).hexdigest()
    done = [t for t in trials if not t.pending]
    if done and done[-1].digest == digest:
        raise InputError(
            f"{label}: the same measured output as trial {done[-1].trial}; run the new input "
            "on the stage first"
        )
    tol = _START_TOL * max(rec.trajectory.extent, 1e-12)
    if np.linalg.norm(y[0] - rec.origin) > tol:
        raise InputError(
            f"{label}: expected the stage to start at the path's first point "
            f"{np.round(rec.origin, 6).tolist()} (absolute coordinates), got "
            f"{np.round(y[0], 6).tolist()}"
        )
    return y, digest


def _contour_rms(points: np.ndarray, dt: float, y: np.ndarray) -> float | None:
    if points.shape[1] < 2:
        return None
    from primlib.contour import contour_error

    ce = contour_error(points, np.arange(len(points)) * dt, y)
    return float(np.sqrt(np.mean(ce**2)))


def step(lib, series: int, measured: Any, *, label: str = "measured") -> StepResult:
    """Record the pending trial's measured output and compute the next input.

    Parameters
    ----------
    lib : Library
        Open for writing.
    series : int
    measured : array, shape (n, d)
        The measured positions of the pending trial, absolute coordinates.
    label : str
        Names the measurement in messages (the CLI passes the file name).

    Returns
    -------
    StepResult

    Raises
    ------
    InputError
        Wrong shape, NaN, the same output as the last trial, a start away from the path's
        first point, or a finished series.
    LibraryBusyError
        Another process stepped the series meanwhile (nothing recorded).
    """
    store = _store(lib)
    rec = store.series(series)
    trials = store.trials(series)
    if rec.state != "running":
        raise InputError(f"trial series {series} is {rec.state}; it takes no more trials")
    y, digest = _check_measured(rec, trials, measured, label)
    k = rec.steps
    inputs = np.stack([t.input for t in trials[: k + 1]])
    outputs = np.stack([*(t.measured for t in trials[:k]), y]) - rec.origin
    ref = rec.points - rec.origin
    upd = learner(lib.machine(rec.machine), ref, rec.options).update(inputs, outputs)
    contour = _contour_rms(rec.points, rec.dt, y)
    rms_axes = np.sqrt(np.mean((ref - outputs[-1]) ** 2, axis=0))
    metrics = {
        "rms": upd.rms,
        "rms_axes": rms_axes,
        "contour_rms": contour,
        "noise_floor": upd.noise_floor,
        "q_cutoff": upd.q_cutoff,
    }
    store.record_step(series, k, y, digest, metrics, upd.u)
    return StepResult(
        series=series,
        trial=k,
        rms=upd.rms,
        contour_rms=contour,
        noise_floor=upd.noise_floor,
        q_cutoff=upd.q_cutoff,
        converged=upd.converged,
        diverging=upd.diverging,
        t=np.arange(rec.n_samples) * rec.dt,
        u=upd.u,
    )


def status(lib, series: int) -> SeriesStatus:
    """Where a series stands: its trials' errors and the stop rule's verdict."""
    store = _store(lib)
    rec = store.series(series)
    trials = store.trials(series)
    done = [t for t in trials if not t.pending]
    floor, converged, diverging, worth = None, False, False, None
    if done:
        lrn, inputs, outputs = _history(lib, rec, done)
        est, converged, diverging = lrn.assess(inputs, outputs)
        floor = None if est is None else est.floor
        worth = lrn.input_error(inputs, outputs)
    if rec.state == "finished":
        verdict = "finished"
    elif not done:
        verdict = "started"
    else:
        verdict = "converged" if converged else "diverging" if diverging else "learning"
    return SeriesStatus(rec, trials, floor, converged, diverging, verdict, worth)


def _source(rec, done, run: tuple[int, int], floor: float | None) -> str:
    where = ", ".join(f"{v:.6g}" for v in rec.origin)
    floor_s = "unknown" if floor is None else f"{floor:.6g}"
    k0, k1 = run
    if k1 - k0 > 1:
        which = f"the mean input of trials {done[k0].trial}-{done[k1 - 1].trial} (settled)"
        which += f", their mean rms {np.mean([t.rms for t in done[k0:k1]]):.6g}"
    else:
        trial = done[k0]
        which = "final" if k0 == len(done) - 1 else f"trial {trial.trial}'s (the best)"
        which += f" rms {trial.rms:.6g}"
    return (
        f"trial series {rec.id}: {len(done)} trials on machine {rec.machine!r}, {which}, "
        f"noise floor {floor_s}, started at ({where})"
    )


def _history(lib, rec, done):
    """(learner, inputs, outputs) of a series' measured trials, outputs relative to its
    start: what the learner's verdicts are computed from."""
    lrn = learner(lib.machine(rec.machine), rec.points - rec.origin, rec.options)
    inputs = np.stack([t.input for t in done])
    return lrn, inputs, np.stack([t.measured for t in done]) - rec.origin


def finish(lib, series: int, *, name: str | None = None, force: bool = False) -> int:
    """Store a series' converged input as a primitive and close the series.

    The pair stored is the input of the measured trial with the lowest RMS error
    (:meth:`primlib.ilc.TrialLearner.best_input`; the last one while the errors fall), or
    the mean input of a run of settled trials where that is estimated to leave less
    (:meth:`primlib.ilc.TrialLearner.stored_input`: near the floor each input carries a
    copy of the last trial's disturbance, and the mean averages them out), with the path,
    the series'
    ``origin`` (the absolute start position) as the primitive's ``origin``, and the true
    error that input is estimated to leave as its ``error_rms``; its ``source``
    names the series, its number of trials, final error, noise floor and that position
    (all of which the series row keeps too).

    Parameters
    ----------
    lib : Library
        Open for writing.
    series : int
    name : str, optional
        The primitive's name (default: the series' name, else ``series-<id>``).
    force : bool
        Store it even though the stop rule does not say converged.

    Returns
    -------
    int
        The new primitive's id.

    Raises
    ------
    InputError
        Not converged (without ``force``), no measured trial, or already finished.
    """
    st = status(lib, series)
    rec = st.record
    if rec.state != "running":
        raise InputError(f"trial series {series} is {rec.state} (primitive {rec.primitive})")
    done = [t for t in st.trials if not t.pending]
    if not done:
        raise InputError(f"trial series {series} has no measured trial yet; step it first")
    if not st.converged and not force:
        raise InputError(
            f"trial series {series} has not converged ({st.verdict}, last rms "
            f"{done[-1].rms:.6g}, noise floor {st.noise_floor}); run more trials, or force it"
        )
    lrn, inputs, outputs = _history(lib, rec, done)
    u, worth, run = lrn.stored_input(inputs, outputs)
    source = _source(rec, done, run, st.noise_floor)
    # a finish interrupted between its two transactions left the primitive: reuse it
    prefix = f"trial series {rec.id}:"
    stored = [p.id for p in lib.primitives(rec.machine) if (p.source or "").startswith(prefix)]
    pid = stored[0] if stored else None
    if pid is None:
        pid = lib.add(
            rec.trajectory,
            u,
            machine=rec.machine,
            name=name or rec.name or f"series-{rec.id}",
            source=source,
            origin=rec.origin,  # where it ran: the position the stage started each trial
            error_rms=worth,  # what its input is worth there, noise learned included
        )
    _store(lib).mark_finished(series, pid)
    return int(pid)
