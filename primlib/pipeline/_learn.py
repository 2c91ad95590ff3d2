"""ILC from a warm start (or from zero) on a machine's model: one function for every caller.

:func:`learn_on_model` picks the law's learner — :func:`primlib.ilc.learn` for the
single-axis laws, :func:`primlib.ilc.learn_master_slave` for the master-slave PDCCILC
paper's laws on a two-axis machine — and :class:`LearnRun` is everything a caller reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from primlib._errors import InputError
from primlib.ilc import ILCResult, MasterSlaveResult, learn, learn_master_slave
from primlib.pipeline._laws import LAWS, MASTER_SLAVE_LAWS
from primlib.pipeline._warm import WarmStart
from primlib.plant import Machine

__all__ = ["LearnRun", "learn_on_model", "check_law"]


@dataclass(frozen=True, eq=False)
class LearnRun:
    """One learning run: warm start (or zero), ILC trials, and what they gave.

    Attributes
    ----------
    machine : Machine
    reference : array, shape (n, d)
        The path on the machine's grid, relative to its first point.
    t : array, shape (n,)
    warm : WarmStart or None
        The warm start the trials began from (None: from zero).
    result : ILCResult or MasterSlaveResult
        The trials; ``result.rms_total[0]`` is the warm start's (or zero's) own error.
    contour : list of float or None
        RMS contour error per trial, where computed.
    notes : tuple of str
    stored_id : int or None
        The primitive the converged input was stored as, when it was stored.
    """

    machine: Machine
    reference: np.ndarray
    t: np.ndarray
    warm: WarmStart | None
    result: ILCResult | MasterSlaveResult
    contour: list[float] | None
    notes: tuple[str, ...] = ()
    stored_id: int | None = None

    @property
    def start(self) -> str:
        """ "warm" or "cold"."""
        return "warm" if self.warm is not None else "cold"

    @property
    def u(self) -> np.ndarray:
        """The last (converged) input, shape (n, d)."""
        return np.asarray(self.result.u)


def check_law(law: str, machine: Machine, option: str = "law") -> str:
    """The law's canonical (lower-case) name; InputError for an unknown law or a
    master-slave law on a machine without exactly two axes (``option`` names the argument
    in the message)."""
    name = str(law).lower()
    if name not in LAWS:
        raise InputError(f"{option}: expected one of {', '.join(LAWS)}, got {law!r}")
    if name in MASTER_SLAVE_LAWS and machine.dim != 2:
        raise InputError(
            f"{option}: expected a two-axis machine for the master-slave law {law!r}, got "
            f"machine '{machine.name}' with {machine.dim} axes ({','.join(machine.axes)})"
        )
    return name


def learn_on_model(
    machine: Machine,
    reference: np.ndarray,
    u0: np.ndarray | None,
    *,
    law: str,
    iterations: int,
    tol: float | None,
    contour: bool,
) -> ILCResult | MasterSlaveResult:
    """ILC trials on the machine's model from ``u0`` (None: zero) with the named law.

    Parameters
    ----------
    machine : Machine
    reference : array, shape (n, d)
        Relative to the path's first point.
    u0 : array, shape (n, d) or None
    law : str
        One of :data:`LAWS` (checked by :func:`check_law`).
    iterations : int
    tol : float or None
        Stop below this RMS error (master-slave laws: RMS estimated contour error, the
        law's own measure).
    contour : bool
        Also compute the RMS contour error per trial (single-axis laws, d >= 2).
    """
    name = check_law(law, machine)
    if name in MASTER_SLAVE_LAWS:
        return learn_master_slave(machine, reference, u0, law=name, iterations=iterations, tol=tol)
    # the convergence check is iterative beyond 400 samples (Lanczos on FFT operators):
    # no dense n x n SVD, long paths (n = 5000) check in about a second
    return learn(
        machine,
        reference,
        u0,
        law=name,
        iterations=iterations,
        tol=tol,
        contour=contour and machine.dim >= 2,
    )
