"""Learning laws as small frozen objects: what to learn with, separate from how long.

A law object carries its gains (None: designed from the model, see
:mod:`primlib.ilc._design`) and its Q-filter; :func:`primlib.ilc.learn` takes one (or its
name) and runs it. The Arimoto laws and the norm-optimal law are defined in
:mod:`primlib.ilc._learn`, the master–slave laws in :mod:`primlib.ilc._ms_law`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any, ClassVar

from primlib._errors import InputError
from primlib.ilc._ms_law import LAWS as MASTER_SLAVE_LAWS
from primlib.ilc._ms_law import MasterSlaveGains

__all__ = [
    "LAW_NAMES",
    "SOLVERS",
    "LearnOptions",
    "MasterSlave",
    "NormOptimal",
    "PDLaw",
    "PIDLaw",
    "PLaw",
    "law_from_name",
]

SOLVERS = ("auto", "dense", "cg")


@dataclass(frozen=True, kw_only=True)
class _Law:
    """Common part of the single-axis laws: u_{j+1} = Q(u_j + step(e_j))."""

    q_cutoff: float | None = None
    q_order: int = 2

    name: ClassVar[str] = ""
    keys: ClassVar[tuple[str, ...]] = ()

    def gains(self) -> dict[str, Any] | None:
        """The gains given (missing ones 0), or None when none is: design them."""
        given = {k: getattr(self, k) for k in self.keys if getattr(self, k) is not None}
        return given or None


@dataclass(frozen=True)
class PLaw(_Law):
    """Arimoto P-type law, ``L = kp`` (scalar or one per axis; None: designed).

    Parameters
    ----------
    kp : float or array of shape (d,), optional
    q_cutoff : float, optional
        Cut-off in Hz of the zero-phase Butterworth Q-filter; None: no Q-filter.
    q_order : int
        Butterworth order of one pass of the Q-filter.
    """

    kp: Any = None
    name: ClassVar[str] = "p"
    keys: ClassVar[tuple[str, ...]] = ("kp",)


@dataclass(frozen=True)
class PDLaw(_Law):
    """Arimoto PD-type law, ``L = kp + kd (1 - q^-1) / dt`` (gains None: designed; a gain
    left None beside a given one is 0). Q-filter as for :class:`PLaw`."""

    kp: Any = None
    kd: Any = None
    name: ClassVar[str] = "pd"
    keys: ClassVar[tuple[str, ...]] = ("kp", "kd")


@dataclass(frozen=True)
class PIDLaw(_Law):
    """Arimoto PID-type law, ``L = kp + kd (1 - q^-1) / dt + ki dt / (1 - q^-1)`` (gains
    None: designed; a gain left None beside a given one is 0). Q-filter as for
    :class:`PLaw`."""

    kp: Any = None
    ki: Any = None
    kd: Any = None
    name: ClassVar[str] = "pid"
    keys: ClassVar[tuple[str, ...]] = ("kp", "ki", "kd")


@dataclass(frozen=True)
class NormOptimal(_Law):
    """Lifted norm-optimal law, ``u + (G^T G + w I)^-1 G^T e`` (w None: designed).

    Parameters
    ----------
    w : float or array of shape (d,), optional
        Input-change weight (> 0).
    solver : {"auto", "dense", "cg"}
        "dense" Cholesky (n - r <= 5,000), "cg" conjugate gradients on FFT operators (any
        length), "auto" dense up to n - r = 1,000. Both give the same inputs to the CG
        tolerance.
    q_cutoff, q_order
        As for :class:`PLaw`.
    """

    w: Any = None
    solver: str = "auto"
    name: ClassVar[str] = "norm-optimal"
    keys: ClassVar[tuple[str, ...]] = ("w",)

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise InputError(f"solver: expected one of {', '.join(SOLVERS)}, got {self.solver!r}")


@dataclass(frozen=True)
class MasterSlave:
    """A master–slave law of the PDCCILC paper for a two-axis machine.

    Parameters
    ----------
    law : {"tdilc", "tdccilc", "pdilc", "pdccilc"}
        Time- or position-domain learning, without or with cross-coupling.
    gains : MasterSlaveGains, optional
        Default: Table 1 of the paper.
    q_cutoff : float or None
        -3 dB frequency (Hz) of the zero-phase Gaussian Q-filter (default 1 Hz); None: none.
    master : {0, 1}
        Master axis.
    lead : int
        Samples between an input and the error it learns from (paper: 1).
    floor : float
        Position-domain regularisation (fraction of the mean master step).

    See :func:`primlib.ilc.master_slave_law` for the equations.
    """

    law: str = "pdccilc"
    gains: MasterSlaveGains | None = None
    q_cutoff: float | None = 1.0
    master: int = 0
    lead: int = 1
    floor: float = 0.25

    @property
    def name(self) -> str:
        return str(self.law).lower()

    def options(self) -> dict[str, Any]:
        """The keyword arguments of :func:`primlib.ilc.master_slave_law`."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class LearnOptions:
    """The rarely changed settings of :func:`primlib.ilc.learn`.

    Parameters
    ----------
    dense_limit : int
        Largest n - r the convergence check handles with dense matrices; beyond, FFT
        operators and Lanczos.
    callback : callable, optional
        Called after every trial as ``callback(trial, rms)`` with the trial number (0 for
        ``u0``) and the per-axis RMS error, shape (d,) (e.g. to print progress).
    check : bool
        Master–slave laws: run the lifted check first (the single-axis laws always check,
        their result carries it).
    """

    dense_limit: int = 400
    callback: Callable[[int, Any], None] | None = None
    check: bool = True


_BY_NAME: dict[str, type] = {cls.name: cls for cls in (PLaw, PDLaw, PIDLaw, NormOptimal)}
LAW_NAMES = tuple(_BY_NAME) + MASTER_SLAVE_LAWS


def law_from_name(law: Any) -> _Law | MasterSlave:
    """The law object for a name (case-insensitive) with designed gains, or ``law`` itself
    when it already is a law object.

    Raises
    ------
    InputError
        For anything else, naming the known laws.
    """
    if isinstance(law, (_Law, MasterSlave)):
        if isinstance(law, MasterSlave) and law.name not in MASTER_SLAVE_LAWS:
            raise InputError(
                f"law: expected one of {', '.join(MASTER_SLAVE_LAWS)}, got {law.law!r}"
            )
        return law
    name = law.lower() if isinstance(law, str) else None
    if name in _BY_NAME:
        return _BY_NAME[name]()
    if name in MASTER_SLAVE_LAWS:
        return MasterSlave(name)
    raise InputError(f"law: expected one of {', '.join(LAW_NAMES)}, got {law!r}")
