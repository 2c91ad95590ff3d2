"""The server's hold on the library: a pool of reader connections and one writer.

DuckDB lets one process own a file; inside that process any number of connections share
the database and see each other's commits (MVCC). So the service opens the file once per
reader thread (each thread its own :class:`primlib.Library`, so the per-library caches are
never shared across threads) and once more for a single writer thread: reads run side by
side, every write waits its turn in the writer's queue, and no client ever sees "busy".
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from primlib._errors import LibraryBusyError

__all__ = ["Service"]

T = TypeVar("T")


class Service:
    """One library file owned by the server: concurrent reads, serialised writes.

    Parameters
    ----------
    db : str
        The library file (created, with no machines, when it does not exist).
    readers : int
        Reader threads, each with its own connection.

    Notes
    -----
    :meth:`read` and :meth:`write` run a function ``fn(library)`` in a reader thread or in
    the writer thread and await its result; :meth:`compute` runs CPU work that needs no
    library (parsing, fitting) in a reader thread, off the event loop.
    """

    def __init__(self, db: str, readers: int = 2) -> None:
        # Import the pipeline now, not in the first request (seconds on a loaded machine).
        import primlib.match  # noqa: F401
        import primlib.nurbs  # noqa: F401
        import primlib.plant  # noqa: F401
        import primlib.splice  # noqa: F401
        from primlib import Library
        from primlib.pipeline import FitShare

        self.db = db
        self._library_class = Library
        # a model one reader is fitting, the others wait for (FitShare): fitted once
        self._fits = FitShare()
        # The writer opens (and, for a new file, creates and migrates) the file first, so
        # the readers find a current schema.
        self._writer_lib = Library(db)
        self._writer_lib.starter.kept.share = self._fits
        self._libraries = [self._writer_lib]
        self._lock = threading.Lock()
        self._local = threading.local()
        self._readers = ThreadPoolExecutor(max(1, int(readers)), thread_name_prefix="primlib-read")
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="primlib-write")
        self._closing = False

    # ------------------------------------------------------------------ threads
    def _reader_library(self) -> Any:
        lib = getattr(self._local, "library", None)
        if lib is None:
            lib = self._library_class(self.db)
            lib.starter.kept.share = self._fits
            self._local.library = lib
            with self._lock:
                self._libraries.append(lib)
        return lib

    async def read(self, fn: Callable[[Any], T]) -> T:
        """Run ``fn(library)`` in a reader thread."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._readers, lambda: fn(self._reader_library()))

    async def write(self, fn: Callable[[Any], T]) -> T:
        """Run ``fn(library)`` in the writer thread, after every write queued before it.

        Raises
        ------
        LibraryBusyError
            When the server is shutting down (the write is refused, nothing written).
        """
        if self._closing:
            raise LibraryBusyError(
                f"{self.db}: the server is shutting down; the write was refused, send it again"
            )
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._writer, lambda: fn(self._writer_lib))

    async def compute(self, fn: Callable[[], T]) -> T:
        """Run ``fn()`` (no library) in a reader thread, off the event loop."""
        loop = asyncio.get_running_loop()
        return await loop.run_in_executor(self._readers, fn)

    @property
    def closing(self) -> bool:
        return self._closing

    def close(self) -> None:
        """Refuse new writes, let queued work finish, then close every connection.

        Closing the last connection makes DuckDB checkpoint the write-ahead log into the
        file, so a cleanly stopped server leaves one self-contained file behind.
        """
        self._closing = True
        self._writer.shutdown(wait=True)
        self._readers.shutdown(wait=True)
        with self._lock:
            libraries, self._libraries = self._libraries, []
        # readers first, the writer (the first opened) last
        for lib in reversed(libraries):
            lib.close()
