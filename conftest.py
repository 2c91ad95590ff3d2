"""Doctest set-up: the examples in primlib's docstrings and in docs/*.rst run as tests.

Every example may use these names without importing them: ``np``, ``pl`` (primlib),
``Machine``, ``Trajectory``, ``m`` (the XYZ machine of eq. (24)), ``m2`` (the two-axis
PDCCILC stage), ``reference`` (a 3-axis rest-to-rest reference for ``m``, shape (201, 3)),
``points`` (a 10 mm semicircle for ``m2``, shape (401, 2)), ``u`` (an input for ``m``),
``lib`` and ``example_lib`` (an in-memory library holding the bundled example primitives)
and ``path`` (a new path made of them, ``data/paths/zigzag.csv``). Examples run from the
repository's top folder, so ``data/...`` paths resolve.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parent

# ``python -m primlib`` runs the CLI at import: not a module to collect doctests from.
collect_ignore = ["primlib/__main__.py"]


def _example_library():
    import primlib as pl
    from primlib.io import read_signal_csv

    lib = pl.Library()
    lib.add_machine(pl.Machine.from_json(ROOT / "data/machines/xyz.json"))
    for f in sorted((ROOT / "data/library").glob("*.csv")):
        if f.name.endswith(".signal.csv"):
            continue
        _, u = read_signal_csv(f.with_suffix(".signal.csv"))
        lib.add(pl.Trajectory.from_csv(f), u, machine="xyz", name=f.stem)
    return lib


@pytest.fixture(scope="session")
def _doctest_objects():
    import primlib as pl
    from primlib.plant import invert

    m = pl.Machine.from_json(ROOT / "data/machines/xyz.json")
    s = np.linspace(0.0, 1.0, 201)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5  # minimum-jerk: rest to rest
    reference = np.column_stack([10 * blend, 5 * blend, 2 * blend])
    th = np.pi * np.linspace(0.0, 1.0, 401)
    lib = _example_library()
    return {
        "np": np,
        "pl": pl,
        "Machine": pl.Machine,
        "Trajectory": pl.Trajectory,
        "m": m,
        "m2": pl.Machine.from_json(ROOT / "data/machines/xy-pdccilc.json"),
        "reference": reference,
        "points": np.column_stack([10 * (1 - np.cos(th)), 10 * np.sin(th)]),
        "u": invert(m, reference),
        "lib": lib,
        "example_lib": lib,  # the same, under a name a page can use after rebinding ``lib``
        "path": pl.Trajectory.from_csv(ROOT / "data/paths/zigzag.csv"),
    }


@pytest.fixture(autouse=True)
def _doctest_setup(request, monkeypatch):
    """Fill the doctest namespace and run doctests from the top folder."""
    from _pytest.doctest import DoctestItem

    if not isinstance(request.node, DoctestItem):
        return
    namespace = request.getfixturevalue("doctest_namespace")
    namespace.update(request.getfixturevalue("_doctest_objects"))
    monkeypatch.chdir(ROOT)
