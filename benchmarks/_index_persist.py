"""Should the matcher's index live in the library file? Reading it against rebuilding it.

What a process builds before its first match, per machine: the arc-length index
(:class:`primlib.match.BankIndex` ``arc_index()``: every primitive resampled at uniform arc
length, a pyramid of levels) and the per-primitive envelopes of the up-front rejection
(``envelope()``). Persisted, it would be written when the machine's primitives change. This
module times, on the same bank:

* ``build``: a fresh ``BankIndex``, ``arc_index()`` and ``envelope()`` (median of runs,
  each followed by the reads);
* ``read`` in three layouts, each from a fresh read-only DuckDB connection on a file
  written by the same run, back as numpy arrays (medians), without even the validation a
  real store would add (that the stored index belongs to the stored primitives):

  - ``list``: one table, one row per array, its values a ``DOUBLE[]`` list (the layout
    the store uses for points: Arrow list columns over flat numpy buffers);
  - ``blob``: one row per array, its bytes one ``BLOB`` (``np.frombuffer`` on the
    bytes DuckDB returns);
  - ``column``: one table per array, its values one plain ``DOUBLE`` column, one row a
    value (DuckDB's own columnar layout; ``fetchnumpy``).

DuckDB reads each at a few hundred MB/s on this machine, the index is ~70 MB for 1,000
primitives of 2,000 samples: all three read back slower than the index is built.

Used by ``bench_match.py`` (a row of its table) and its smoke test.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import duckdb
import numpy as np
import pyarrow as pa

from primlib.match import BankIndex

__all__ = ["LAYOUTS", "index_arrays", "write_index", "read_index", "compare", "build_seconds"]

LAYOUTS = ("list", "blob", "column")


def index_arrays(index: BankIndex) -> dict[str, np.ndarray]:
    """Every array the first match builds on ``index``, flat, by name."""
    arc = index.arc_index()
    env = index.envelope()
    out: dict[str, np.ndarray] = {
        "x_all": arc.x_all,
        "garc_all": arc.garc_all,
        "steps": np.array([lv.step for lv in arc.levels]),
        "env_radius": env.radius,
        "env_half": env.half.ravel(),
        "env_radius_xy": env.radius_xy,
        "env_last": env.last,
    }
    for j, lv in enumerate(arc.levels):
        out[f"pts{j}"] = lv.pts.ravel()
        out[f"prim{j}"] = lv.prim.astype(float)
        out[f"x{j}"] = lv.x
    return out


def write_index(db: Path, arrays: dict[str, np.ndarray], layout: str = "list") -> int:
    """The arrays as float64 in ``db`` in one of :data:`LAYOUTS` (module notes); bytes
    written."""
    names = list(arrays)
    values = [np.ascontiguousarray(arrays[k], dtype=float).ravel() for k in names]
    con = duckdb.connect(str(db))
    if layout == "list":
        offsets = np.concatenate([[0], np.cumsum([v.size for v in values])]).astype(np.int64)
        flat = np.concatenate(values)
        table = pa.table(
            {
                "name": pa.array(names),
                "vals": pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(flat)),
            }
        )
        con.execute("CREATE OR REPLACE TABLE match_index (name VARCHAR, vals DOUBLE[])")
        con.register("t", table)
        con.execute("INSERT INTO match_index SELECT name, vals FROM t")
    elif layout == "blob":
        con.execute("CREATE OR REPLACE TABLE match_blobs (name VARCHAR, vals BLOB)")
        for name, v in zip(names, values, strict=True):
            con.execute("INSERT INTO match_blobs VALUES ($n, $v)", {"n": name, "v": v.tobytes()})
    else:
        for i, v in enumerate(values):
            con.register("t", pa.table({"v": pa.array(v)}))
            con.execute(f"CREATE OR REPLACE TABLE match_col_{i} AS SELECT v FROM t")
            con.unregister("t")
        con.execute("CREATE OR REPLACE TABLE match_cols (i INTEGER, name VARCHAR)")
        con.executemany("INSERT INTO match_cols VALUES (?, ?)", list(enumerate(names)))
    con.close()
    return int(sum(v.nbytes for v in values))


def read_index(db: Path, layout: str = "list") -> dict[str, np.ndarray]:
    """The arrays back from a fresh read-only connection, as float64 numpy."""
    con = duckdb.connect(str(db), read_only=True)
    if layout == "list":
        table = con.sql("SELECT name, vals FROM match_index").to_arrow_table()
        names = table.column("name").to_pylist()
        col = table.column("vals").combine_chunks()
        flat = col.flatten().to_numpy(zero_copy_only=False)
        offsets = col.offsets.to_numpy()
        out = {n: flat[offsets[i] : offsets[i + 1]] for i, n in enumerate(names)}
    elif layout == "blob":
        rows = con.execute("SELECT name, vals FROM match_blobs").fetchall()
        out = {n: np.frombuffer(b, dtype=np.float64) for n, b in rows}
    else:
        out = {
            n: con.sql(f"SELECT v FROM match_col_{i}").fetchnumpy()["v"]
            for i, n in con.execute("SELECT i, name FROM match_cols ORDER BY i").fetchall()
        }
    con.close()
    return out


def compare(bank, db: Path, repeat: int = 5) -> dict[str, float]:
    """Median seconds to build the index of ``bank`` and to read it back from ``db`` in
    each of :data:`LAYOUTS` (keys ``read_list``, ``read_blob``, ``read_column``; ``read``
    the fastest of them), each build followed by the reads (interleaved, so a change of
    load on a shared machine falls on all alike); asserts every array read back equals
    the built one."""
    index = BankIndex(bank)
    arrays = index_arrays(index)
    files = {lay: db.with_name(f"{db.stem}_{lay}{db.suffix}") for lay in LAYOUTS}
    nbytes = 0
    for lay, f in files.items():
        nbytes = write_index(f, arrays, lay)
    builds: list[float] = []
    reads: dict[str, list[float]] = {lay: [] for lay in LAYOUTS}
    back: dict[str, dict[str, np.ndarray]] = {}
    for _ in range(repeat):
        t0 = time.perf_counter()
        index = BankIndex(bank)
        arrays = index_arrays(index)
        builds.append(time.perf_counter() - t0)
        for lay, f in files.items():
            t0 = time.perf_counter()
            back[lay] = read_index(f, lay)
            reads[lay].append(time.perf_counter() - t0)
    for lay in LAYOUTS:
        for k, v in arrays.items():
            np.testing.assert_array_equal(
                back[lay][k], np.asarray(v, dtype=float).ravel(), err_msg=f"{lay}: {k}"
            )
    out = {"build": statistics.median(builds), "mb": nbytes / 2**20}
    out.update({f"read_{lay}": statistics.median(reads[lay]) for lay in LAYOUTS})
    out["read"] = min(out[f"read_{lay}"] for lay in LAYOUTS)
    return out


def build_seconds(repeat: int = 5, kind: str = "random-1000") -> dict[str, float]:
    """Median wall and CPU seconds (keys ``wall``, ``cpu``) to build the 1,000 random
    primitives' (``kind``: or the bundled library's) index and envelopes (a fresh
    ``BankIndex``, ``arc_index()``, ``envelope()``) with the primlib on ``sys.path``: run as
    ``python _index_persist.py --worker N`` under another revision's ``PYTHONPATH``, the
    same build there (``bench_match.py --index --baseline REV``)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_match_novel import _library

    bank, _ = _library(kind)
    walls, cpus = [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        index = BankIndex(bank)
        index.arc_index()
        index.envelope()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return {"wall": statistics.median(walls), "cpu": statistics.median(cpus)}


if __name__ == "__main__":
    import json
    import sys

    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        print(json.dumps(build_seconds(int(sys.argv[2]))))
