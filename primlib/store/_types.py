"""Records the library returns: :class:`PrimitiveInfo`, :class:`Primitive`, :class:`Bank`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the NURBS code loads scipy: imported when a path is rebuilt
    from primlib.nurbs import Trajectory

__all__ = ["PrimitiveInfo", "Primitive", "Bank", "AddResult"]


@dataclass(frozen=True)
class PrimitiveInfo:
    """What the library knows about a stored primitive, without its arrays.

    Attributes
    ----------
    id : int
        The primitive's id (never reused after removal).
    name : str or None
    machine : str
        The machine whose signal this is.
    duration : float
        T, seconds.
    dt : float
        The machine's sample time the path and signal are stored at, seconds.
    n_samples : int
        n = round(T / dt) + 1.
    dim : int
        Number of axes d.
    source : str or None
        Where it came from (a file name, ``"ilc"``...).
    added : datetime
        When it was stored, UTC (timezone-aware).
    origin : tuple of float or None
        The absolute machine position the path started from when its signal was learned
        (where it ran), one coordinate per axis; None where unknown.
    error_rms : float or None
        The RMS tracking error (Euclidean over axes, output units) the signal is estimated
        to leave where it ran, without the measurement noise; None where unknown.
    """

    id: int
    name: str | None
    machine: str
    duration: float
    dt: float
    n_samples: int
    dim: int
    source: str | None
    added: datetime
    origin: tuple[float, ...] | None = field(default=None, kw_only=True)
    error_rms: float | None = field(default=None, kw_only=True)

    def __post_init__(self) -> None:
        if self.origin is not None:  # a JSON list (primlib.client) becomes a tuple
            object.__setattr__(self, "origin", tuple(float(x) for x in self.origin))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary (``added`` in ISO 8601)."""
        return {
            "id": self.id,
            "name": self.name,
            "machine": self.machine,
            "duration": self.duration,
            "dt": self.dt,
            "n_samples": self.n_samples,
            "dim": self.dim,
            "source": self.source,
            "added": self.added.isoformat(),
            "origin": None if self.origin is None else list(self.origin),
            "error_rms": self.error_rms,
        }


@dataclass(frozen=True, eq=False)
class Primitive(PrimitiveInfo):
    """A stored primitive with its curve and arrays.

    Attributes
    ----------
    trajectory : primlib.nurbs.Trajectory
        The NURBS path, rebuilt from its stored definition.
    points : array, shape (n_samples, dim)
        The path at t = 0, dt, ..., T.
    signal : array, shape (n_samples, dim)
        The learned input on the same grid.
    """

    trajectory: Trajectory
    points: np.ndarray
    signal: np.ndarray

    def times(self) -> np.ndarray:
        """The time grid t = 0, dt, ..., T, shape (n_samples,)."""
        return np.arange(self.n_samples) * self.dt


