"""Timing another git revision's primlib beside this tree's, in the same run.

The revision's ``primlib`` is extracted with ``git archive`` into a folder (:func:`extract`);
a benchmark's worker script then runs once per tree in a process of its own, single-threaded,
with that tree's primlib first on ``PYTHONPATH`` (:func:`run_worker`; the script's own folder
is on ``sys.path`` as for any script, so its helper modules are this tree's), alternated
round by round so that a shared machine's load weighs on both alike (:func:`alternated`).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

__all__ = ["ROOT", "alternated", "checkout_env", "extract", "run_worker", "without_kept"]


def checkout_env() -> dict[str, str]:
    """The environment of a fresh ``primlib`` process that runs this checkout's primlib (first
    on ``PYTHONPATH``), drawing without a display."""
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def without_kept(src: str | Path, dst: str | Path) -> None:
    """A copy of library file ``src`` at ``dst`` without the models kept in it, so that the
    run timed on it fits them (as every tree's first warm start did before they were kept)."""
    import shutil

    import duckdb

    shutil.copyfile(src, dst)
    with duckdb.connect(str(dst)) as con:
        con.execute("DELETE FROM fitted_models")


def extract(rev: str, folder: str | Path) -> Path:
    """Revision ``rev``'s ``primlib`` package extracted into ``folder`` (returned); a
    SystemExit (status 2) saying why when git cannot give it (no git, a folder that is not a
    checkout -- a ``git archive`` snapshot -- or an unknown revision)."""
    try:
        done = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "primlib"],
                              capture_output=True)  # fmt: skip
    except OSError as exc:
        raise SystemExit(_no_baseline(rev, f"git did not run ({exc})")) from None
    if done.returncode != 0:
        why = done.stderr.decode(errors="replace").strip().splitlines() or ["git failed"]
        raise SystemExit(_no_baseline(rev, why[-1]))
    tar = done.stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=tar, check=True)
    return Path(folder)


def _no_baseline(rev: str, why: str) -> int:
    """Say on stderr why the baseline revision cannot be had; the exit status (2)."""
    print(f"baseline {rev!r}: cannot extract it from {ROOT}: {why} (run from a git "
          "checkout that holds the revision, or pass --no-baseline)", file=sys.stderr)  # fmt: skip
    return 2


def run_worker(script: str | Path, arg: str, tree: str | Path) -> Any:
    """``script --worker arg`` with ``tree``'s primlib, single-threaded, in a process of its
    own: its last line of output, parsed as JSON."""
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    out = subprocess.run([sys.executable, str(script), "--worker", arg], env=env,
                         capture_output=True, text=True, check=True)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def alternated(script: str | Path, arg: str, baseline: str, rounds: int) -> dict[str, list]:
    """:func:`run_worker` with this tree and with revision ``baseline``, alternated
    ``rounds`` times (which goes first swaps each round): each run's result, per tree
    (keys ``"this tree"`` and ``baseline``)."""
    res: dict[str, list] = {"this tree": [], baseline: []}
    with tempfile.TemporaryDirectory(prefix="bench_base_") as folder:
        trees = {"this tree": ROOT, baseline: extract(baseline, folder)}
        for r in range(rounds):
            for label in list(trees) if r % 2 == 0 else list(trees)[::-1]:
                res[label].append(run_worker(script, arg, trees[label]))
    return res
