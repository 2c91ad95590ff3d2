"""A realistic machine: the per-axis linear model plus friction, ripple, noise, disturbance.

Per axis, in the machine's input units (``G = num / den`` the axis's own plant, ``x_abs``
the absolute motor position ``start + y_m``, ``v`` its velocity)::

    y_m = G(s) [u + PID + d_j(t) - f(v) - c_r sin(2 pi x_abs / p + phi)]
    f(v) = c_c [1 + (r_s - 1) exp(-(v / v_s)^2)] sgn(v) + c_v v     (Stribeck, Coulomb, viscous)
    y   = R(s) y_m,   R(s) = w^2 / (s^2 + 2 zeta w s + w^2)           (optional resonance)
    measured = y + n_j(t)

``d_j`` is trial j's input disturbance (Gaussian, first-order low-pass: stationary std
``disturbance``, corner ``disturbance_bandwidth``), ``n_j`` white measurement noise of std
``noise``; both are drawn from ``numpy.random.default_rng((seed, j, stream))``, so a trial is
reproducible and each trial differs. A PID, where there is one, acts on the measured
output (noise included); the noise-free motion ``y`` is what :meth:`simulate` returns unless
asked for the measurement. For a plant whose high-frequency gain is negative, ``f`` is
applied with that sign, so that friction always opposes the motion.

Where the resonance sits: between the driven carriage (where friction and cogging act and
whose velocity they see) and the measured point, as a compliant coupling of unit static
gain. So the friction acts on a rigid force-to-position part of relative degree >= 2, where
the stick/slip step below is well defined, the mode is excited by every input (and by the
friction's stick/slip, as a structural mode is), and static positioning is unchanged.

Velocity and integration. Each loop axis is a continuous state space ``x' = A x + B w``
(``scipy.signal.tf2ss`` of ``G``, then the resonance in series), ``y_m = C x``. With relative
degree >= 2, ``C B = 0`` and the motor velocity is exactly ``v = C A x``. Viscous friction is
linear velocity feedback, folded into ``A`` (``A - c_v B C A``), hence integrated exactly.
A sample is cut into ``substeps``; in each, the force ``w`` (input, disturbance, ripple
where the carriage is half-way through the substep) is held and the state advanced by the
exact zero-order hold
``x+ = A_d x + B_d w`` (``scipy.linalg.expm``), so with Coulomb friction and ripple off the
loop is the ZOH model up to rounding. Coulomb friction is a set-valued force in a
Moreau-type time-stepping (as :mod:`primlib.plant._linear_motor`): with ``v_free`` the
end-of-substep velocity without it, at rest or where the substep would reverse the motion
the axis sticks (``v = 0``) if friction up to its static level ``r_s c_c`` absorbs the whole
free motion, else it slides on; no chattering at ``v = 0`` and no stiff solver.

Axes whose Coulomb friction and ripple are off are linear: they run, vectorised, through the
linear :class:`~primlib.plant.Machine` ``G R / (1 + c_v s G)`` (:meth:`linear_part`), which
with every departure off is the nominal machine itself, so the output is exactly
:class:`Machine`'s. The others run a per-sample loop on plain floats.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from scipy import signal

from primlib._errors import InputError
from primlib.plant._departures import (
    check_count,
    scale_departures,
    validate_departures,
)
from primlib.plant._machine import Machine, register_kind
from primlib.plant._realistic_loop import linear_plant, loop_kernel, run_axis
from primlib.plant._spec import check_kind, check_start, read_note

__all__ = ["RealisticMachine", "TrialRunner"]

_TOP_KEYS = {
    "name",
    "kind",
    "dt",
    "axes",
    "plants",
    "feedback",
    "note",
    "departures",
    "seed",
    "substeps",
}
_DISTURBANCE, _NOISE = 1, 2  # random streams of a trial


class RealisticMachine(Machine):
    """A Machine with friction, force ripple, noise, a disturbance and a resonance.

    Parameters
    ----------
    name, dt, axes, plants, feedback
        As :class:`Machine`: the nominal linear model (``plants`` in input units to the
        user's length unit), optionally in its PID loops.
    departures : dict, optional
        Per axis (all or some) the departures of
        :data:`primlib.plant.DEPARTURE_KEYS` (module docstring of
        :mod:`primlib.plant._realistic` for the model): ``coulomb``, ``static_ratio`` (1),
        ``stribeck_velocity`` (1), ``viscous``, ``ripple``, ``ripple_pitch`` (5),
        ``ripple_phase`` (0 rad), ``disturbance``, ``disturbance_bandwidth`` (2 Hz),
        ``noise``, ``resonance_hz`` (0: none), ``resonance_damping`` (0.05). Missing keys
        and axes are off.
    seed : int
        Seed of the random parts (disturbance and noise of each trial), >= 0.
    substeps : int
        Integration sub-steps per sample where friction or ripple is on (>= 1).

    Notes
    -----
    ``discrete``, ``impulse_response``, ``lifted`` and ``closed_loop`` describe the
    nominal linear model (what a learning law is designed on); ``simulate`` runs the
    realistic one. With every departure off it is exactly its nominal Machine.

    Examples
    --------
    >>> from primlib.plant import RealisticMachine
    >>> rm = Machine.from_json("data/machines/realistic-xyz.json")  # "kind": "realistic"
    >>> u = np.zeros((400, 3))
    >>> true = rm.simulate(u, start=[10.0, 0.0, 0.0], trial=1)  # the noise-free motion
    >>> measured = rm.simulate(u, start=[10.0, 0.0, 0.0], trial=1, noise=True)
    >>> bool(abs(np.std(measured - true) - 0.001) < 1e-4)  # 1 um measurement noise
    True
    """

    kind: ClassVar[str] = "realistic"

    def __init__(
        self,
        name: str,
        dt: float,
        axes,
        plants: Mapping[str, Any],
        feedback: Mapping[str, Any] | None = None,
        departures: Mapping[str, Any] | None = None,
        *,
        seed: int = 0,
        substeps: int = 4,
    ) -> None:
        super().__init__(name, dt, axes, plants, feedback)
        self._departures = validate_departures(departures, self.axes)
        self._seed = check_count(seed, "seed", 0)
        self._substeps = check_count(substeps, "substeps", 1)
        deps = [self._departures[a] for a in self.axes]
        self._linear = Machine(
            name,
            self.dt,
            self.axes,
            {a: linear_plant(*self._plants[a], self._departures[a]) for a in self.axes},
            self.feedback,
        )
        self._kernels = [
            loop_kernel(a, *self._plants[a], dep, self.dt, self._substeps)
            if dep["coulomb"] > 0 or dep["ripple"] > 0
            else None
            for a, dep in zip(self.axes, deps, strict=True)
        ]
        self._sigma_d = np.array([dep["disturbance"] for dep in deps])
        self._pole_d = np.exp(
            -2 * np.pi * self.dt * np.array([dep["disturbance_bandwidth"] for dep in deps])
        )
        self._sigma_n = np.array([dep["noise"] for dep in deps])

    # ------------------------------------------------------------------ properties
    @property
    def departures(self) -> dict[str, dict[str, float]]:
        """Per-axis departure parameters, complete (copies)."""
        return {a: dict(p) for a, p in self._departures.items()}

    @property
    def seed(self) -> int:
        return self._seed

    @property
    def substeps(self) -> int:
        return self._substeps

    def nominal(self) -> Machine:
        """The nominal linear Machine (the plants and feedback, no departure)."""
        return Machine(self.name, self.dt, self.axes, self.plants, self.feedback)

    def linear_part(self) -> Machine:
        """The linear Machine with the linear departures (viscous friction, resonance)."""
        return Machine(self.name, self.dt, self.axes, self._linear.plants, self.feedback)

    # ------------------------------------------------------------------ random parts
    def disturbance(self, n: int, trial: int = 0) -> np.ndarray:
        """Trial ``trial``'s input disturbance, shape (n, d), input units (zeros where off).

        First-order low-pass filtered Gaussian noise, stationary from the first sample:
        ``d[k] = a d[k-1] + sqrt(1 - a^2) sigma e[k]``, ``a = exp(-2 pi f_b dt)``.
        """
        n, trial = check_count(n, "n", 0), check_count(trial, "trial", 0)
        if not np.any(self._sigma_d):
            return np.zeros((n, self.dim))
        e = np.random.default_rng((self._seed, trial, _DISTURBANCE)).standard_normal(
            (n + 1, self.dim)
        )
        out = np.empty((n, self.dim))
        for i, (a, sigma) in enumerate(zip(self._pole_d, self._sigma_d, strict=True)):
            zi = [a * sigma * e[0, i]]
            out[:, i] = signal.lfilter([math.sqrt(1 - a * a) * sigma], [1.0, -a], e[1:, i], zi=zi)[
                0
            ]
        return out

    def measurement_noise(self, n: int, trial: int = 0) -> np.ndarray:
        """Trial ``trial``'s measurement noise, shape (n, d), length units (zeros where off)."""
        n, trial = check_count(n, "n", 0), check_count(trial, "trial", 0)
        if not np.any(self._sigma_n):
            return np.zeros((n, self.dim))
        rng = np.random.default_rng((self._seed, trial, _NOISE))
        return rng.standard_normal((n, self.dim)) * self._sigma_n

    # ------------------------------------------------------------------ simulation
    def _check_start(self, start) -> np.ndarray:
        return check_start(start, self.dim)

    def simulate(
        self,
        u: Any,
        reference: Any = None,
        start: Any = None,
        *,
        trial: int = 0,
        noise: bool = False,
    ) -> np.ndarray:
        """Output of the realistic machine for input ``u``, from rest at ``start``.

        Parameters
        ----------
        u : array, shape (n, d)
            Input per axis (feedforward added to the PID output where there is feedback).
        reference : array, shape (n, d), optional
            Reference of the PID loops (relative to the start), None = zeros.
        start : array, shape (d,), optional
            Absolute start position, user units (the ripple's phase); default 0.
        trial : int
            Trial number (>= 0): selects the disturbance and noise realisation.
        noise : bool
            False (default): the true, noise-free motion; True: the measurement.

        Returns
        -------
        y : array, shape (n, d)
            Position relative to the start, user units; ``y[k]`` responds to ``u[: k]``.
        """
        u = self.check_signal(u, "u")
        r = None
        if reference is not None:
            r = self.check_signal(reference, "reference")
            if r.shape != u.shape:
                raise InputError(f"reference: expected the shape of u {u.shape}, got {r.shape}")
        s = self._check_start(start)
        n = u.shape[0]
        nz = self.measurement_noise(n, trial)
        if np.any(self._sigma_d):
            u = u + self.disturbance(n, trial)
        y = self._motion(u, r, s, nz)
        return y + nz if noise else y

    def _motion(self, u: np.ndarray, r, start: np.ndarray, nz: np.ndarray, loop=None):
        """Noise-free motion for the total input ``u`` (disturbance included); ``loop``
        (tests only) forces the per-sample loop on those axes."""
        fb = self.feedback or {}
        r_pid = r
        if fb and np.any(nz):
            r_pid = (np.zeros_like(u) if r is None else r) - nz
        y = self._linear.simulate(u, r_pid)
        for i, a in enumerate(self.axes):
            kern = self._kernels[i]
            if kern is None and loop is not None and i in loop:
                kern = loop_kernel(
                    a, *self._plants[a], self._departures[a], self.dt, self._substeps
                )
            if kern is None:
                continue
            pid = None
            if a in fb:
                g = fb[a]
                pid = (g["kp"], g["ki"], g["kd"], g["tf"], self.dt)
            r_i = np.zeros(len(u)) if r is None else r[:, i]
            y[:, i] = run_axis(
                kern, u[:, i].tolist(), r_i.tolist(), nz[:, i].tolist(), float(start[i]), pid
            )
        return y

    def _loop_kernel(self, axis: str) -> tuple:
        if axis not in self.axes:
            raise InputError(f"axis: expected one of {list(self.axes)}, got {axis!r}")
        i = self.axes.index(axis)
        kern = self._kernels[i]
        if kern is None:  # a linear axis: the loop runs it all the same (to rounding)
            kern = loop_kernel(
                axis, *self._plants[axis], self._departures[axis], self.dt, self._substeps
            )
        return kern

    def run_recorded(self, axis: str, u: Any, start: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """One axis's noise-free output for its input ``u`` (shape (n,), open loop, no
        disturbance) from rest at the absolute position ``start``, and what it ran on.

        Returns
        -------
        y : array, shape (n,)
            As :meth:`simulate` gives it on that axis.
        record : array, shape (n * substeps, 3)
            Per substep: the force friction and ripple took off the input (input units),
            the sign by which the friction force grows with its Coulomb level (0 while
            stuck), the velocity the substep started from. Frozen, they linearise the run
            about its switching: on a rigid axis (no resonance) :meth:`substep_response` of
            ``np.repeat(u, substeps) - record[:, 0]`` is ``y`` to rounding (what
            :func:`primlib.greybox.refit_greybox` differentiates).
        """
        kern = self._loop_kernel(axis)
        u = np.asarray(u, dtype=float)
        if u.ndim != 1 or not np.all(np.isfinite(u)):
            raise InputError(f"u: expected a finite 1-D input, got shape {u.shape}")
        rec: list = []
        zero = [0.0] * len(u)
        y = run_axis(kern, u.tolist(), zero, zero, float(start), None, rec)
        return np.asarray(y), np.asarray(rec, dtype=float).reshape(-1, 3)

    def substep_response(self, axis: str, w: Any) -> np.ndarray:
        """The axis's linear part (viscous friction folded in) driven by the force ``w`` held
        over each substep (shape (n * substeps,)), from rest: its output at the n samples."""
        kern = self._loop_kernel(axis)
        Ad, Bd, Cy = np.asarray(kern[0]), np.asarray(kern[1]), np.asarray(kern[5])
        b, a = signal.ss2tf(Ad, Bd[:, None], Cy[None, :], np.zeros((1, 1)))
        # output index j is the state after j substeps: sample k is index k * substeps
        return signal.lfilter(b[0], a, np.asarray(w, dtype=float))[:: self._substeps]

    def reference_response(self, reference: Any) -> np.ndarray:
        """Noise-free output in the PID loops for u = 0 (trial 0, start 0), shape (n, d)."""
        r = self.check_signal(reference, "reference")
        return self.simulate(np.zeros_like(r), r)

    def impulse_response(self, n: int) -> np.ndarray:
        """Markov parameters of the nominal linear model (closed loop where there is
        feedback): what learning laws design on."""
        return self.nominal().impulse_response(n)

    def trials(self, start: Any = None, *, noise: bool = True, first: int = 0) -> TrialRunner:
        """A runner of successive trials from ``start`` (see :class:`TrialRunner`)."""
        return TrialRunner(self, start, noise=noise, first=first)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_machine(
        cls,
        machine: Machine,
        *,
        typical_input: Any = None,
        typical_velocity: Any = None,
        seed: int = 0,
        substeps: int = 4,
        name: str | None = None,
        **departures: Any,
    ) -> RealisticMachine:
        """A realistic machine on a nominal Machine's plants and feedback.

        Parameters
        ----------
        machine : Machine
            The nominal linear machine (its ``nominal()`` if it has one).
        typical_input, typical_velocity : float or array, shape (d,), optional
            When ``typical_input`` is given, ``coulomb``, ``ripple``, ``disturbance`` and
            ``viscous`` are fractions "of the typical input"
            (:func:`primlib.plant.typical_scales` measures both scales; the convention is
            in :func:`primlib.plant.scale_departures`).
        seed, substeps : int
        name : str, optional
            Default: the machine's name.
        **departures
            Departure keys, each a number (every axis) or one per axis.

        Examples
        --------
        >>> from primlib.plant import RealisticMachine
        >>> rm = RealisticMachine.from_machine(m, coulomb=0.02, typical_input=[5.0, 4.0, 2.0])
        >>> rm.departures["y"]["coulomb"]
        0.08
        """
        if hasattr(machine, "nominal"):
            machine = machine.nominal()
        deps = scale_departures(machine.axes, departures, typical_input, typical_velocity)
        return cls(
            machine.name if name is None else name,
            machine.dt,
            machine.axes,
            machine.plants,
            machine.feedback,
            deps,
            seed=seed,
            substeps=substeps,
        )

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> RealisticMachine:
        """Build from the JSON dictionary (``"kind": "realistic"``; docs/files.rst).

        Raises
        ------
        InputError
            Unknown or missing keys, or any invalid field.
        """
        check_kind(d, cls.kind, _TOP_KEYS, ("name", "dt", "axes", "plants"))
        axes = d["axes"]
        if not isinstance(axes, (list, tuple)):
            raise InputError(f"axes: expected a list of axis names, got {axes!r}")
        m = cls(
            d["name"],
            d["dt"],
            axes,
            d["plants"],
            d.get("feedback"),
            d.get("departures"),
            seed=d.get("seed", 0),
            substeps=d.get("substeps", 4),
        )
        return read_note(m, d)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary; ``RealisticMachine.from_dict(m.to_dict()) == m``."""
        out = super().to_dict()
        out.update(seed=self._seed, substeps=self._substeps, departures=self.departures)
        return out

    def __repr__(self) -> str:
        fb = "PID" if self.feedback else "open loop"
        return f"RealisticMachine({self.name!r}, dt={self.dt}, axes={list(self.axes)}, {fb})"


class TrialRunner:
    """Successive trials of a :class:`RealisticMachine` from one start position.

    Each call of :meth:`simulate` (or :meth:`run`) is the next trial (new disturbance and
    noise) and returns the measurement (``noise=True``) or the true motion; the true motion
    of every trial is kept in :attr:`true`. It has the attributes ``primlib.ilc.learn``
    reads from a plant (``dt``, ``axes``, ``dim``, ``feedback``, ``check_signal``), so a
    series of trials learns on the machine as on a real one.

    Parameters
    ----------
    machine : RealisticMachine
    start : array, shape (d,), optional
        Absolute start position (user units).
    noise : bool
        Return measurements (default) or the true motion.
    first : int
        Number of the first trial.
    """

    def __init__(
        self, machine: RealisticMachine, start=None, *, noise: bool = True, first: int = 0
    ):
        self.machine = machine
        self.start = machine._check_start(start)
        self.noise = bool(noise)
        self.trial = check_count(first, "first", 0)
        self.true: list[np.ndarray] = []

    dt = property(lambda self: self.machine.dt)
    axes = property(lambda self: self.machine.axes)
    dim = property(lambda self: self.machine.dim)
    feedback = property(lambda self: self.machine.feedback)

    def check_signal(self, x: Any, what: str) -> np.ndarray:
        return self.machine.check_signal(x, what)

    def simulate(self, u: Any, reference: Any = None) -> np.ndarray:
        """Run the next trial; returns the measured (or true) output, shape (n, d)."""
        m = self.machine
        y = m.simulate(u, reference, self.start, trial=self.trial)
        self.true.append(y)
        nz = m.measurement_noise(len(y), self.trial) if self.noise else 0.0
        self.trial += 1
        return y + nz

    def run(self, u: Any) -> np.ndarray:
        """The next trial for input ``u`` (a :class:`primlib.trials.Plant`)."""
        return self.simulate(u)


register_kind("realistic", RealisticMachine)
