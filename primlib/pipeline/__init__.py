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

from __future__ import annotations

import importlib
from typing import Any

from primlib.pipeline._laws import ILC_LAWS, LAWS, MASTER_SLAVE_LAWS

# public name -> module that defines it, imported on first use: the CLI lists the laws
# without loading the matcher, the splice and the learners
_LAZY = {
    "Library": "primlib.pipeline._library",
    "store_learned": "primlib.pipeline._library",
    "WarmStarter": "primlib.pipeline._starter",
    "as_trajectory": "primlib.pipeline._starter",
    "model_count": "primlib.pipeline._starter",
    "FitShare": "primlib.pipeline._fitted",
    "WarmStart": "primlib.pipeline._warm",
    "find_versions": "primlib.pipeline._warm",
    "stored_signals": "primlib.pipeline._warm",
    "LearnRun": "primlib.pipeline._learn",
    "learn_on_model": "primlib.pipeline._learn",
    "check_law": "primlib.pipeline._learn",
}

__all__ = [*_LAZY, "LAWS", "ILC_LAWS", "MASTER_SLAVE_LAWS"]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'primlib.pipeline' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
