"""Benchmark of the command's start-up: ``primlib --help`` and ``primlib list`` on the
bundled example library (14 primitives), each a fresh process.

Reports the median and the worst of ``--repeat`` runs of each command, beside the baseline
measured in the same run: the same command in a process that first imports every package
eagerly (numpy, scipy, duckdb, pyarrow, matplotlib, geomdl and all of primlib's packages),
as the command did before its imports were made lazy. Goals (issue 13): ``--help`` <= 0.3 s,
``list`` <= 0.6 s. Then the heaviest modules ``primlib list`` imports (``python -X
importtime``), and an assertion that neither command loads scipy or matplotlib.

Run: ``python benchmarks/bench_startup.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _revisions import checkout_env

ROOT = Path(__file__).resolve().parents[1]
GOALS = {"--help": 0.3, "list": 0.6}
# what the command loaded before: every package, at start-up
EAGER = (
    "import numpy, scipy.interpolate, scipy.signal, scipy.spatial, duckdb, pyarrow, geomdl, "
    "matplotlib.pyplot; import primlib.nurbs, primlib.plant, primlib.store, primlib.match, "
    "primlib.splice, primlib.ilc, primlib.pipeline, primlib.plot; "
)
HEAVY = ("scipy", "matplotlib")


def _run(code: str, args: list[str]) -> float:
    """Wall-clock seconds of one fresh interpreter running ``code`` then the command."""
    script = f"{code}import sys; from primlib.cli import main; main({args!r}, prog_name='primlib')"
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", script], env=checkout_env(), check=True, capture_output=True
    )
    return time.perf_counter() - t0


def _build_library(db: Path) -> None:
    import contextlib
    import io

    from primlib.cli import main

    csvs = sorted(str(p) for p in (ROOT / "data" / "library").glob("*.csv"))
    paths = [p for p in csvs if not p.endswith(".signal.csv")]
    for args in (
        ["--db", str(db), "machine", "add", str(ROOT / "data/machines/xyz.json")],
        ["--db", str(db), "ingest", *paths, "--machine", "xyz"],
    ):
        with contextlib.redirect_stdout(io.StringIO()):
            main(args, prog_name="primlib", standalone_mode=False)


def _loaded(args: list[str]) -> set[str]:
    """Top-level packages of ``HEAVY`` that the command leaves in ``sys.modules``."""
    script = (
        "import sys; from primlib.cli import main\n"
        f"try:\n    main({args!r}, prog_name='primlib')\nexcept SystemExit:\n    pass\n"
        f"print('LOADED:', *[m for m in {HEAVY!r} if m in sys.modules])"
    )
    out = subprocess.run(
        [sys.executable, "-c", script],
        env=checkout_env(),
        check=True,
        capture_output=True,
        text=True,
    )
    return set(out.stdout.strip().splitlines()[-1].split()[1:])


def _heaviest(args: list[str], top: int = 6) -> list[tuple[float, str]]:
    """The ``top`` top-level imports by cumulative time (``python -X importtime``)."""
    script = f"from primlib.cli import main; main({args!r}, prog_name='primlib')"
    err = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", script],
        env=checkout_env(),
        capture_output=True,
        text=True,
    ).stderr
    rows = []
    for line in err.splitlines():
        parts = line.split("|")
        if len(parts) == 3 and parts[1].strip().isdigit():
            name = parts[2].rstrip()
            depth = (len(name) - len(name.lstrip())) // 2
            if depth <= 1:
                rows.append((int(parts[1]) / 1e6, name.strip()))
    return sorted(rows, reverse=True)[:top]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=7)
    opts = ap.parse_args()
    print(f"load average: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "example.duckdb"
        _build_library(db)
        commands = {"--help": ["--help"], "list": ["--db", str(db), "list"]}
        print(f"{'command':<9}{'lazy median':>13}{'worst':>8}{'eager median':>14}{'ratio':>7}"
              f"{'goal':>7}")  # fmt: skip
        for label, args in commands.items():
            lazy = [_run("", args) for _ in range(opts.repeat)]
            eager = [_run(EAGER, args) for _ in range(opts.repeat)]
            m, e = statistics.median(lazy), statistics.median(eager)
            ok = "ok" if m <= GOALS[label] else "MISSED"
            print(f"{label:<9}{m:>11.3f} s{max(lazy):>7.3f}{e:>12.3f} s{e / m:>6.1f}x"
                  f"{GOALS[label]:>6.1f} {ok}")  # fmt: skip
        print("\nheaviest imports of `primlib list` (cumulative, python -X importtime):")
        for seconds, name in _heaviest(commands["list"]):
            print(f"  {seconds:7.3f} s  {name}")
        for label, args in commands.items():
            loaded = _loaded(args)
            assert not loaded, f"`primlib {label}` imported {sorted(loaded)}"
        print(f"\nneither command imports {', '.join(HEAVY)}")
    print(f"load average: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")


if __name__ == "__main__":
    main()
