"""A stage over files: run one trial of the example linear-motor table, like hardware would.

    python examples/stage/stage.py --start X,Y INPUT.csv OUTPUT.csv [--noise MM] [--seed S]

Reads the input (signal CSV ``t,ux,uy``, volts), runs the nonlinear motor model of
``stage.json`` (friction, force ripple, a constant disturbance) from rest at the absolute
position ``--start`` (mm), adds measurement noise (Gaussian, ``--noise`` mm standard
deviation, default 0.01 = 10 um) and writes the measured absolute positions (path CSV
``t,x,y``). The noise is seeded by ``--seed`` and the input's bytes: running the same input
again measures the same output, so a series resumed after a crash can be compared with an
uninterrupted one sample for sample. Exit status 2 with one line on stderr for bad input.

``--model OUT.json`` writes the stage's data-sheet model instead and exits: K / (M s^2 + B s)
per axis with the catalogue's moving mass and damping (``DATASHEET``: the carriage without
the payload, 20 % light, and 15 % less damping), the linear part a user knows before any
experiment, a little wrong as data sheets are.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
# data-sheet values relative to the stage's: moving mass, viscous damping
DATASHEET = {"M": 0.8, "B": 0.85}


def _stage(config: Path):
    from primlib.plant import Machine

    return Machine.from_json(config)


def _datasheet(stage):
    from primlib.plant import Machine

    plants = {
        a: ([p["K"] / stage.length_unit], [p["M"] * DATASHEET["M"], p["B"] * DATASHEET["B"], 0.0])
        for a, p in stage.motors.items()
    }
    return Machine(stage.name, stage.dt, stage.axes, plants)


def _parse(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("input", nargs="?", type=Path)
    p.add_argument("output", nargs="?", type=Path)
    p.add_argument("--start", help="absolute start position, mm: X,Y")
    p.add_argument("--noise", type=float, default=0.01, help="noise sigma, mm (default 0.01)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--config", type=Path, default=HERE / "stage.json")
    p.add_argument("--model", type=Path, help="write the nominal linear model JSON and exit")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    from primlib import PrimlibError
    from primlib.io import read_signal_csv, write_path_csv

    try:
        stage = _stage(args.config)
        if args.model is not None:
            _datasheet(stage).to_json(args.model)
            return 0
        if args.input is None or args.output is None or args.start is None:
            raise ValueError("expected --start X,Y INPUT OUTPUT")
        start = np.array([float(v) for v in args.start.split(",")])
        if start.shape != (stage.dim,):
            raise ValueError(f"--start: expected {stage.dim} coordinates, got {args.start!r}")
        t, u = read_signal_csv(args.input)
        if abs((t[1] - t[0]) - stage.dt) > 1e-9:
            raise ValueError(f"{args.input}: expected dt = {stage.dt} s, got {t[1] - t[0]:.9g}")
        y = stage.simulate(u, start=start) + start
        digest = hashlib.sha256(np.ascontiguousarray(u).tobytes()).digest()
        rng = np.random.default_rng([args.seed, *digest[:8]])
        y = y + args.noise * rng.standard_normal(y.shape)
        write_path_csv(args.output, t, y)
    except (PrimlibError, ValueError, OSError) as exc:
        print(f"stage: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
