"""The pipeline: match -> warm start -> learn -> store back, with one owner.

:class:`Library` (what users get as ``primlib.Library``) is the store
(:class:`primlib.store.Store`, persistence only) plus :meth:`Library.match`,
:meth:`Library.warm_start` and :meth:`Library.learn`, all through one :class:`WarmStarter`
that holds the pipeline's caches on itself. The Python API, ``primlib learn``,
``primlib ingest --learn`` and ``primlib match --out`` run the same code:
:meth:`WarmStarter.learn` (warm start, then :func:`learn_on_model`), then
:func:`store_learned`.

Data flows one way: ``store`` reads the bank, ``match`` cuts the path, ``splice`` carries
the stored inputs over, ``ilc`` learns; none of them calls back into this package.
"""

from primlib.pipeline._learn import (
    ILC_LAWS,
    LAWS,
    MASTER_SLAVE_LAWS,
    LearnRun,
    check_law,
    learn_on_model,
)
from primlib.pipeline._library import Library, store_learned
from primlib.pipeline._starter import WarmStarter, as_trajectory
from primlib.pipeline._warm import WarmStart, find_versions, stored_signals

__all__ = [
    "Library",
    "WarmStarter",
    "WarmStart",
    "LearnRun",
    "learn_on_model",
    "check_law",
    "store_learned",
    "as_trajectory",
    "find_versions",
    "stored_signals",
    "LAWS",
    "ILC_LAWS",
    "MASTER_SLAVE_LAWS",
]
