"""Library (DuckDB) benchmark: batch ingest, loading a machine's bank, one signal by id.

    python benchmarks/bench_store.py [--k 1000] [--n 2400] [--repeat 3]

Figures (goals from issue 2), each beside a baseline measured in the same run:

* ingest k = 1,000 primitives (3 axes, n = 2,400 samples) into a FILE library through
  ``Store.add_many`` in one batch (checks, ``sample_many`` of the paths on the machine
  grid, one Arrow list per big column, one INSERT, commit -- which for a batch this big
  includes DuckDB's checkpoint into the file): goal <= 1 s. The close that follows is a line
  of its own, and the sum too. Baselines, same run: the previous data path (each path's
  ``Trajectory.sample``, one Arrow chunk per primitive, DuckDB's default threads, the batch
  through the WAL, written again by the checkpoint at close), and ``executemany`` of the
  same rows (parameters prepared as Python lists beforehand) on a subset, scaled to k.
  The sampling alone: ``sample_many`` against a ``Trajectory.sample`` loop, and their
  largest difference (must be <= 1e-12 of the largest coordinate).
* loading the bank back (``Store.bank``: one columnar query to Arrow to flat numpy) from a
  freshly opened file: goal <= 0.2 s. The bank holds the points matching reads; its signals
  come with a second query on first use, timed as well. Baseline: a row loop, one indexed
  query per primitive.
* one signal by id (``Store.signal``, a unique-index lookup), median: goal <= 2 ms.
  Baseline: the same query on a copy of the table without the index.

The trajectories are built with ``Trajectory.from_definition`` from a few distinct curves,
so the benchmark times the store, not the fitting. Each fast path is checked to return what
its baseline returns.
"""

from __future__ import annotations

import os

if __name__ == "__main__":  # timed single-threaded; a test importing this keeps its threads
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import resource  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import duckdb  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout too

from primlib.nurbs import Trajectory, sample_many  # noqa: E402
from primlib.plant import Machine  # noqa: E402
from primlib.store import Store  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
MACHINE = ROOT / "data" / "machines" / "xyz.json"


def tic() -> np.ndarray:
    """Wall-clock and process CPU time now (CPU time includes DuckDB's threads)."""
    return np.array([time.perf_counter(), time.process_time()])


def toc(t0: np.ndarray) -> np.ndarray:
    """Elapsed (wall, cpu) seconds since ``t0``."""
    return tic() - t0


def make_items(k: int, n: int, dt: float, distinct: int = 5, seed: int = 0):
    """k (trajectory, u, name, source) items: fresh Trajectory objects over a few curves."""
    rng = np.random.default_rng(seed)
    duration = (n - 1) * dt
    p, m = 3, 24
    knots = np.concatenate([np.zeros(p + 1), np.linspace(0, 1, m - p + 1)[1:-1], np.ones(p + 1)])
    defs = [
        (knots, rng.uniform(-100, 100, (m, 3)), rng.uniform(0.5, 2, m)) for _ in range(distinct)
    ]
    t = np.arange(n) * dt
    base = np.stack([np.sin(2 * np.pi * t / duration * (j + 1)) for j in range(3)], axis=1)
    items = []
    for i in range(k):
        kn, ctrl, w = defs[i % distinct]
        traj = Trajectory.from_definition(p, kn, ctrl, w, duration)
        u = base * (1 + i / k) + 1e-3 * rng.standard_normal((n, 3))
        items.append((traj, u, f"prim-{i}", "bench"))
    return items


def fresh_library(folder: Path, name: str, machine: Machine) -> Path:
    db = folder / name
    with Store(db) as lib:
        lib.add_machine(machine)
    return db


