"""Running a series' trials on a plant until the stop rule says so.

``run_trials`` steps a series on any :class:`Plant` with the library kept open;
``run_command`` runs it on an external program and opens the library only to read the
pending input and to record each step, so the library can be read (``trials status``)
while a trial runs, and a failure of the program loses no recorded trial. Both stop at
convergence, on divergence, or after ``max_trials``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.trials._plant import CommandPlant
from primlib.trials._series import StepResult, pending, step

__all__ = ["run_trials", "run_command", "RunResult", "TrialSeries"]


@dataclass(frozen=True)
class RunResult:
    """Trials run by one call, and why it stopped.

    Attributes
    ----------
    steps : list of StepResult
    stopped : str
        ``"converged"``, ``"diverging"`` or ``"max-trials"``.
    """

    steps: list
    stopped: str


def _check_max(max_trials: Any) -> int:
    if isinstance(max_trials, bool) or not isinstance(max_trials, (int, np.integer)):
        raise InputError(f"max_trials: expected an integer >= 1, got {max_trials!r}")
    if max_trials < 1:
        raise InputError(f"max_trials: expected an integer >= 1, got {max_trials}")
    return int(max_trials)


def _stop(res: StepResult) -> str | None:
    return "converged" if res.converged else "diverging" if res.diverging else None


def run_trials(
    lib,
    series: int,
    plant,
    max_trials: int = 20,
    callback: Callable[[StepResult], None] | None = None,
) -> RunResult:
    """Run a series' pending trials on a Python plant.

    Parameters
    ----------
    lib : Library
        Open for writing.
    series : int
    plant : Plant
        ``run(u) -> y``, y relative to the start point.
    max_trials : int
        Trials to run at most in this call.
    callback : callable, optional
        Called with each :class:`StepResult`.

    Returns
    -------
    RunResult
    """
    from primlib.store import TrialStore

    max_trials = _check_max(max_trials)
    origin = TrialStore(lib).series(series).origin
    steps: list[StepResult] = []
    for _ in range(max_trials):
        _, _, u = pending(lib, series)
        y = np.asarray(plant.run(u), dtype=float)
        res = step(lib, series, y + origin, label=f"trial on {type(plant).__name__}")
        steps.append(res)
        if callback is not None:
            callback(res)
        why = _stop(res)
        if why:
            return RunResult(steps, why)
    return RunResult(steps, "max-trials")


def run_command(
    db: str,
    series: int,
    command: str,
    *,
    max_trials: int = 20,
    timeout: float | None = None,
    workdir: str = ".",
    callback: Callable[[StepResult], None] | None = None,
) -> RunResult:
    """Run a series' trials on an external program (see :class:`CommandPlant`).

    The library file is opened for each read and each step and closed while the program
    runs. A step is refused if another process stepped the series meanwhile.

    Parameters
    ----------
    db : str
        The library file.
    series : int
    command : str
        ``"CMD {input} {output}"``.
    max_trials : int
    timeout : float, optional
        Seconds per trial.
    workdir : str
        Folder for the trial files (``series<ID>-trial<k>-input.csv``, ``...-measured.csv``).
    callback : callable, optional
        Called with each :class:`StepResult`.

    Returns
    -------
    RunResult

    Raises
    ------
    TrialCommandError
        The program failed; every trial recorded before stays recorded.
    """
    from primlib.pipeline import Library
    from primlib.store import TrialStore

    max_trials = _check_max(max_trials)
    with Library(db, create=False) as lib:
        rec = TrialStore(lib).series(series)
        pending(lib, series)
    plant = CommandPlant(command, rec.dt, rec.origin, workdir, timeout, prefix=f"series{series}")
    steps: list[StepResult] = []
    for _ in range(max_trials):
        with Library(db, create=False) as lib:
            trial, _, u = pending(lib, series)
        plant.trial = trial
        y = plant.run_absolute(u)
        with Library(db, create=False) as lib:
            res = step(lib, series, y, label=str(plant.files(trial)[1]))
        steps.append(res)
        if callback is not None:
            callback(res)
        why = _stop(res)
        if why:
            return RunResult(steps, why)
    return RunResult(steps, "max-trials")


class TrialSeries:
    """One trial series of a library, for scripts: the functions of this package as methods.

    Parameters
    ----------
    lib : Library
        Open (for writing, to step or finish).
    series : int

    Examples
    --------
    >>> s = TrialSeries.start(lib, path, machine="xyz", first="inverse")
    >>> s.status().verdict
    'started'
    >>> result = s.run(m, max_trials=1)  # a Machine is a Plant; so is your stage
    >>> [t.pending for t in s.status().trials]
    [False, True]
    """

    def __init__(self, lib, series: int) -> None:
        from primlib.store import TrialStore

        TrialStore(lib).series(series)  # NotFoundError for an unknown id
        self.lib = lib
        self.id = int(series)

    @classmethod
    def start(cls, lib, path, machine: str, **kw: Any) -> TrialSeries:
        """Start a series (:func:`primlib.trials.start`) and return it."""
        from primlib.trials._series import start

        return cls(lib, start(lib, path, machine, **kw).series)

    def pending(self):
        """(trial, t, u) of the trial to run next."""
        return pending(self.lib, self.id)

    def step(self, measured, label: str = "measured") -> StepResult:
        """Record the pending trial's measured output (absolute positions)."""
        return step(self.lib, self.id, measured, label=label)

    def run(self, plant, max_trials: int = 20, callback=None) -> RunResult:
        """Run trials on a plant until the stop rule (:func:`run_trials`)."""
        return run_trials(self.lib, self.id, plant, max_trials, callback)

    def status(self):
        """The series' :class:`SeriesStatus`."""
        from primlib.trials._series import status

        return status(self.lib, self.id)

    def finish(self, name: str | None = None, force: bool = False) -> int:
        """Store the converged input as a primitive; its id."""
        from primlib.trials._series import finish

        return finish(self.lib, self.id, name=name, force=force)

    def __repr__(self) -> str:
        return f"TrialSeries({self.lib!r}, {self.id})"
