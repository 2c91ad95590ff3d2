"""Machine JSON files (format in API.md): read with one-sentence errors, write atomically."""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

from primlib._errors import InputError

__all__ = ["read_machine", "write_machine"]


def read_machine(path: str | os.PathLike):
    """Read a machine JSON file.

    Parameters
    ----------
    path : path-like
        The JSON file.

    Returns
    -------
    Machine
        Built by :meth:`primlib.plant.Machine.from_dict` (dispatching on ``"kind"``).

    Raises
    ------
    InputError
        If the file is missing, unreadable, not JSON, or describes an invalid machine; the
        message starts with the file name.
    """
    from primlib.plant import Machine

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"{path}: expected a machine JSON file, got no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: expected a readable UTF-8 JSON file, got {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{path}: expected valid JSON, got {exc.msg} at line {exc.lineno} column {exc.colno}"
        ) from None
    try:
        return Machine.from_dict(data)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def write_machine(path: str | os.PathLike, machine) -> None:
    """Write ``machine.to_dict()`` as indented JSON, atomically (temporary file + rename)."""
    path = Path(path)
    text = json.dumps(machine.to_dict(), indent=2) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent or ".")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