def legacy_ingest(db: Path, items, machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """Baseline: the previous add_many's data path on the same rows.

    Each path sampled by its own ``Trajectory.sample``, one Arrow chunk per primitive for
    the big columns, DuckDB's default threads, the batch through the WAL and written again
    by the checkpoint at close. Returns (insert + commit, close) as (wall, cpu) each.
    """
    import pyarrow as pa

    def chunks(arrays):
        return pa.chunked_array(
            [
                pa.LargeListArray.from_arrays(
                    pa.array(np.array([0, a.size], dtype=np.int64)), pa.array(a.ravel())
                )
                for a in arrays
            ],
            type=pa.large_list(pa.float64()),
        )

    def flat(arrays):
        arrays = [np.asarray(a, dtype=np.float64).ravel() for a in arrays]
        off = np.concatenate([[0], np.cumsum([a.size for a in arrays])]).astype(np.int64)
        return pa.LargeListArray.from_arrays(pa.array(off), pa.array(np.concatenate(arrays)))

    con = duckdb.connect(str(db))
    k, dt = len(items), machine.dt
    t0 = tic()
    points = chunks([traj.sample(dt) for traj, *_ in items])
    signals = chunks([u for _, u, *_ in items])
    defs = [traj.definition() for traj, *_ in items]
    table = pa.table(
        {
            "id": pa.array(np.arange(1, k + 1)),
            "machine": pa.array([machine.name] * k),
            "name": pa.array([it[2] for it in items]),
            "source": pa.array([it[3] for it in items]),
            "duration": pa.array([traj.duration for traj, *_ in items]),
            "dt": pa.array(np.full(k, dt)),
            "dim": pa.array(np.full(k, 3, dtype=np.int32)),
            "n_samples": pa.array(np.array([len(it[1]) for it in items], dtype=np.int32)),
            "degree": pa.array(np.array([d["degree"] for d in defs], dtype=np.int32)),
            "knots": flat([d["knots"] for d in defs]),
            "ctrlpts": flat([d["ctrlpts"] for d in defs]),
            "weights": flat([d["weights"] for d in defs]),
            "points": points,
            "signal": signals,
        }
    )
    con.begin()
    con.register("batch", table)
    con.execute(
        "INSERT INTO primitives (id, machine, name, source, added, duration, dt, dim, "
        "n_samples, degree, knots, ctrlpts, weights, points, signal, content_hash) "
        "SELECT id, machine, name, source, now()::TIMESTAMP, duration, "
        "dt, dim, n_samples, degree, knots, ctrlpts, weights, points, signal, "
        "NULL FROM batch"  # no content hash: the data path before duplicates were detected
    )
    con.commit()
    insert = toc(t0)
    t0 = tic()
    con.close()
    return insert, toc(t0)


def bench_ingest(folder: Path, k: int, n: int, machine: Machine, repeat: int):
    """add_many (and close) against the legacy data path, interleaved; and the sampling."""
    times, closes, sampling, batched, legacy, legacy_close = [], [], [], [], [], []
    for r in range(repeat):
        # fresh Trajectory objects each time: none has its splines cached yet
        fresh = make_items(k, n, machine.dt)
        t0 = tic()
        ref = np.concatenate([traj.sample(machine.dt) for traj, *_ in fresh])
        sampling.append(toc(t0))
        fresh = make_items(k, n, machine.dt)
        t0 = tic()
        got, _ = sample_many([traj for traj, *_ in fresh], machine.dt)
        batched.append(toc(t0))
        rel = np.abs(got - ref).max() / np.abs(ref).max()
        assert rel <= 1e-12, rel

        old_db = fresh_library(folder, f"legacy{r}.duckdb", machine)
        insert, close = legacy_ingest(old_db, make_items(k, n, machine.dt), machine)
        legacy.append(insert)
        legacy_close.append(close)
        if r < repeat - 1:
            old_db.unlink()

        items = make_items(k, n, machine.dt)
        db = fresh_library(folder, f"ingest{r}.duckdb", machine)
        lib = Store(db)
        t0 = tic()
        ids = lib.add_many(items, machine.name)
        times.append(toc(t0))
        t0 = tic()
        lib.close()  # a checkpoint of what is left in the WAL (nothing after a big batch)
        closes.append(toc(t0))
        assert len(ids) == len(items)
        if r < repeat - 1:
            db.unlink()
    med = [np.median(x, axis=0) for x in (times, closes, sampling, batched, legacy, legacy_close)]
    return (db, old_db, *med, rel)


def bench_executemany(folder: Path, items, machine: Machine, subset: int):
    """Baseline: executemany of the same rows into the same table, on a subset."""
    db = fresh_library(folder, "executemany.duckdb", machine)
    dt = machine.dt
    rows = []
    for i, (traj, u, name, source) in enumerate(items[:subset]):
        d = traj.definition()
        rows.append(
            [
                i + 1,
                machine.name,
                name,
                source,
                traj.duration,
                dt,
                3,
                len(u),
                d["degree"],
                d["knots"].tolist(),
                d["ctrlpts"].ravel().tolist(),
                d["weights"].tolist(),
                traj.sample(dt).ravel().tolist(),
                u.ravel().tolist(),
            ]
        )
    con = duckdb.connect(str(db))
    con.begin()
    t0 = tic()
    con.executemany(
        "INSERT INTO primitives (id, machine, name, source, added, duration, dt, dim, "
        "n_samples, degree, knots, ctrlpts, weights, points, signal, content_hash) VALUES "
        "(?, ?, ?, ?, now()::TIMESTAMP, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, NULL)",
        rows,
    )
    con.commit()
    elapsed = toc(t0)
    con.close()
    return db, elapsed


def _row(con, column: str, pid: int) -> np.ndarray:
    table = con.sql(
        f"SELECT {column} FROM primitives WHERE id = $id", params={"id": pid}
    ).to_arrow_table()
    return table.column(0).combine_chunks().flatten().to_numpy().reshape(-1, 3)


def usage() -> np.ndarray:
    """Minor page faults, user and system CPU seconds of this process so far."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return np.array([r.ru_minflt, r.ru_utime, r.ru_stime])


def bench_bank(db: Path, machine: str, repeat: int):
    """Bank points (what matching reads) and then its signals, each from a fresh open; and
    where the fresh read's time goes: its minor page faults, user and system CPU (medians),
    beside the same read again on the connection still open (``again``: wall, faults, user,
    system)."""
    points_t, signals_t, fresh_use, again = [], [], [], []
    for _ in range(repeat):
        with Store(db, read_only=True) as lib:  # fresh open: DuckDB's cache is cold
            t0, u0 = tic(), usage()
            bank = lib.bank(machine)
            points_t.append(toc(t0))
            fresh_use.append(usage() - u0)
            t0 = tic()
            signals = bank.signals
            signals_t.append(toc(t0))
            lib._bank_cache.clear()  # read again: DuckDB's blocks now in its buffer pool
            t0, u0 = tic(), usage()
            lib.bank(machine)
            again.append(np.concatenate([toc(t0)[:1], usage() - u0]))
    # Baseline: a row loop, one indexed query per primitive and column.
    with Store(db, read_only=True) as lib:
        con = lib._con
        t0 = tic()
        points_loop = [_row(con, "points", int(i)) for i in bank.ids]
        loop_points = toc(t0)
        t0 = tic()
        signals_loop = [_row(con, "signal", int(i)) for i in bank.ids]
        loop_signals = toc(t0)
    np.testing.assert_array_equal(bank.points, np.concatenate(points_loop))
    np.testing.assert_array_equal(signals, np.concatenate(signals_loop))
    return (
        bank,
        signals,
        np.median(points_t, axis=0),
        np.median(signals_t, axis=0),
        loop_points,
        loop_signals,
        (np.median(fresh_use, axis=0), np.median(again, axis=0)),
    )


def bench_signal(db: Path, folder: Path, ids: np.ndarray, lookups: int):
    rng = np.random.default_rng(1)
    pick = rng.choice(ids, lookups)
    times = []
    with Store(db, read_only=True) as lib:
        lib.signal(int(pick[0]))  # warm the connection
        for i in pick:
            t0 = tic()
            lib.signal(int(i))
            times.append(toc(t0))
        check = {int(i): lib.signal(int(i)) for i in pick[:20]}
    # Baseline: the same table and query without the unique index (a copy made by CTAS).
    plain = folder / "noindex.duckdb"
    shutil.copy(db, plain)
    con = duckdb.connect(str(plain))
    con.execute("CREATE TABLE plain AS SELECT id, dim, signal FROM primitives")
    con.execute("DROP TABLE primitives")
    con.execute("CHECKPOINT")
    base = []
    for i in pick[: max(20, lookups // 10)]:
        t0 = tic()
        table = con.sql(
            "SELECT dim, signal FROM plain WHERE id = $id", params={"id": int(i)}
        ).to_arrow_table()
        u = table.column("signal").combine_chunks().flatten().to_numpy().reshape(-1, 3)
        base.append(toc(t0))
        if int(i) in check:
            np.testing.assert_array_equal(u, check[int(i)])
    con.close()
    return np.median(times, axis=0), np.median(base, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=int, default=1000, help="primitives (default 1000)")
    ap.add_argument("--n", type=int, default=2400, help="samples per primitive (default 2400)")
    ap.add_argument("--repeat", type=int, default=3, help="repetitions for medians (default 3)")
    ap.add_argument("--subset", type=int, default=40, help="rows for the executemany baseline")
    args = ap.parse_args()

    machine = Machine.from_json(MACHINE)
    items = make_items(args.k, args.n, machine.dt)
    mb = 2 * args.k * args.n * 3 * 8 / 1e6
    print(f"primlib store benchmark: {args.k} primitives x {args.n} samples x 3 axes ")
    print(f"({mb:.0f} MB of points + signals), duckdb {duckdb.__version__}, medians")
    print(f"load average now: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs\n")

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (db, old_db, ingest, close, sampling, batched, legacy, legacy_close, rel) = bench_ingest(
            folder, args.k, args.n, machine, args.repeat
        )
        base_db, base_sub = bench_executemany(folder, items, machine, args.subset)
        base = base_sub * args.k / args.subset
        # same rows, same table: what the fast path stored equals what the baselines stored
        scale = np.abs(items[0][0].ctrlpts).max()
        with (
            Store(db, read_only=True) as fast,
            Store(base_db, read_only=True) as slow,
            Store(old_db, read_only=True) as old,
        ):
            for i in range(1, args.subset + 1, max(1, args.subset // 8)):
                np.testing.assert_array_equal(fast.signal(i), slow.signal(i))
                np.testing.assert_array_equal(fast.signal(i), old.signal(i))
                for other in (slow, old):
                    np.testing.assert_allclose(
                        fast.get(i).points, other.get(i).points, rtol=0, atol=1e-12 * scale
                    )

        bank, signals, load, load_signals, loop, loop_signals, faults = bench_bank(
            db, machine.name, args.repeat
        )
        np.testing.assert_array_equal(signals[: args.n], items[0][1])

        one, one_base = bench_signal(db, folder, bank.ids, 200)
        size = db.stat().st_size / 1e6

    rows_out = [
        (
            f"ingest {args.k:,} primitives (add_many, commit)",
            ingest,
            1.0,
            legacy,
            "previous data path (sample loop, chunks, WAL)",
        ),
        (
            "  the same, plus close (checkpoint)",
            ingest + close,
            1.0,
            legacy + legacy_close,
            "previous data path plus its close",
        ),
        ("  the same, add_many alone", ingest, 1.0, base, "executemany, scaled"),
        (
            f"  of which: sample {args.k:,} paths (sample_many)",
            batched,
            np.inf,
            sampling,
            "Trajectory.sample loop",
        ),
        ("bank for matching (points), fresh open", load, 0.2, loop, "row loop, points"),
        (
            "bank points + signals (signals on first use)",
            load + load_signals,
            np.inf,
            loop + loop_signals,
            "row loop, both",
        ),
        ("one signal by id", one, 0.002, one_base, "same query, no index"),
    ]

    def fmt(x: float) -> str:
        return f"{x * 1e3:.2f} ms" if x < 0.1 else f"{x:.3f} s"

    w = max(len(r[0]) for r in rows_out)
    print(
        f"{'figure':<{w}}  {'wall':>9}  {'cpu':>9}  {'goal':>6}  {'baseline':>9}  "
        f"{'ratio':>6}  {'cpu ratio':>9}  baseline is"
    )
    for label, value, goal, baseline, what in rows_out:
        if np.isinf(goal):
            g = "-"
        else:
            g = f"{goal * 1e3:g} ms" if goal < 0.1 else f"{goal:g} s"
        ok = "" if value[0] <= goal else "  (wall over goal)"
        print(
            f"{label:<{w}}  {fmt(value[0]):>9}  {fmt(value[1]):>9}  {g:>6}  {fmt(baseline[0]):>9}  "
            f"{baseline[0] / value[0]:>5.1f}x  {baseline[1] / value[1]:>8.1f}x  {what}{ok}"
        )
    print(f"\nsample_many vs Trajectory.sample: max difference {rel:.1e} of the largest coordinate")
    print(
        f"close after the ingest: {close[0]:.3f} s wall (previous path: {legacy_close[0]:.3f} s, "
        "the WAL checkpointed into the file)"
    )
    rate = mb / (load[0] + load_signals[0])
    print(
        f"file size: {size:.0f} MB; ingest {mb / ingest[0]:.0f} MB/s, bank {rate:.0f} MB/s (wall)"
    )
    (flt, user, system), (again, flt2, user2, system2) = faults
    page = resource.getpagesize()
    print(
        f"bank read, fresh open: {flt:,.0f} minor page faults ({flt * page / 1e6:.0f} MB first "
        f"touched; the points are {bank.points.nbytes / 1e6:.0f} MB), CPU {user:.3f} s user + "
        f"{system:.3f} s system; again on the open connection: {fmt(again)} wall, "
        f"{flt2:,.0f} faults, {user2:.3f} s user + {system2:.3f} s system"
    )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    print("cpu = process CPU time (all threads): what the work costs when the machine is shared")


if __name__ == "__main__":
    main()
