"""A client of ``primlib serve``: the library's method names over HTTP (stdlib only).

A script moves between a local library file and a server by one line::

    lib = pl.Library("lib.duckdb")                    # local
    lib = Client("http://stage-pc:8321", token=tok)   # remote, same calls below
    ws = lib.warm_start(path, machine="xyz", eps=0.05)

Trial series (:mod:`primlib.trials`) are ``Client.trials``: ``lib.trials.start(path,
"xyz")``, ``.step(series, measured, trial=k)``, ``.status``, ``.pending``, ``.finish``,
``.run`` and ``.list``.
"""

from primlib.client._client import (
    Client,
    RemoteError,
    RemoteInputError,
    RemoteNotFoundError,
    match_from_dict,
    warm_start_from_dict,
)
from primlib.client._trials import RemoteTrials

__all__ = [
    "Client",
    "RemoteError",
    "RemoteInputError",
    "RemoteNotFoundError",
    "match_from_dict",
    "warm_start_from_dict",
    "RemoteTrials",
]
