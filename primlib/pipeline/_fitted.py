"""The warm start's fitted models, kept in the library file and read back.

A warm start fits a grey-box model (:func:`primlib.greybox.fit_greybox`) and a refined linear
model (:func:`primlib.splice.refine_machine`) to a machine's stored pairs. On a library
learned on a machine with friction that took 50 s, and every process paid it again: each
``primlib match --out`` took 50 s for a 1 s match and splice. :class:`KeptModels` keeps each
fitted model in the library (table ``fitted_models``, schema version 7) under a key that
names everything the fit depends on, so the next process reads it instead.

The key is a SHA-256 of: the kind of model, the machine definition it is fitted beside,
the machine's primitive ids (stored primitives never change and ids are never reused, so the
ids name the data), the fit's options, and :func:`code_version` -- a hash of primlib's own
source and numpy's and scipy's versions, so that any change of the code that fits makes the
kept models unreadable rather than stale. A model read back is the fitted one to the bit
(arrays as ``.npz``, the machine as its JSON dictionary, whose floats round-trip exactly):
the warm start from a kept model equals the one from a fresh fit, which the tests assert.
The payload is read with ``allow_pickle=False``: a library file cannot run code.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import threading
from collections import OrderedDict
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from primlib._errors import InputError, LibraryBusyError
from primlib.greybox import GreyBox
from primlib.plant import Machine
from primlib.splice import RefinedModel
from primlib.store import Store, keep_fitted, read_fitted

__all__ = [
    "FitShare",
    "KeptModels",
    "code_version",
    "encode",
    "decode",
    "fit_key",
    "bank_signature",
]

_TYPES = {"GreyBox": GreyBox, "RefinedModel": RefinedModel}


@functools.cache
def code_version() -> str:
    """A hash of primlib's source files and numpy's and scipy's versions (16 hex digits)."""
    import scipy

    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    h.update(f"numpy {np.__version__} scipy {scipy.__version__}".encode())
    return h.hexdigest()[:16]


def bank_signature(ids: Sequence[int]) -> str:
    """The primitive set a model was fitted to: a hash of its sorted ids."""
    text = ",".join(str(int(i)) for i in sorted(int(i) for i in ids))
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def fit_key(kind: str, machine: Machine, ids: Sequence[int], **options: Any) -> str:
    """The key of a fitted model: what it is, beside which machine, on which primitives,
    with which options, by which code."""
    text = json.dumps(
        {
            "kind": kind,
            "machine": machine.to_dict(),
            "ids": [int(i) for i in ids],
            "options": options,
            "code": code_version(),
        },
        sort_keys=True,
    )
    return hashlib.sha256(text.encode()).hexdigest()


def encode(model: GreyBox | RefinedModel) -> bytes:
    """A fitted model as ``.npz`` bytes: its arrays, and a JSON header for the rest."""
    fields: dict[str, Any] = {}
    arrays: dict[str, np.ndarray] = {}
    for f in dataclasses.fields(model):
        v = getattr(model, f.name)
        if isinstance(v, Machine):
            fields[f.name] = {"machine": v.to_dict()}
        elif isinstance(v, np.ndarray):
            arrays[f.name] = v
            fields[f.name] = {"array": True}
        elif isinstance(v, tuple):
            fields[f.name] = {"tuple": [str(x) for x in v]}
        elif v is None or isinstance(v, (bool, int, float, str, np.generic)):
            fields[f.name] = {"value": v.item() if isinstance(v, np.generic) else v}
        else:  # a new field of another type must be taught here, not pickled
            raise TypeError(f"{type(model).__name__}.{f.name}: cannot encode {type(v).__name__}")
    header = json.dumps({"type": type(model).__name__, "fields": fields})
    buf = io.BytesIO()
    np.savez(buf, __header__=np.frombuffer(header.encode(), dtype=np.uint8), **arrays)
    return buf.getvalue()


def decode(payload: bytes) -> GreyBox | RefinedModel:
    """The model :func:`encode` wrote.

    Raises
    ------
    ValueError
        Bytes this code cannot read as a fitted model (the caller fits it again).
    """
    try:
        with np.load(io.BytesIO(payload), allow_pickle=False) as z:
            header = json.loads(bytes(z["__header__"]).decode())
            cls = _TYPES[header["type"]]
            kw: dict[str, Any] = {}
            for name, spec in header["fields"].items():
                if "machine" in spec:
                    kw[name] = Machine.from_dict(spec["machine"])
                elif "array" in spec:
                    kw[name] = z[name]
                elif "tuple" in spec:
                    kw[name] = tuple(spec["tuple"])
                else:
                    kw[name] = spec["value"]
            return cls(**kw)
    except (OSError, KeyError, TypeError, ValueError, InputError) as exc:
        raise ValueError(f"not a fitted model this primlib reads ({exc})") from None


