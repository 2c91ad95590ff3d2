"""Should the matcher's index live in the library file? Reading it against rebuilding it.

What a process builds before its first match, per machine: the arc-length index
(:class:`primlib.match.BankIndex` ``arc_index()``: every primitive resampled at uniform arc
length, a pyramid of levels) and the per-primitive envelopes of the up-front rejection
(``envelope()``). Persisted, it would be one table of list columns (the layout the store
uses for points: Arrow list columns over flat numpy buffers, read back zero-copy), written
when the machine's primitives change. This module times, on the same bank:

* ``build``: a fresh ``BankIndex``, ``arc_index()`` and ``envelope()`` (median of runs,
  each followed by a read);
* ``read``: a fresh DuckDB connection, the stored arrays read back as numpy arrays, on a
  file written by the same run (median of runs), without even the validation a real
  store would add (that the stored index belongs to the stored primitives).

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

__all__ = ["index_arrays", "write_index", "read_index", "compare", "build_seconds"]


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
        out[f"garc{j}"] = lv.garc
        out[f"left{j}"] = lv.left
    return out


def write_index(db: Path, arrays: dict[str, np.ndarray]) -> int:
    """One row per array (name, values as a DOUBLE list column); bytes written."""
    names = list(arrays)
    values = [np.ascontiguousarray(arrays[k], dtype=float) for k in names]
    offsets = np.concatenate([[0], np.cumsum([v.size for v in values])]).astype(np.int64)
    flat = np.concatenate(values)
    table = pa.table(
        {
            "name": pa.array(names),
            "vals": pa.LargeListArray.from_arrays(pa.array(offsets), pa.array(flat)),
        }
    )
    con = duckdb.connect(str(db))
    con.execute("CREATE OR REPLACE TABLE match_index (name VARCHAR, vals DOUBLE[])")
    con.register("t", table)
    con.execute("INSERT INTO match_index SELECT name, vals FROM t")
    con.close()
    return int(flat.nbytes)


def read_index(db: Path) -> dict[str, np.ndarray]:
    """The arrays back from a fresh read-only connection, as float64 numpy."""
    con = duckdb.connect(str(db), read_only=True)
    table = con.sql("SELECT name, vals FROM match_index").to_arrow_table()
    con.close()
    names = table.column("name").to_pylist()
    col = table.column("vals").combine_chunks()
    flat = col.flatten().to_numpy(zero_copy_only=False)
    offsets = col.offsets.to_numpy()
    return {n: flat[offsets[i] : offsets[i + 1]] for i, n in enumerate(names)}


def compare(bank, db: Path, repeat: int = 5) -> dict[str, float]:
    """Median seconds to build the index of ``bank`` and to read it back from ``db``,
    each build followed by a read (interleaved, so a change of load on a shared machine
    falls on both alike)."""
    index = BankIndex(bank)
    nbytes = write_index(db, index_arrays(index))
    builds, reads = [], []
    arrays = back = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        index = BankIndex(bank)
        arrays = index_arrays(index)
        builds.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        back = read_index(db)
        reads.append(time.perf_counter() - t0)
    for k, v in arrays.items():
        np.testing.assert_array_equal(back[k], np.asarray(v, dtype=float).ravel(), err_msg=k)
    mb = nbytes / 2**20
    return {"build": statistics.median(builds), "read": statistics.median(reads), "mb": mb}


def build_seconds(repeat: int = 5, kind: str = "random-1000") -> float:
    """Median seconds to build the 1,000 random primitives' (``kind``: or the bundled
    library's) index and envelopes (a fresh
    ``BankIndex``, ``arc_index()``, ``envelope()``) with the primlib on ``sys.path``: run as
    ``python _index_persist.py --worker N`` under another revision's ``PYTHONPATH``, the
    same build there (``bench_match.py --index --baseline REV``)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_match_novel import _library

    bank, _ = _library(kind)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        index = BankIndex(bank)
        index.arc_index()
        index.envelope()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


if __name__ == "__main__":
    import json
    import sys

    if len(sys.argv) == 3 and sys.argv[1] == "--worker":
        print(json.dumps(build_seconds(int(sys.argv[2]))))
