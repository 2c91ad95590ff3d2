"""Trial series on a server: :mod:`primlib.trials`' functions as methods of ``Client.trials``.

``primlib.trials.start(lib, path, "xyz")`` becomes ``client.trials.start(path, "xyz")``,
and so on for ``pending``, ``step``, ``status``, ``finish`` and ``run`` (``run_trials``),
with the same arguments after ``lib`` and the same result types (``StartResult``,
``StepResult``, ``RunResult``); ``status`` returns :meth:`SeriesStatus.to_dict`'s dict.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from primlib._errors import InputError

__all__ = ["RemoteTrials"]


def _series(series: Any) -> int:
    if isinstance(series, bool) or not isinstance(series, (int, np.integer)):
        raise InputError(f"series: expected an integer series id, got {series!r}")
    return int(series)


def _step_result(d: dict[str, Any]) -> Any:
    from primlib.trials import StepResult

    return StepResult(
        series=int(d["series"]),
        trial=int(d["trial"]),
        rms=float(d["rms"]),
        contour_rms=d["contour_rms"],
        noise_floor=d["noise_floor"],
        q_cutoff=d["q_cutoff"],
        converged=bool(d["converged"]),
        diverging=bool(d["diverging"]),
        t=np.asarray(d["t"], dtype=float),
        u=np.asarray(d["u"], dtype=float),
    )


class RemoteTrials:
    """The trial series of a server's library (``Client(url).trials``).

    A step names the trial it measured; the server refuses (409,
    :class:`~primlib.client.RemoteInputError`) a step of a trial another client has
    recorded meanwhile, so two controllers never both step one trial.
    """

    def __init__(self, client: Any) -> None:
        self._client = client

    def __repr__(self) -> str:
        return f"{self._client!r}.trials"

    def start(
        self,
        path: Any,
        machine: str,
        *,
        first: str = "warm",
        eps: float | None = None,
        name: str | None = None,
        **options: Any,
    ) -> Any:
        """Start a series (:func:`primlib.trials.start`); its :class:`StartResult`.

        ``options`` are the law's (``law``, ``noise_aware``, ``average``, ``margin``,
        ``q_cutoff``); those left out take the library's defaults, as locally.
        """
        from primlib.client._client import nurbs_of
        from primlib.trials import StartResult

        body = {"machine": machine, "path": nurbs_of(path), "first": first, "eps": eps,
                "name": name, **options}  # fmt: skip
        body = {k: v for k, v in body.items() if v is not None}
        d = self._client.request("POST", "/trials", body)
        t, u = np.asarray(d["t"], dtype=float), np.asarray(d["u"], dtype=float)
        return StartResult(int(d["series"]), t, u, d["start"], tuple(d["notes"]))

    def pending(self, series: int) -> tuple[int, np.ndarray, np.ndarray]:
        """The trial to run next: (trial number, t (n,), u (n, d))."""
        d = self._client.request("GET", f"/trials/{_series(series)}/input")
        return int(d["trial"]), np.asarray(d["t"], dtype=float), np.asarray(d["u"], dtype=float)

    def step(self, series: int, measured: Any, *, trial: int | None = None) -> Any:
        """Record the pending trial's measured output (absolute positions); the
        :class:`StepResult` with the next input.

        Parameters
        ----------
        series : int
        measured : array, shape (n, d)
        trial : int, optional
            The trial ``measured`` was run for (what :meth:`pending`, :meth:`start` or the
            last step said). Default: the trial pending when this is called (one more
            request; pass it to be refused rather than recorded as the next trial when
            another client stepped the series in between).
        """
        sid = _series(series)
        y = np.asarray(measured, dtype=float)
        if not np.isfinite(y).all():
            raise InputError("measured: expected finite positions, got NaN or inf")
        k = self.pending(sid)[0] if trial is None else int(trial)
        body = {"trial": k, "measured": y.tolist()}
        return _step_result(self._client.request("POST", f"/trials/{sid}/step", body))

    def status(self, series: int) -> dict[str, Any]:
        """Where a series stands: :meth:`primlib.trials.SeriesStatus.to_dict`'s dict
        (``verdict``, ``noise_floor``, ``trials`` with their errors, ``origin``...)."""
        return self._client.request("GET", f"/trials/{_series(series)}")

    def finish(self, series: int, *, name: str | None = None, force: bool = False) -> int:
        """Store the converged input as a primitive (:func:`primlib.trials.finish`); its id."""
        body = {"force": bool(force), **({"name": name} if name is not None else {})}
        d = self._client.request("POST", f"/trials/{_series(series)}/finish", body)
        return int(d["primitive"])

    def run(
        self,
        series: int,
        plant: Any,
        max_trials: int = 20,
        callback: Callable[[Any], None] | None = None,
    ) -> Any:
        """Run trials on a plant until the stop rule (:func:`primlib.trials.run_trials`).

        ``plant.run(u)`` returns the output relative to the start point; the series'
        origin is added before each step, as locally.
        """
        from primlib.trials import RunResult

        if isinstance(max_trials, bool) or not isinstance(max_trials, (int, np.integer)):
            raise InputError(f"max_trials: expected an integer >= 1, got {max_trials!r}")
        if max_trials < 1:
            raise InputError(f"max_trials: expected an integer >= 1, got {max_trials}")
        origin = np.asarray(self.status(series)["origin"], dtype=float)
        steps = []
        for _ in range(int(max_trials)):
            trial, _, u = self.pending(series)
            y = np.asarray(plant.run(u), dtype=float) + origin
            res = self.step(series, y, trial=trial)
            steps.append(res)
            if callback is not None:
                callback(res)
            if res.converged or res.diverging:
                return RunResult(steps, "converged" if res.converged else "diverging")
        return RunResult(steps, "max-trials")

    def list(self, machine: str | None = None) -> list[dict[str, Any]]:
        """The series (of one machine): id, machine, name, state, start, steps, last rms,
        primitive (as ``primlib trials list``)."""
        return self._client.request("GET", "/trials", query={"machine": machine})
