"""Importing a benchmark's module in a test: ``benchmarks/`` on the path for the fixture's
life only, so the benchmarks' short module names do not leak into other tests."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


@contextmanager
def benchmark_modules(*names: str) -> Iterator[tuple[ModuleType, ...]]:
    """The benchmarks' modules ``names``, imported with ``benchmarks/`` on ``sys.path``."""
    sys.path.insert(0, str(BENCH))
    try:
        yield tuple(importlib.import_module(n) for n in names)
    finally:
        sys.path.remove(str(BENCH))


def bench_output(name: str, args: list[str], monkeypatch, capsys) -> str:
    """What benchmark ``name``'s ``main`` prints when run with command-line ``args``."""
    with benchmark_modules(name) as (bench,):
        monkeypatch.setattr(sys, "argv", [f"{name}.py", *args])
        bench.main()
    return capsys.readouterr().out
