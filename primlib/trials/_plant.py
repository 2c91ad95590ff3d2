"""What runs a trial: the ``Plant`` protocol, and a plant that is an external program.

A trial takes the input u (n x d, on the machine's grid) and returns the output y (n x d)
relative to the start point, like :meth:`primlib.plant.Machine.simulate`. ``Machine`` is a
plant (``Machine.run``); a user's hardware class is one by having ``run(u)``.
:class:`CommandPlant` runs one trial through a user's program over files: it writes the
input as a signal CSV (``t,ux,uy[,uz]``), runs the command, and reads the measured
positions it wrote (a path CSV ``t,x,y[,z]`` in the machine's absolute coordinates).
"""

from __future__ import annotations

import os
import shlex
import subprocess
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from primlib._errors import InputError, PrimlibError

__all__ = ["Plant", "CommandPlant", "TrialCommandError", "read_measured"]


@runtime_checkable
class Plant(Protocol):
    """Anything that runs one trial: ``run(u) -> y``.

    ``u`` : array, shape (n, d), the input on the machine's grid; ``y`` : array, shape
    (n, d), the output relative to the start point (the stage starts at rest at the path's
    first point). :class:`primlib.plant.Machine` satisfies it.
    """

    def run(self, u: np.ndarray) -> np.ndarray:  # pragma: no cover - protocol
        ...


class TrialCommandError(PrimlibError, RuntimeError):
    """The trial command failed (exit status, time-out, no or malformed output). CLI exit 1."""


def read_measured(path: str | os.PathLike, dt: float, n: int, d: int) -> np.ndarray:
    """Read a measured output file (path CSV, absolute positions) on the series' grid.

    Parameters
    ----------
    path : str or path-like
        CSV ``t,x,y`` or ``t,x,y,z``.
    dt : float
        The machine's sample time.
    n, d : int
        Samples and axes of the series.

    Returns
    -------
    array, shape (n, d)

    Raises
    ------
    InputError
        A malformed file (header, numbers, NaN, grid), other than ``d`` axes, a time step
        other than ``dt``, or other than ``n`` samples (a trial of the wrong length).
    """
    from primlib.io import read_path_csv

    t, y = read_path_csv(path)
    if y.shape[1] != d:
        raise InputError(f"{path}: expected measured positions on {d} axes, got {y.shape[1]}")
    step = (t[-1] - t[0]) / (len(t) - 1)
    if abs(step - dt) > 1e-6 * dt:
        raise InputError(f"{path}: expected samples every dt = {dt:g} s, got dt = {step:.9g} s")
    if len(t) != n:
        raise InputError(
            f"{path}: expected a trial of {n} samples (T = {(n - 1) * dt:g} s), got {len(t)} "
            f"(T = {t[-1]:.9g} s)"
        )
    return y


class CommandPlant:
    """A plant that is a program: one trial = one run of a command over two files.

    Parameters
    ----------
    command : str
        Command line with ``{input}`` and ``{output}`` (split like a shell would, no shell
        run; the file names replace the placeholders inside each word).
    dt : float
        The machine's sample time.
    origin : array, shape (d,)
        The absolute start position: subtracted from the measured positions.
    workdir : str or path-like
        Where the input and output files go.
    timeout : float, optional
        Seconds a trial may take (None: no limit).
    prefix : str
        File name prefix (the CLI uses ``series<ID>``).

    Raises
    ------
    InputError
        A command without ``{input}`` or ``{output}``, or a folder that does not exist.
    """

    def __init__(
        self,
        command: str,
        dt: float,
        origin: Any,
        workdir: str | os.PathLike = ".",
        timeout: float | None = None,
        prefix: str = "trial",
    ) -> None:
        for key in ("{input}", "{output}"):
            if key not in command:
                raise InputError(f"--trial-command: expected {key} in the command, got {command!r}")
        try:
            self._argv = shlex.split(command)
        except ValueError as exc:
            raise InputError(f"--trial-command: cannot split {command!r} ({exc})") from None
        self._workdir = Path(workdir)
        if not self._workdir.is_dir():
            raise InputError(f"--workdir {workdir}: folder does not exist")
        if timeout is not None and not timeout > 0:
            raise InputError(f"--timeout: expected seconds > 0, got {timeout}")
        self.dt = float(dt)
        self.origin = np.asarray(origin, dtype=float)
        self.timeout = timeout
        self.prefix = prefix
        self.trial = 0

    def files(self, trial: int) -> tuple[Path, Path]:
        """The input and output files of a trial."""
        stem = f"{self.prefix}-trial{trial}"
        return self._workdir / f"{stem}-input.csv", self._workdir / f"{stem}-measured.csv"

    def run(self, u: np.ndarray) -> np.ndarray:
        """Run trial ``self.trial`` on the program; the output relative to ``origin``."""
        return self.run_absolute(u) - self.origin

    def run_absolute(self, u: np.ndarray) -> np.ndarray:
        """Run one trial; the measured absolute positions, shape (n, d).

        Raises
        ------
        TrialCommandError
            Non-zero exit, time-out, the program cannot start, no output file, or a
            malformed one (the message says which and names the files).
        """
        from primlib.io import write_signal_csv

        u = np.asarray(u, dtype=float)
        n, d = u.shape
        inp, out = self.files(self.trial)
        write_signal_csv(inp, np.arange(n) * self.dt, u)
        out.unlink(missing_ok=True)
        argv = [a.replace("{input}", str(inp)).replace("{output}", str(out)) for a in self._argv]
        label = f"trial {self.trial}: the trial command"
        try:
            proc = subprocess.run(argv, capture_output=True, text=True, timeout=self.timeout)
        except subprocess.TimeoutExpired:
            raise TrialCommandError(f"{label} timed out after {self.timeout:g} s") from None
        except OSError as exc:
            raise TrialCommandError(
                f"{label} could not start ({exc.strerror}: {argv[0]})"
            ) from None
        if proc.returncode != 0:
            last = (proc.stderr or proc.stdout).strip().splitlines()
            why = f": {last[-1]}" if last else ""
            raise TrialCommandError(f"{label} exited with status {proc.returncode}{why}")
        if not out.is_file():
            raise TrialCommandError(f"{label} wrote no output file {out}")
        try:
            return read_measured(out, self.dt, n, d)
        except InputError as exc:
            raise TrialCommandError(f"{label} wrote a malformed output: {exc}") from None
