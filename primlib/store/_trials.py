"""Trial series in the library: the ``series`` and ``trials`` tables (schema version 3).

A trial series is learning on a real stage, one trial at a time, across processes: the
series row holds the path (NURBS and sampled on the machine's grid, absolute coordinates),
where it runs (the absolute start position) and a step counter; a trial row holds the input
that was (or is to be) run and, once measured, the measured output and its errors.

Every write is one transaction. A step records the measured output of the pending trial and
the next input together, and only if the series' step counter still has the value the
caller read (``UPDATE ... WHERE steps = expected``): two processes that step one series
never both succeed. DuckDB's file lock already keeps a second process out while one has the
library open for writing; the counter also covers a process that read the series, ran a
trial while the library was closed, and comes back after someone else stepped it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

import numpy as np

from primlib._errors import InputError, LibraryBusyError, NotFoundError
from primlib.store._connection import transaction
from primlib.store._schema import utcnow

__all__ = ["TrialStore", "SeriesRecord", "TrialRecord"]

_SERIES_INFO = (
    "id, machine, name, created, state, start, options, notes, duration, dt, dim, n_samples, "
    "steps, primitive, finished"
)


@dataclass(frozen=True)
class TrialRecord:
    """One trial of a series.

    Attributes
    ----------
    trial : int
        0, 1, 2, ... in the order run.
    input : array, shape (n, d)
        The input that was (or is to be) run.
    measured : array, shape (n, d) or None
        The measured output, absolute positions; None while the trial is pending.
    digest : str or None
        SHA-256 of the measured array (a repeated file is refused).
    rms, contour_rms : float or None
        RMS Euclidean tracking error and RMS contour error of the measured output.
    rms_axes : array, shape (d,) or None
    noise_floor : float or None
        The noise floor the learning law estimated after this trial (None before two).
    q_cutoff : float or None
        The Q-filter cut-off (Hz) of the update that followed this trial.
    created, recorded : datetime or None
        When the input was written, when the measurement was recorded (UTC).
    """

    trial: int
    input: np.ndarray
    measured: np.ndarray | None
    digest: str | None
    rms: float | None
    rms_axes: np.ndarray | None
    contour_rms: float | None
    noise_floor: float | None
    q_cutoff: float | None
    created: datetime
    recorded: datetime | None

    @property
    def pending(self) -> bool:
        """True while the trial has no measured output."""
        return self.measured is None


@dataclass(frozen=True)
class SeriesRecord:
    """A trial series' row: what it learns, where, and how far it got.

    Attributes
    ----------
    id : int
    machine : str
    name : str or None
    created : datetime
    state : str
        ``"running"`` or ``"finished"``.
    start : str
        How the first input was made: ``"warm"``, ``"inverse"`` or ``"cold"``.
    options : dict
        The learning options (law, noise awareness, averaging, margin...).
    notes : list of str
    duration, dt : float
    dim, n_samples : int
    steps : int
        Trials measured so far.
    primitive : int or None
        The primitive it was stored as, once finished.
    finished : datetime or None
    trajectory : Trajectory
        The path, absolute coordinates.
    points : array, shape (n, d)
        The path on the machine's grid, absolute.
    origin : array, shape (d,)
        The absolute start position (the path's first point), where the series ran.
    """

    id: int
    machine: str
    name: str | None
    created: datetime
    state: str
    start: str
    options: dict
    notes: list
    duration: float
    dt: float
    dim: int
    n_samples: int
    steps: int
    primitive: int | None
    finished: datetime | None
    trajectory: Any
    points: np.ndarray
    origin: np.ndarray


def _utc(value: datetime | None) -> datetime | None:
    return None if value is None else value.replace(tzinfo=UTC)


def _arr(values: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    if values is None:
        return None
    return np.asarray(values, dtype=np.float64).reshape(shape)


def _flat(a: np.ndarray) -> list[float]:
    return np.ascontiguousarray(a, dtype=np.float64).ravel().tolist()


class TrialStore:
    """The trial series of one library (its ``series`` and ``trials`` tables).

    Parameters
    ----------
    library : Store
        An open library (a :class:`primlib.store.Store`, or ``primlib.Library``); writes
        need it open for writing.

    Examples
    --------
    >>> store = TrialStore(lib)
    >>> pts = path.sample(0.005)
    >>> sid = store.create(path, pts, np.zeros_like(pts), machine="xyz", start="cold", options={})
    >>> store.trials(sid)[0].pending, store.series(sid).steps
    (True, 0)
    """

    def __init__(self, library: Any) -> None:
        self._lib = library

    @property
    def label(self) -> str:
        """The library's name for messages."""
        return self._lib._label

    # ------------------------------------------------------------------ writing
    def create(
        self,
        trajectory: Any,
        points: np.ndarray,
        u0: np.ndarray,
        *,
        machine: str,
        start: str,
        options: dict,
        notes: list[str] | tuple[str, ...] = (),
        name: str | None = None,
    ) -> int:
        """Record a new series and its first input (trial 0) in one transaction.

        Parameters
        ----------
        trajectory : Trajectory
            The path, absolute coordinates.
        points : array, shape (n, d)
            The path on the machine's grid t = 0, dt, ..., T.
        u0 : array, shape (n, d)
            The first trial's input.
        machine, start, options, notes, name
            See :class:`SeriesRecord`.

        Returns
        -------
        int
            The series id (never reused).
        """
        dt, axes, _ = self._lib._machine_row(machine)
        points = np.asarray(points, dtype=np.float64)
        u0 = np.asarray(u0, dtype=np.float64)
        n, d = points.shape
        if d != len(axes) or u0.shape != (n, d):
            raise InputError(
                f"series: expected path and input of shape (n, {len(axes)}) for machine "
                f"{machine!r}, got {points.shape} and {u0.shape}"
            )
        definition = trajectory.definition()
        now = utcnow()
        with transaction(self._lib._writable()) as con:
            sid = int(con.sql("SELECT nextval('series_ids')").fetchall()[0][0])
            con.execute(
                "INSERT INTO series VALUES ($id, $m, $name, $t, 'running', $start, $opt, $notes, "
                "$dur, $dt, $d, $n, $deg, $knots, $ctrl, $w, $pts, $origin, 0, NULL, NULL)",
                {
                    "id": sid,
                    "m": machine,
                    "name": name,
                    "t": now,
                    "start": start,
                    "opt": json.dumps(options, sort_keys=True),
                    "notes": json.dumps(list(notes)),
                    "dur": float(trajectory.duration),
                    "dt": dt,
                    "d": d,
                    "n": n,
                    "deg": int(definition["degree"]),
                    "knots": _flat(np.asarray(definition["knots"])),
                    "ctrl": _flat(np.asarray(definition["ctrlpts"])),
                    "w": _flat(np.asarray(definition["weights"])),
                    "pts": _flat(points),
                    "origin": _flat(points[0]),
                },
            )
            con.execute(
                "INSERT INTO trials (series, trial, input, created) VALUES ($s, 0, $u, $t)",
                {"s": sid, "u": _flat(u0), "t": now},
            )
        return sid

    def record_step(
        self,
        series: int,
        expected_steps: int,
        measured: np.ndarray,
        digest: str,
        metrics: dict[str, Any],
        next_input: np.ndarray | None,
        trial_metrics: dict[int, dict[str, Any]] | None = None,
    ) -> None:
        """Record the pending trial's measured output and the next input, atomically.

        Parameters
        ----------
        series : int
        expected_steps : int
            The step counter the caller read; the step is refused if it changed since.
        measured : array, shape (n, d)
            Absolute measured positions of trial ``expected_steps``.
        digest : str
            Its SHA-256.
        metrics : dict
            ``rms``, ``rms_axes``, ``contour_rms``, ``noise_floor``, ``q_cutoff``.
        next_input : array, shape (n, d) or None
            The input of the next trial (None: no further trial).

        Raises
        ------
        LibraryBusyError
            The series was stepped by someone else since it was read (nothing recorded).
        InputError
            The series is finished.
        """
        trial = int(expected_steps)
        now = utcnow()
        with transaction(self._lib._writable()) as con:
            rows = con.execute(
                "UPDATE series SET steps = steps + 1 WHERE id = $s AND steps = $k "
                "AND state = 'running' RETURNING steps",
                {"s": series, "k": trial},
            ).fetchall()
            if not rows:
                self._refuse_step(con, series, trial)
            con.execute(
                "UPDATE trials SET measured = $y, digest = $h, rms = $rms, rms_axes = $ra, "
                "contour_rms = $c, noise_floor = $nf, q_cutoff = $q, recorded = $t "
                "WHERE series = $s AND trial = $k",
                {
                    "y": _flat(measured),
                    "h": digest,
                    "rms": metrics.get("rms"),
                    "ra": _flat(np.asarray(metrics["rms_axes"])),
                    "c": metrics.get("contour_rms"),
                    "nf": metrics.get("noise_floor"),
                    "q": metrics.get("q_cutoff"),
                    "t": now,
                    "s": series,
                    "k": trial,
                },
            )
            if next_input is not None:
                con.execute(
                    "INSERT INTO trials (series, trial, input, created) VALUES ($s, $k, $u, $t)",
                    {"s": series, "k": trial + 1, "u": _flat(next_input), "t": now},
                )

    def _refuse_step(self, con: Any, series: int, trial: int) -> None:
        row = con.sql(
            "SELECT steps, state FROM series WHERE id = $s", params={"s": series}
        ).fetchall()
        if not row:
            raise NotFoundError(f"no trial series with id {series} in {self.label}")
        steps, state = row[0]
        if state != "running":
            raise InputError(f"trial series {series} is {state}; it takes no more trials")
        raise LibraryBusyError(
            f"trial series {series} was stepped by another process meanwhile (trial {trial} is "
            f"already recorded, {steps} trials now); nothing recorded, check its status"
        )

    def mark_finished(self, series: int, primitive: int) -> None:
        """Set a running series finished, stored as ``primitive`` (one transaction)."""
        with transaction(self._lib._writable()) as con:
            rows = con.execute(
                "UPDATE series SET state = 'finished', primitive = $p, finished = $t "
                "WHERE id = $s AND state = 'running' RETURNING id",
                {"p": int(primitive), "t": utcnow(), "s": series},
            ).fetchall()
            if not rows:
                self._refuse_step(con, series, -1)

    # ------------------------------------------------------------------ reading
    def ids(self, machine: str | None = None) -> list[int]:
        """Ids of the series (of one machine), in order."""
        con = self._lib._db()
        if machine is None:
            rows = con.sql("SELECT id FROM series ORDER BY id").fetchall()
        else:
            rows = con.sql(
                "SELECT id FROM series WHERE machine = $m ORDER BY id", params={"m": machine}
            ).fetchall()
        return [int(r[0]) for r in rows]

    def series(self, series: int) -> SeriesRecord:
        """One series with its path.

        Raises
        ------
        NotFoundError
            No series with that id.
        """
        from primlib.nurbs import Trajectory

        if isinstance(series, bool) or not isinstance(series, (int, np.integer)):
            raise InputError(f"series: expected an integer series id, got {series!r}")
        rows = (
            self._lib._db()
            .sql(
                f"SELECT {_SERIES_INFO}, degree, knots, ctrlpts, weights, points, origin "
                "FROM series WHERE id = $s",
                params={"s": int(series)},
            )
            .fetchall()
        )
        if not rows:
            raise NotFoundError(f"no trial series with id {series} in {self.label}")
        r = rows[0]
        (sid, machine, name, created, state, start, options, notes, T, dt, d, n) = r[:12]
        steps, primitive, finished, degree, knots, ctrl, weights, pts, origin = r[12:]
        trajectory = Trajectory.from_definition(
            int(degree),
            np.asarray(knots),
            np.asarray(ctrl).reshape(-1, d),
            np.asarray(weights),
            float(T),
        )
        return SeriesRecord(
            id=int(sid),
            machine=machine,
            name=name,
            created=_utc(created),
            state=state,
            start=start,
            options=json.loads(options),
            notes=json.loads(notes),
            duration=float(T),
            dt=float(dt),
            dim=int(d),
            n_samples=int(n),
            steps=int(steps),
            primitive=None if primitive is None else int(primitive),
            finished=_utc(finished),
            trajectory=trajectory,
            points=_arr(pts, (n, d)),
            origin=_arr(origin, (d,)),
        )

    def trials(self, series: int) -> list[TrialRecord]:
        """Every trial of a series with its arrays, in order."""
        rec = self.series(series)
        n, d = rec.n_samples, rec.dim
        rows = (
            self._lib._db()
            .sql(
                "SELECT trial, input, measured, digest, rms, rms_axes, contour_rms, noise_floor, "
                "q_cutoff, created, recorded FROM trials WHERE series = $s ORDER BY trial",
                params={"s": int(series)},
            )
            .fetchall()
        )
        return [
            TrialRecord(
                trial=int(k),
                input=_arr(u, (n, d)),
                measured=_arr(y, (n, d)),
                digest=h,
                rms=rms,
                rms_axes=_arr(ra, (d,)),
                contour_rms=c,
                noise_floor=nf,
                q_cutoff=q,
                created=_utc(t0),
                recorded=_utc(t1),
            )
            for k, u, y, h, rms, ra, c, nf, q, t0, t1 in rows
        ]

    def for_primitive(self, primitive: int) -> int | None:
        """The series a primitive was finished from, or None."""
        rows = (
            self._lib._db()
            .sql("SELECT id FROM series WHERE primitive = $p", params={"p": int(primitive)})
            .fetchall()
        )
        return int(rows[0][0]) if rows else None
