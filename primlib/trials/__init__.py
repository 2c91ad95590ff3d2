"""Learning on a real stage: trial series kept in the library, trial by trial.

A series learns one path's input over trials that run on hardware (or on anything with
``run(u) -> y``): :func:`start` writes the first input (the library's warm start, else the
model inverse) and records the series; :func:`step` records a measured output and writes
the next input (:class:`primlib.ilc.TrialLearner`: averaging, a Q-filter band and a noise
floor estimated from the trials); :func:`status` and :func:`finish` report and store the
converged pair as a primitive. :func:`run_command` drives an external program per trial,
:func:`run_trials` a Python :class:`Plant`. Each step is one transaction of the library, so
a series survives a crash between any two steps and resumes in another process.
"""

from primlib.trials._plant import CommandPlant, Plant, TrialCommandError, read_measured
from primlib.trials._run import RunResult, TrialSeries, run_command, run_trials
from primlib.trials._series import (
    SeriesStatus,
    StartResult,
    StepResult,
    finish,
    first_input,
    learner,
    pending,
    start,
    status,
    step,
)

__all__ = [
    "Plant",
    "CommandPlant",
    "TrialCommandError",
    "read_measured",
    "TrialSeries",
    "RunResult",
    "run_trials",
    "run_command",
    "start",
    "step",
    "status",
    "finish",
    "first_input",
    "pending",
    "learner",
    "StartResult",
    "StepResult",
    "SeriesStatus",
]
