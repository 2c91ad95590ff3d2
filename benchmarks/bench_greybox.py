"""Benchmark of fitting a machine's models (the grey-box model and the linear model refined
beside it): what the first warm start on a machine, ``primlib machine fit`` and a server's
refit at a checkpoint wait for, this tree against a baseline revision in the same run.

The library: by default loops learned by ILC on the example stage (Coulomb/Stribeck friction
and a force ripple at absolute positions, ``examples/stage``; ``bench_kept.py``'s), or
``--db FILE --machine NAME`` (e.g. a library of ``bench_realism.py --save-libraries``). Each
tree runs in a fresh single-threaded process of its own (:mod:`_revisions`), alternated round
by round, on a copy of the file without kept models.

Printed per tree: ``fit_greybox`` on all the machine's stored pairs (linear terms and not,
the two fits a warm start makes) and ``machine fit``'s whole job (both, the refit through a
simulation of the machine, the refined linear model), median and worst over the rounds, and
this tree's time over the baseline's; then how the models differ between the trees (ripple
frequency, coefficients, cross-validated errors, relative; and whether the same terms are
kept).

Run: ``python benchmarks/bench_greybox.py [--primitives 14] [--samples 1001] [--rounds 3]
[--baseline 95dd56c]``, ``python benchmarks/bench_greybox.py --db lib.duckdb --machine xyz``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _revisions import alternated, run_worker, without_kept

ROOT = Path(__file__).resolve().parents[1]
BASELINE = "95dd56c"  # main before the folds' ripple searches shared one pass (stop 47)


def worker(spec: dict) -> dict:
    """Time the fits with the primlib importable here; JSON-able results."""
    import primlib
    from primlib.greybox import fit_greybox
    from primlib.pipeline import Library
    from primlib.pipeline._greywarm import bank_pairs

    db = Path(spec["folder"]) / f"run-{time.time_ns()}.duckdb"
    without_kept(spec["db"], db)
    out: dict = {"primlib": primlib.__file__, "models": {}}
    with Library(db) as lib:
        machine, bank = lib.machine(spec["machine"]), lib.bank(spec["machine"])
        pairs = bank_pairs(bank)
        t0 = time.perf_counter()
        for linear in (True, False):
            gb = fit_greybox(machine, pairs, linear=linear)
            out["models"][str(linear)] = {
                "w": gb.w.tolist(),
                "coef": gb.coef.tolist(),
                "cv": gb.cv_rms.tolist(),
            }
        out["greybox"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        lib.starter.fit_models(spec["machine"])
        out["fit"] = time.perf_counter() - t0
    db.unlink()
    return out


def _differ(a: dict, b: dict) -> str:
    """How the models of two runs differ: the largest relative difference of each figure,
    and whether the same coefficients are nonzero (the same terms kept)."""
    parts, same = [], True
    for key in ("w", "coef", "cv"):
        worst = 0.0
        for linear in a:
            x, y = np.asarray(a[linear][key]), np.asarray(b[linear][key])
            same &= key != "coef" or bool(np.array_equal(x != 0, y != 0))
            scale = np.maximum(np.abs(x), 1e-300)
            worst = max(worst, float(np.max(np.abs(x - y) / scale, initial=0.0)))
        parts.append(f"{key} {worst:.1e}")
    return ", ".join(parts) + ("; the same terms kept" if same else "; OTHER TERMS KEPT")


def _row(label: str, mine: list[float], theirs: list[float] | None) -> str:
    text = f"{label:<44} {statistics.median(mine):8.2f} s ({max(mine):.2f})"
    if theirs:
        ratio = statistics.median(theirs) / statistics.median(mine)
        text += f"   {statistics.median(theirs):8.2f} s ({max(theirs):.2f})   {ratio:.2f}x faster"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--db", type=Path, help="a library file (default: build a stage library)")
    ap.add_argument("--machine", default="stage", help="its machine (with --db)")
    ap.add_argument("--primitives", type=int, default=14, help="stage library: loops")
    ap.add_argument("--samples", type=int, default=1001, help="stage library: samples each")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--baseline", default=BASELINE, help="revision to compare with")
    ap.add_argument("--no-baseline", action="store_true")
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(worker(json.loads(args.worker))))
        return
    with tempfile.TemporaryDirectory(prefix="bench_greybox_") as folder:
        db, what = args.db, f"{args.db} (machine {args.machine})"
        if db is None:
            sys.path.insert(0, str(ROOT / "tests"))  # the stage's helpers
            from bench_kept import stage_library  # (it puts this checkout first on sys.path)

            db = stage_library(Path(folder), args.primitives, args.samples)[0]
            what = f"{args.primitives} loops of {args.samples} samples learned on the stage"
        print(f"library: {what}")
        job = json.dumps({"db": str(db), "machine": args.machine, "folder": folder})
        if args.no_baseline:
            res = {"this tree": [run_worker(__file__, job, ROOT) for _ in range(args.rounds)]}
        else:
            res = alternated(__file__, job, args.baseline, args.rounds)
    labels = list(res)
    base = None if len(labels) == 1 else res[labels[1]]
    head = f"{'median (worst) over ' + str(args.rounds) + ' rounds':<44} {'this tree':>20}"
    print(head + (f"   {labels[1]:>20}" if base else ""))
    for key, label in (("greybox", "fit_greybox, linear terms and not"),
                       ("fit", "machine fit (every model)")):  # fmt: skip
        mine = [r[key] for r in res["this tree"]]
        print(_row(label, mine, None if base is None else [r[key] for r in base]))
    if base is not None:
        print(f"models, this tree against {labels[1]}: "
              f"{_differ(res['this tree'][0]['models'], base[0]['models'])}")  # fmt: skip


if __name__ == "__main__":
    main()
