"""``identify``: per-axis continuous models from one experiment, as a Machine.

Each axis is fitted on its own (no coupling between axes) by output-error least squares
(:mod:`primlib.identify._fit`) on the first part of the record; the last ``holdout``
fraction is never fitted and measures the model: its normalised RMS error
rms(y - y_hat) / std(y) on those samples. With ``structure="auto"`` every structure is
fitted and the simplest one whose held-out error is within ``AUTO_REL`` (relative) plus
``AUTO_ABS`` (absolute) of the best is kept: a structure with more coefficients must earn
them on data it has not seen.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from primlib._errors import InputError
from primlib.identify._fit import AxisFit, AxisRecord, fit_axis
from primlib.identify._structures import STRUCTURES
from primlib.identify._structures import structure as _get_structure
from primlib.plant import Machine

__all__ = ["identify", "Identified", "HOLDOUT", "AUTO_REL", "AUTO_ABS"]

HOLDOUT = 0.3
"""Default fraction of the record (its end) held out of the fit to measure the model."""
AUTO_REL = 0.1
AUTO_ABS = 2e-3
"""``auto`` keeps the simplest structure with held-out error <= (1 + AUTO_REL) best +
AUTO_ABS: a tenth more than the best, or 0.2 % of the output's spread."""
MIN_SAMPLES = 20  # in each of the estimation and the held-out part
_AXIS_NAMES = ("x", "y", "z")
_PID_KEYS = ("kp", "ki", "kd", "tf")


@dataclass(frozen=True)
class Identified:
    """Models identified from one experiment.

    Attributes
    ----------
    machine : Machine
        The identified machine (per-axis plant, the given PID as its feedback, sample time
        ``machine_dt``), with the fit quality in its note.
    fits : tuple of AxisFit
        Per axis, the kept fit: coefficients, their standard uncertainty, held-out error.
    candidates : tuple of dict
        Per axis, structure name -> its held-out normalised RMS error (every structure
        tried; one entry unless ``structure="auto"``).
    u, y : array, shape (n, d)
        The record (y relative to its first sample).
    dt : float
        The record's sample time.
    n_est : int
        Samples fitted; ``y[n_est:]`` is held out.
    """

    machine: Machine
    fits: tuple
    candidates: tuple
    u: np.ndarray
    y: np.ndarray
    dt: float
    n_est: int

    @property
    def nrmse(self) -> np.ndarray:
        """Held-out normalised RMS error per axis, shape (d,)."""
        return np.array([f.nrmse for f in self.fits])

    @property
    def uncertainty(self) -> dict[str, dict[str, np.ndarray]]:
        """Per axis ``{"num": std, "den": std}``: the standard uncertainty of each
        continuous coefficient (descending powers of s; 0 for the fixed ones)."""
        return {
            a: {"num": f.num_std.copy(), "den": f.den_std.copy()}
            for a, f in zip(self.machine.axes, self.fits, strict=True)
        }

    @property
    def y_model(self) -> np.ndarray:
        """The model's output over the whole record, shape (n, d)."""
        return np.stack([f.y_model for f in self.fits], axis=1)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fit quality: the machine's name and dt, the record's dt and sample
        counts, and per axis the structure, held-out and estimation NRMSE, the coefficients
        with their standard uncertainty, the offset, and every structure's held-out NRMSE."""
        axes = {}
        for a, f, c in zip(self.machine.axes, self.fits, self.candidates, strict=True):
            axes[a] = {
                "structure": f.structure,
                "nrmse": f.nrmse,
                "nrmse_fit": f.nrmse_fit,
                "num": f.num.tolist(),
                "num_std": f.num_std.tolist(),
                "den": f.den.tolist(),
                "den_std": f.den_std.tolist(),
                "offset": f.offset,
                "offset_std": f.offset_std,
                "candidates": dict(c),
            }
        return {
            "machine": self.machine.name,
            "dt": self.machine.dt,
            "record_dt": self.dt,
            "samples": len(self.y),
            "held_out": len(self.y) - self.n_est,
            "axes": axes,
        }

    def plot(self, ax=None):
        """Measured vs model output per axis, the held-out part marked; see
        :func:`primlib.plot.plot_identified`.

        Parameters
        ----------
        ax : array of matplotlib Axes, shape (d,), optional
            Drawn into; None: a new figure.

        Returns
        -------
        array of matplotlib Axes
        """
        from primlib.plot import plot_identified

        return plot_identified(self, ax=ax)


def _as_record(x: Any, what: str) -> np.ndarray:
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected an array of numbers, got {type(x).__name__}") from None
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] < 1:
        raise InputError(f"{what}: expected an array of shape (n, d), got shape {np.shape(x)}")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        k, i = bad[0]
        raise InputError(f"{what}: expected finite values, got {arr[k, i]} at sample {k}, axis {i}")
    return arr