@dataclass(frozen=True, eq=False)
class Bank:
    """All primitives of one machine as flat arrays, for matching without a row loop.

    Primitive i (0 <= i < len(bank), ordered by id) owns samples
    ``offsets[i]:offsets[i + 1]`` of ``points`` and ``signals``.

    Attributes
    ----------
    machine : str
    dt : float
        The machine's sample time, seconds.
    dim : int
        Number of axes d.
    ids : array of int64, shape (k,)
    names : tuple of (str or None), length k
    durations : array, shape (k,)
        Seconds.
    offsets : array of int64, shape (k + 1,)
        Sample offsets; ``np.diff(offsets)`` are the sample counts.
    points : array, shape (N, d)
        Every primitive's path on the dt grid, concatenated (N = offsets[-1]).
    signals : array, shape (N, d)
        Every primitive's signal on the same grid, concatenated. Read from the library on
        first access (one more columnar query), since matching needs only ``points``; the
        library must still be open then.
    degrees : array of int64, shape (k,)
        NURBS degrees.
    knots, knot_offsets : array (K,), array of int64 (k + 1,)
        Knot vectors concatenated, and where each starts.
    ctrlpts : array, shape (M, d)
        Control points concatenated.
    weights : array, shape (M,)
    ctrl_offsets : array of int64, shape (k + 1,)
        Where each primitive's control points (and weights) start.
    origins : array, shape (k, d)
        Each primitive's absolute start position where it ran (its ``origin``), NaN where
        unknown.
    errors : array, shape (k,)
        Each primitive's ``error_rms`` (the tracking error its signal leaves where it ran),
        NaN where unknown.
    """

    machine: str
    dt: float
    dim: int
    ids: np.ndarray
    names: tuple[str | None, ...]
    durations: np.ndarray
    offsets: np.ndarray
    points: np.ndarray
    degrees: np.ndarray
    knots: np.ndarray
    knot_offsets: np.ndarray
    ctrlpts: np.ndarray
    weights: np.ndarray
    ctrl_offsets: np.ndarray
    origins: np.ndarray = field(default=None, kw_only=True)  # type: ignore[assignment]
    errors: np.ndarray = field(default=None, kw_only=True)  # type: ignore[assignment]
    load_signals: Callable[[], np.ndarray] | None = field(default=None, repr=False)
    _signals: list[np.ndarray] = field(default_factory=list, repr=False)

    @classmethod
    def from_samples(
        cls,
        pieces: list[np.ndarray],
        dt: float,
        ids: Any = None,
        names: Any = None,
        machine: str = "",
    ) -> Bank:
        """A bank of sampled paths only (arrays from elsewhere, tests, benchmarks).

        It has no NURBS definitions (``trajectory`` is unavailable) and no signals.

        Parameters
        ----------
        pieces : list of array, shape (n_i, d)
            Each primitive's path at t = 0, dt, ...
        dt : float
        ids : array of int, optional
            Default 0, 1, ...
        names : sequence of str, optional
            Default ``p<id>``.
        machine : str, optional
        """
        counts = [len(p) for p in pieces]
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        ids = np.arange(len(pieces)) if ids is None else np.asarray(ids)
        names = tuple(names) if names is not None else tuple(f"p{i}" for i in ids)
        d = int(pieces[0].shape[1]) if pieces else 3
        points = np.concatenate(pieces).astype(float) if pieces else np.zeros((0, d))
        zero = np.zeros(len(pieces) + 1, dtype=np.int64)
        return cls(
            machine=machine,
            dt=float(dt),
            dim=d,
            ids=ids.astype(np.int64),
            names=names,
            durations=(np.asarray(counts, dtype=float) - 1) * float(dt),
            offsets=offsets,
            points=points,
            degrees=np.zeros(len(pieces), dtype=np.int64),
            knots=np.zeros(0),
            knot_offsets=zero,
            ctrlpts=np.zeros((0, d)),
            weights=np.zeros(0),
            ctrl_offsets=zero,
        )

    def __post_init__(self) -> None:
        if self.origins is None:  # a bank built elsewhere knows no origins
            object.__setattr__(self, "origins", np.full((len(self.ids), self.dim), np.nan))
        if self.errors is None:  # nor what its signals are worth
            object.__setattr__(self, "errors", np.full(len(self.ids), np.nan))

    @property
    def signals(self) -> np.ndarray:
        """Every primitive's signal, concatenated, shape (N, d) (read once, then kept)."""
        if not self._signals:
            if self.load_signals is None:
                raise ValueError("this bank was built without signals")
            self._signals.append(self.load_signals())
        return self._signals[0]

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def n_samples(self) -> np.ndarray:
        """Samples per primitive, shape (k,)."""
        return np.diff(self.offsets)

    def index(self, id: int) -> int:
        """Position in the bank of the primitive with this id (KeyError if absent)."""
        i = int(np.searchsorted(self.ids, id))
        if i >= len(self.ids) or self.ids[i] != id:
            raise KeyError(id)
        return i

    def points_of(self, i: int) -> np.ndarray:
        """Path samples of primitive i, shape (n_i, d) (a view)."""
        return self.points[self.offsets[i] : self.offsets[i + 1]]

    def signal_of(self, i: int) -> np.ndarray:
        """Signal of primitive i, shape (n_i, d) (a view)."""
        return self.signals[self.offsets[i] : self.offsets[i + 1]]

    def times_of(self, i: int) -> np.ndarray:
        """Time grid of primitive i, shape (n_i,)."""
        return np.arange(self.offsets[i + 1] - self.offsets[i]) * self.dt

    def trajectory(self, i: int) -> Trajectory:
        """The NURBS path of primitive i, a :class:`primlib.nurbs.Trajectory`."""
        from primlib.nurbs import Trajectory

        c0, c1 = self.ctrl_offsets[i], self.ctrl_offsets[i + 1]
        return Trajectory.from_definition(
            int(self.degrees[i]),
            self.knots[self.knot_offsets[i] : self.knot_offsets[i + 1]],
            self.ctrlpts[c0:c1],
            self.weights[c0:c1],
            float(self.durations[i]),
        )

    def head(self, n: int) -> Bank:
        """The bank of the first ``n`` primitives (the oldest: ids never come back), sharing
        this bank's arrays (views) and its signals (read through this bank, once)."""
        n = max(0, min(int(n), len(self)))
        if n == len(self):
            return self
        s, c, k = int(self.offsets[n]), int(self.ctrl_offsets[n]), int(self.knot_offsets[n])
        loader = None
        if self.load_signals is not None or self._signals:
            loader = lambda: self.signals[:s]  # noqa: E731  lazily, as this bank's own
        return Bank(
            machine=self.machine,
            dt=self.dt,
            dim=self.dim,
            ids=self.ids[:n],
            names=self.names[:n],
            durations=self.durations[:n],
            offsets=self.offsets[: n + 1],
            points=self.points[:s],
            degrees=self.degrees[:n],
            knots=self.knots[:k],
            knot_offsets=self.knot_offsets[: n + 1],
            ctrlpts=self.ctrlpts[:c],
            weights=self.weights[:c],
            ctrl_offsets=self.ctrl_offsets[: n + 1],
            origins=self.origins[:n],
            errors=self.errors[:n],
            load_signals=loader,
        )

    def __repr__(self) -> str:
        return (
            f"Bank(machine={self.machine!r}, {len(self)} primitives, "
            f"{int(self.offsets[-1])} samples, dt={self.dt})"
        )


@dataclass(frozen=True)
class AddResult:
    """What a batch write did: the id each item is stored under, and which were there already.

    Attributes
    ----------
    ids : tuple of int
        Per item, in order: its new id, or for a duplicate the id of the identical primitive
        already stored (or written earlier in the same batch).
    duplicates : tuple of int
        Positions (in the batch) of the items that were not written because an identical
        primitive (same machine, path and signal) was stored already.
    """

    ids: tuple[int, ...]
    duplicates: tuple[int, ...] = ()

    @property
    def added(self) -> int:
        """How many primitives were written."""
        return len(self.ids) - len(self.duplicates)
