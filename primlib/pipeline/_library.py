"""``primlib.Library``: the store with the pipeline's verbs (match, warm start, learn)."""

from __future__ import annotations

import os
from typing import Any

from primlib.match import Match
from primlib.nurbs import Trajectory
from primlib.pipeline._learn import LearnRun
from primlib.pipeline._starter import WarmStarter, as_trajectory
from primlib.pipeline._warm import WarmStart
from primlib.store import Store

__all__ = ["Library", "store_learned"]


def store_learned(
    store: Store,
    run: LearnRun,
    path: Trajectory,
    machine: str,
    name: str | None = None,
    source: str | None = None,
) -> int:
    """Store a learning run's converged input as a primitive of ``machine``; its id.

    An identical primitive already stored is not written twice (its id is returned).
    """
    return store.add(path, run.u, machine=machine, name=name, source=source)


class Library(Store):
    """A primitive library: the :class:`~primlib.store.Store` plus matching and warm starts.

    What ``pl.Library`` is. Storing and reading are the store's (``add_machine``, ``add``,
    ``add_many``, ``primitives``, ``get``, ``bank``...); :meth:`match`, :meth:`warm_start`
    and :meth:`learn` go through this library's :class:`~primlib.pipeline.WarmStarter`
    (attribute ``starter``), which holds the caches.

    Parameters
    ----------
    path : str or path-like, optional
        The library file; None (the default) gives an in-memory library.
    read_only : bool, default False
    create : bool, default True
        As for :class:`~primlib.store.Store`.

    Examples
    --------
    >>> import primlib as pl
    >>> with pl.Library("lib.duckdb") as lib:  # doctest: +SKIP
    ...     lib.add_machine(pl.Machine.from_json("data/machines/xyz.json"))
    ...     pid = lib.add(path, u, machine="xyz", name="glyph-a")
    ...     ws = lib.warm_start(new_path, machine="xyz", eps=0.05)
    """

    def __init__(
        self, path: str | os.PathLike | None = None, *, read_only: bool = False, create: bool = True
    ) -> None:
        super().__init__(path, read_only=read_only, create=create)
        self.starter = WarmStarter(self)

    def match(
        self, path: Trajectory | str, machine: str, eps: float | None = None, **kw: Any
    ) -> Match:
        """Match a new path against the machine's primitives (:meth:`WarmStarter.match`)."""
        return self.starter.match(path, machine, eps, **kw)

    def warm_start(
        self, path: Trajectory | str, machine: str, eps: float | None = None, **kw: Any
    ) -> WarmStart:
        """First-iteration input for a new path (:meth:`WarmStarter.warm_start`)."""
        return self.starter.warm_start(path, machine, eps, **kw)

    def model_input(self, path: Trajectory | str, machine: str, origin: Any = None):
        """The model-only input of a path and the grey-box model it comes from
        (:meth:`WarmStarter.model_input`)."""
        return self.starter.model_input(path, machine, origin)

    def learn(
        self,
        path: Trajectory | str,
        machine: str,
        *,
        store: bool = False,
        name: str | None = None,
        source: str | None = None,
        **kw: Any,
    ) -> LearnRun:
        """Warm start, ILC, and (``store=True``) the converged input stored back.

        Parameters
        ----------
        path : Trajectory or str
        machine : str
        store : bool
            Store the converged input as a new primitive (the library must be writable).
        name, source : str, optional
            For the stored primitive.
        **kw
            ``cold``, ``iterations``, ``eps``, ``band``, ``law``, ``tol``, ``contour`` of
            :meth:`WarmStarter.learn`.

        Returns
        -------
        LearnRun
            With ``stored_id`` set when stored.
        """
        traj = as_trajectory(path)
        run = self.starter.learn(traj, machine, **kw)
        if not store:
            return run
        pid = store_learned(self, run, traj, machine, name=name, source=source)
        return LearnRun(**{**vars(run), "stored_id": pid})
