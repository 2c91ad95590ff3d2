"""The command starts fast: `primlib --help` and `primlib list` load neither scipy nor
matplotlib (each costs 0.5-2 s to import), and importing the CLI loads no computing library.

Each check runs in a fresh interpreter, since this test process has imported everything.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import primlib as pl

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("scipy", "matplotlib", "duckdb", "pyarrow", "numpy", "geomdl")


def _loaded_after(code: str) -> set[str]:
    """The packages of HEAVY in ``sys.modules`` after a fresh interpreter runs ``code``."""
    script = f"{code}\nimport sys\nprint('LOADED:', *[m for m in {HEAVY!r} if m in sys.modules])"
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    out = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    last = out.stdout.strip().splitlines()[-1].split()
    assert last[0] == "LOADED:", out.stdout
    return set(last[1:])


def test_import_cli_loads_no_computing_library():
    assert _loaded_after("import primlib.cli") == set()


def test_help_loads_no_computing_library():
    code = "from primlib.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass"
    assert _loaded_after(code) == set()


@pytest.mark.slow
def test_list_loads_neither_scipy_nor_matplotlib(tmp_path):
    db = tmp_path / "lib.duckdb"
    lib = pl.Library(db)
    m = pl.Machine.from_json(ROOT / "data/machines/xyz.json")
    lib.add_machine(m)
    path = pl.Trajectory.from_csv(ROOT / "data/library/circle.csv")
    lib.add(path, np.zeros_like(path.sample(m.dt)), machine="xyz", name="circle")
    del lib
    code = (
        f"from primlib.cli import main\nmain(['--db', {str(db)!r}, 'list'], standalone_mode=False)"
    )
    loaded = _loaded_after(code)
    assert "duckdb" in loaded  # the listing really read the file
    assert not loaded & {"scipy", "matplotlib"}
