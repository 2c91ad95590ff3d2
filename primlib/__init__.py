"""primlib: a library of learned motion primitives for iterative learning control.

A new path is cut into pieces that match stored primitives up to rotation, translation and
time scale (``primlib.match``); the primitives' converged ILC inputs are carried over and
spliced into a first-iteration input (``primlib.splice``); ILC (``primlib.ilc``) starts from
it on a machine model (``primlib.plant``), and what it learns is stored back
(``primlib.store``). ``primlib.pipeline`` owns that loop; ``pl.Library`` is its library (the
store plus ``match``, ``warm_start`` and ``learn``). See ``docs/api.rst`` for the public interface.

Top-level names are imported lazily, so ``import primlib`` stays cheap (no DuckDB, no
matplotlib until used).
"""

from __future__ import annotations

import importlib
from typing import Any

from primlib._errors import (
    InputError,
    LibraryBusyError,
    NoMatchError,
    NotALibraryError,
    NotFoundError,
    PrimlibError,
)

__version__ = "0.1.0"

# public name -> module that defines it
_LAZY = {
    "Trajectory": "primlib.nurbs",
    "Machine": "primlib.plant",
    "Library": "primlib.pipeline",
    "Store": "primlib.store",
    "Match": "primlib.match",
    "Segment": "primlib.match",
    "WarmStart": "primlib.pipeline",
}

__all__ = [
    "PrimlibError",
    "InputError",
    "NotFoundError",
    "NotALibraryError",
    "LibraryBusyError",
    "NoMatchError",
    *_LAZY,
]


def _subpackages() -> list[str]:
    import pkgutil

    return [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        # a subpackage (primlib.contour, primlib.pipeline...), imported on first use
        if name.startswith("_") or name not in _subpackages():
            raise AttributeError(f"module 'primlib' has no attribute {name!r}")
        value = importlib.import_module(f"primlib.{name}")
        globals()[name] = value
        return value
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY) | set(_subpackages()))