def _check_number(value: Any, what: str, low: float, high: float | None = None) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what}: expected a number, got {value!r}") from None
    if not math.isfinite(v) or v <= low or (high is not None and v >= high):
        span = f"> {low:g}" if high is None else f"in ({low:g}, {high:g})"
        raise InputError(f"{what}: expected a finite number {span}, got {value!r}")
    return v


def _gains(axis: str, spec: Any) -> dict[str, float]:
    if not isinstance(spec, Mapping) or not set(spec) <= set(_PID_KEYS):
        raise InputError(
            f"pid of axis {axis!r}: expected gains among {', '.join(_PID_KEYS)}, got {spec!r}"
        )
    out = {}
    for key in _PID_KEYS:
        value = spec.get(key, 0.0)
        try:
            out[key] = float(value)
        except (TypeError, ValueError):
            raise InputError(
                f"pid {key} of axis {axis!r}: expected a number, got {value!r}"
            ) from None
        if not math.isfinite(out[key]) or (key == "tf" and out[key] < 0):
            raise InputError(
                f"pid {key} of axis {axis!r}: expected a finite number"
                f"{' >= 0' if key == 'tf' else ''}, got {value!r}"
            )
    return out


def _pid_per_axis(pid: Any, axes: Sequence[str]) -> dict[str, dict] | None:
    """None, one gain dict for every axis, or a mapping axis -> gains."""
    if pid is None:
        return None
    if not isinstance(pid, Mapping):
        raise InputError(f"pid: expected PID gains {{'kp', 'ki', 'kd', 'tf'}}, got {pid!r}")
    if set(pid) <= set(_PID_KEYS):
        pid = {a: pid for a in axes}
    unknown = [a for a in pid if a not in axes]
    if unknown:
        raise InputError(f"pid: got gains for unknown axis {unknown[0]!r} (axes are {list(axes)})")
    return {a: _gains(a, pid[a]) for a in axes if a in pid}


def _choose(fits: dict[str, AxisFit]) -> AxisFit:
    best = min(f.nrmse for f in fits.values())
    for name in STRUCTURES:  # simplest first
        if name in fits and fits[name].nrmse <= (1 + AUTO_REL) * best + AUTO_ABS:
            return fits[name]
    raise AssertionError("the best structure always qualifies")  # pragma: no cover


def _fmt(value: float, std: float) -> str:
    return f"{value:.6g} +- {std:.2g}"


def _note(fits: Sequence[AxisFit], axes: Sequence[str], dt: float, n: int, n_est: int) -> str:
    parts = [
        f"Identified by primlib (output-error least squares on a ZOH simulation at the "
        f"record's dt {dt:g} s; {n} samples, the last {n - n_est} held out). Per axis: "
        "structure, held-out normalised RMS error, continuous coefficients +- standard "
        "uncertainty (descending powers of s)."
    ]
    for a, f in zip(axes, fits, strict=True):
        num = ", ".join(_fmt(v, s) for v, s in zip(f.num, f.num_std, strict=True))
        den = ", ".join(_fmt(v, s) for v, s in zip(f.den, f.den_std, strict=True))
        parts.append(
            f"{a}: {f.structure}, held-out NRMSE {100 * f.nrmse:.3g} %, num [{num}], den [{den}]."
        )
    return " ".join(parts)


