"""Bearer tokens: the token file, and who may do what.

A token file has one token per line, with its role in front::

    # primlib serve --token-file tokens.txt
    rw 3f9c0e1d...   # may read and write
    ro 77a1b2c4...   # may read, match and warm-start; never writes

Blank lines and ``#`` comments are ignored. Tokens are compared with
:func:`hmac.compare_digest` against every token of the file (no early exit), so the time a
check takes does not tell how much of a guess was right.
"""

from __future__ import annotations

import hmac
import ipaddress
import os
from dataclasses import dataclass

from primlib._errors import InputError

__all__ = ["Tokens", "read_tokens", "is_loopback", "ROLES", "MIN_TOKEN_LENGTH"]

ROLES = ("rw", "ro")
MIN_TOKEN_LENGTH = 16


@dataclass(frozen=True)
class Tokens:
    """The accepted tokens and their roles (``"rw"`` or ``"ro"``)."""

    entries: tuple[tuple[str, bytes], ...]

    def role(self, token: str | None) -> str | None:
        """The role of ``token``, or None when it is not one of the file's."""
        if token is None:
            return None
        given = token.encode("utf-8", "surrogateescape")
        found = None
        for role, expected in self.entries:
            if hmac.compare_digest(given, expected):
                found = role
        return found


def read_tokens(path: str | os.PathLike) -> Tokens:
    """Read a token file (see the module docstring).

    Raises
    ------
    InputError
        A missing or unreadable file, a line that is not ``ROLE TOKEN``, a token shorter
        than 16 characters, the same token twice, or no token at all.
    """
    try:
        with open(path, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    except FileNotFoundError:
        raise InputError(f"--token-file {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"--token-file {path}: cannot read it ({exc})") from None
    entries: list[tuple[str, bytes]] = []
    for lineno, raw in enumerate(lines, 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) != 2 or parts[0] not in ROLES:
            raise InputError(
                f"--token-file {path}, line {lineno}: expected 'rw TOKEN' or 'ro TOKEN', "
                f"got {len(parts)} word(s)"
                + ("" if len(parts) != 2 else f" starting with {parts[0]!r}")
            )
        if len(parts[1]) < MIN_TOKEN_LENGTH:
            raise InputError(
                f"--token-file {path}, line {lineno}: expected a token of at least "
                f"{MIN_TOKEN_LENGTH} characters, got {len(parts[1])}"
            )
        token = parts[1].encode("utf-8")
        if any(token == t for _, t in entries):
            raise InputError(f"--token-file {path}, line {lineno}: the same token twice")
        entries.append((parts[0], token))
    if not entries:
        raise InputError(f"--token-file {path}: expected at least one token, got none")
    return Tokens(tuple(entries))


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) only accepts local connections."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
