"""Exceptions raised by primlib.

Every error that a user can cause by what they pass in (a file, an array, an option) is a
:class:`PrimlibError` *and* the fitting builtin, so ``except ValueError`` keeps working. The
command line turns :class:`InputError` and :class:`NotFoundError` into exit status 2 with the
message as one line, and any other :class:`PrimlibError` into exit status 1.
"""

from __future__ import annotations

__all__ = [
    "PrimlibError",
    "InputError",
    "NotFoundError",
    "NotALibraryError",
    "LibraryBusyError",
    "NoMatchError",
]


class PrimlibError(Exception):
    """Base class of every error primlib raises on purpose."""


class InputError(PrimlibError, ValueError):
    """Bad input: a malformed file or array, an option out of range. CLI exit status 2."""


class NotFoundError(PrimlibError, LookupError):
    """A named thing that is not there: an unknown machine, a primitive id. CLI exit 2."""

    def __str__(self) -> str:  # LookupError would quote the message like a dict key
        return str(self.args[0]) if self.args else ""


class NotALibraryError(InputError):
    """A file that exists but is not a primlib library (or is of a newer schema)."""


class LibraryBusyError(PrimlibError, OSError):
    """Another process holds the library file open for writing. CLI exit 2."""


class NoMatchError(InputError):
    """Nothing to match against (an empty library) or a path nothing matches at all."""