def identify(
    u: Any,
    y: Any,
    dt: float,
    *,
    structure: str = "auto",
    pid: Mapping[str, Any] | None = None,
    reference: Any = None,
    holdout: float = HOLDOUT,
    axes: Sequence[str] | None = None,
    name: str = "identified",
    machine_dt: float | None = None,
) -> Identified:
    r"""Identify a machine (one continuous LTI model per axis) from one experiment.

    Per axis, the coefficients theta and an output offset c (the first sample's error)
    minimise the output error on the first ``1 - holdout`` of the record,

    .. math:: V(\theta, c) = \sum_{k < n_e} (y_k - \hat y_k(\theta) - c)^2,

    :math:`\hat y(\theta)` the candidate's ZOH simulation from rest by
    :class:`primlib.plant.Machine` (in the PID loop when ``pid`` is given); solved by
    ``scipy.optimize.least_squares`` (trust-region reflective, poles in the closed left
    half plane) from an equation-error (ARX) start.

    Parameters
    ----------
    u : array, shape (n, d)
        Input per axis (with ``pid``: the feedforward added to the PID output).
    y : array, shape (n, d)
        Measured position per axis relative to the start (the stage at rest at y = 0).
    dt : float
        Sample time of the record, s.
    structure : {"auto", "integrator", "first-order", "second-order"}
        See :data:`STRUCTURES`; "auto": per axis the simplest within a margin of the best
        held-out error.
    pid : dict, optional
        The PID the record ran in, ``{"kp", "ki", "kd", "tf"}`` for every axis or a mapping
        axis -> gains; the plant inside is identified, the machine gets this feedback.
    reference : array, shape (n, d), optional
        The PID loops' reference relative to the start (None: zero).
    holdout : float
        Fraction of the record (its end) held out of the fit, in (0, 1).
    axes : sequence of str, optional
        Axis names (default x, y, z).
    name : str
        The machine's name.
    machine_dt : float, optional
        The machine's sample time (default ``dt``; the model is continuous).

    Returns
    -------
    Identified

    Raises
    ------
    InputError
        Shapes that differ, NaN or inf, a short record, an input that is zero throughout,
        an output that does not move in the held-out part, a bad option.

    Examples
    --------
    >>> from primlib.identify import excite
    >>> from primlib.plant import Machine
    >>> true = Machine("m", 0.01, ("x",), {"x": ([2.0], [0.5, 1.0, 0.0])})
    >>> u = excite(8.0, 1.0, 1, 0.01)
    >>> res = identify(u, true.simulate(u), 0.01, structure="second-order", axes=("x",))
    >>> bool(np.allclose(res.machine.plants["x"][1], [1.0, 2.0, 0.0], atol=1e-6))
    True
    """
    u, y, ref, dt, n_est, axes, pids = _check_inputs(u, y, dt, pid, reference, holdout, axes)
    machine_dt = dt if machine_dt is None else _check_number(machine_dt, "machine_dt", 0.0)
    names = list(STRUCTURES) if structure == "auto" else [_structure_name(structure)]
    fits, candidates = _fit_axes(u, y, ref, dt, n_est, axes, pids, names)
    note = _note(fits, axes, dt, len(u), n_est)
    machine = _machine(name, machine_dt, axes, fits, pids, note)
    return Identified(machine, tuple(fits), tuple(candidates), u, y, dt, n_est)


def _fit_axes(u, y, ref, dt, n_est, axes, pids, names) -> tuple[list, list]:
    """Per axis, the kept fit and every tried structure's held-out error."""
    fits, candidates = [], []
    for i, a in enumerate(axes):
        rec = AxisRecord(
            u[:, i], y[:, i], dt, n_est,
            None if pids is None else pids.get(a),
            None if ref is None else ref[:, i],
        )  # fmt: skip
        tried = {s: fit_axis(STRUCTURES[s], rec) for s in names}
        fits.append(_choose(tried))
        candidates.append({s: f.nrmse for s, f in tried.items()})
    return fits, candidates


def _machine(name, dt, axes, fits, pids, note) -> Machine:
    """The identified machine, built through its JSON dictionary (the note is a key there)."""
    plants = {
        a: {"num": f.num.tolist(), "den": f.den.tolist()} for a, f in zip(axes, fits, strict=True)
    }
    return Machine.from_dict(
        {"name": name, "dt": dt, "axes": list(axes), "plants": plants, "feedback": pids,
         "note": note}
    )  # fmt: skip


def _check_inputs(u, y, dt, pid, reference, holdout, axes):
    """Checked arrays and options of :func:`identify`, in its order, plus n_est."""
    u = _as_record(u, "u")
    y = _as_record(y, "y")
    if u.shape != y.shape:
        raise InputError(f"y: expected the shape of u {u.shape}, got {y.shape}")
    n, d = u.shape
    dt = _check_number(dt, "dt", 0.0)
    holdout = _check_number(holdout, "holdout", 0.0, 1.0)
    n_est = int(round((1 - holdout) * n))
    if min(n_est, n - n_est) < MIN_SAMPLES:
        raise InputError(
            f"u, y: expected at least {MIN_SAMPLES} samples to fit and {MIN_SAMPLES} held out "
            f"(holdout {holdout:g}), got {n} samples"
        )
    if axes is None:
        if d > len(_AXIS_NAMES):
            raise InputError(f"axes: expected names for {d} axes, got none")
        axes = _AXIS_NAMES[:d]
    axes = tuple(axes)
    if len(axes) != d:
        raise InputError(f"axes: expected {d} names (the columns of u), got {list(axes)}")
    for i, a in enumerate(axes):
        if not np.any(u[:, i]):
            raise InputError(f"u: the input of axis {a!r} is zero throughout: nothing excites it")
        if np.ptp(y[n_est:, i]) == 0:
            raise InputError(f"y: axis {a!r} does not move in the held-out part of the record")
    ref = None if reference is None else _as_record(reference, "reference")
    if ref is not None and ref.shape != u.shape:
        raise InputError(f"reference: expected the shape of u {u.shape}, got {ref.shape}")
    return u, y, ref, dt, n_est, axes, _pid_per_axis(pid, axes)


def _structure_name(name: Any) -> str:
    if not isinstance(name, str):
        raise InputError(f"structure: expected a name, got {name!r}")
    return _get_structure(name).name