class FitShare:
    """Models being fitted, shared by the :class:`KeptModels` of several connections to one
    file in one process (``primlib serve``'s reader threads): a model one is fitting, the
    others wait for rather than fit too.

    When the library crosses a size at which its models are fitted again, every reader asked
    for a warm start fitted them at once, on the same cores (on 1,000 primitives, 11 s a fit
    alone). The one that starts first fits; the others take its model when it is done, or
    fit it themselves if its fit failed.
    """

    def __init__(self, keep: int = 8) -> None:
        self._lock = threading.Lock()
        self._running: dict[str, threading.Event] = {}
        self._done: OrderedDict[str, Any] = OrderedDict()
        self._keep = int(keep)

    def fit(self, key: str, fit: Callable[[], Any]) -> tuple[Any, bool]:
        """(the model under ``key``, whether this call fitted it): fitted here, or the one
        another thread fitted (waited for)."""
        while True:
            with self._lock:
                if key in self._done:
                    return self._done[key], False
                event = self._running.get(key)
                if event is None:
                    event = self._running[key] = threading.Event()
                    break
            event.wait()  # the other thread's fit; none left behind: try again
        try:
            model = fit()
            with self._lock:
                self._done[key] = model
                while len(self._done) > self._keep:
                    self._done.popitem(last=False)
            return model, True
        finally:
            with self._lock:
                del self._running[key]
            event.set()


class KeptModels:
    """The fitted models of one store: read by key, fitted on a miss, and kept.

    A writable store keeps each model as it is fitted (one transaction). A read-only one
    (``primlib match`` and ``primlib learn`` read with the file open read-only, so other
    readers are not locked out) collects them in :attr:`pending`, which a writer keeps
    with :meth:`keep_pending`.

    Attributes
    ----------
    pending : dict
        Machine name -> (primitive set signature, list of (key, kind, payload)): fitted in
        this process, not yet in the file.
    fitted, read : int
        Models fitted here, and read back from the file (or taken from another connection's
        fit through :attr:`share`).
    share : FitShare or None
        Shared with other connections to the file in this process (``primlib serve``).
    """

    def __init__(self, store: Store, share: FitShare | None = None) -> None:
        self.store = store
        self.share = share
        self.pending: dict[str, tuple[str, list[tuple[str, str, bytes]]]] = {}
        self.fitted = 0
        self.read = 0

    def get(self, kind: str, machine: str, ids: Sequence[int], key: str, fit: Callable[[], Any]):
        """The model kept under ``key``, else ``fit()`` (kept, or queued in :attr:`pending`).

        ``machine`` names the store's machine, ``ids`` the primitives the model is fitted
        on (:meth:`~primlib.pipeline.WarmStarter.model_bank`).
        """
        payload = read_fitted(self.store, key)
        if payload is not None:
            try:
                model = decode(payload)
            except ValueError:  # written by another primlib: fitted again and replaced
                pass
            else:
                self.read += 1
                return model
        if self.share is None:
            model, fitted = fit(), True
        else:  # another connection of this process may be fitting it: wait for it
            model, fitted = self.share.fit(key, fit)
        if not fitted:
            self.read += 1
            return model
        self.fitted += 1
        bank = bank_signature(ids)
        row = (key, kind, encode(model))
        if self.store.read_only:
            if machine in self.pending and self.pending[machine][0] == bank:
                self.pending[machine][1].append(row)
            else:
                self.pending[machine] = (bank, [row])
            return model
        try:
            keep_fitted(self.store, machine, bank, code_version(), [row])
        except LibraryBusyError:  # a concurrent writer (a server's reader thread): not kept
            pass
        return model

    def keep_pending(self, store: Store) -> int:
        """Keep :attr:`pending` in the writable ``store`` (the same file); rows written.

        Raises
        ------
        InputError
            ``store`` is open read-only.
        """
        if store.read_only:
            raise InputError(f"{store.path}: open read-only; cannot keep the fitted models")
        code = code_version()
        count = sum(
            keep_fitted(store, m, bank, code, rows) for m, (bank, rows) in self.pending.items()
        )
        self.pending = {}
        return count
