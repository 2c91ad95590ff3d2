"""Machine JSON files (format in docs/files.rst): the file and its JSON, nothing about machines.

:meth:`primlib.plant.Machine.from_json` reads the dictionary here and builds the machine
from it, so ``io`` never imports ``plant`` (one direction: plant -> io).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from primlib._errors import InputError
from primlib.io._csv import write_text_atomic

__all__ = ["read_machine_json", "write_machine_json"]


def read_machine_json(path: str | os.PathLike) -> dict[str, Any]:
    """Read a machine JSON file into its dictionary (checked by ``Machine.from_dict``).

    Parameters
    ----------
    path : path-like
        The JSON file.

    Returns
    -------
    dict
        The JSON object.

    Raises
    ------
    InputError
        If the file is missing, unreadable, not JSON or not a JSON object; the message
        starts with the file name.
    """
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
    except RecursionError:
        raise InputError(f"{path}: expected valid JSON, got nesting too deep to read") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: machine: expected a JSON object, got {type(data).__name__}")
    return data


def write_machine_json(path: str | os.PathLike, data: dict[str, Any]) -> None:
    """Write a machine's dictionary (``Machine.to_dict()``) as indented JSON, atomically
    (temporary file + rename)."""
    write_text_atomic(Path(path), json.dumps(data, indent=2) + "\n")
