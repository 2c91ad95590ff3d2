"""Path and uniform-table CSV files: round trips and one-sentence errors naming file and line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from primlib import InputError
from primlib.io import (
    read_path_csv,
    read_path_json,
    read_uniform_table,
    write_path_csv,
    write_path_json,
    write_table,
)

HEADERS = [("t", "x", "y"), ("t", "x", "y", "z")]


def _rows(n=10, dt=0.1, broken=None):
    """CSV body lines t,x,y; ``broken`` maps a row index to a replacement line."""
    lines = [f"{i * dt!r},{i},{2 * i}" for i in range(n)]
    for i, line in (broken or {}).items():
        lines[i] = line
    return lines


def _write(tmp_path, text, name="p.csv"):
    f = tmp_path / name
    f.write_text(text)
    return f


@pytest.mark.parametrize("d", [2, 3])
def test_path_csv_round_trip_is_bit_exact(tmp_path, d):
    rng = np.random.default_rng(0)
    t = np.arange(50) * 0.001
    points = rng.normal(size=(50, d)) * 1e3
    f = tmp_path / "p.csv"
    write_path_csv(f, t, points)
    assert f.read_text().splitlines()[0] == ("t,x,y" if d == 2 else "t,x,y,z")
    t2, p2 = read_path_csv(f)
    assert t2.dtype == np.float64 and p2.dtype == np.float64
    np.testing.assert_array_equal(t2, t)
    np.testing.assert_array_equal(p2, points)


def test_header_tolerates_blanks_case_bom_and_trailing_blank_lines(tmp_path):
    f = tmp_path / "p.csv"
    f.write_bytes(("\ufeff T , X ,y\n" + "\n".join(_rows()) + "\n\n\n").encode("utf-8"))
    t, xy = read_uniform_table(f, HEADERS, "path")
    assert t.shape == (10,) and xy.shape == (10, 2)
    np.testing.assert_allclose(xy[:, 1], 2 * np.arange(10))


def test_missing_file(tmp_path):
    with pytest.raises(InputError, match=r"nope\.csv: no such path file"):
        read_path_csv(tmp_path / "nope.csv")


def test_empty_file(tmp_path):
    f = _write(tmp_path, "\n  \n")
    with pytest.raises(InputError, match=r"p\.csv: expected a path CSV table, got an empty file"):
        read_path_csv(f)


def test_binary_file(tmp_path):
    f = tmp_path / "p.csv"
    f.write_bytes(b"\xff\xfe\x00\x81binary")
    with pytest.raises(InputError, match=r"p\.csv: expected a path CSV text file, got binary"):
        read_path_csv(f)


@pytest.mark.parametrize("header", ["t,x", "t,ux,uy", "x,y,t", "t,x,y,z,w", "time,x,y"])
def test_wrong_header_says_expected_and_got(tmp_path, header):
    f = _write(tmp_path, header + "\n" + "\n".join(_rows()) + "\n")
    with pytest.raises(
        InputError, match=rf"p\.csv: expected path header t,x,y or t,x,y,z, got {header}$"
    ):
        read_path_csv(f)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("0.4,4", "expected 3 columns, got 2"),
        ("0.4,4,8,9", "expected 3 columns, got 4"),
        ("0.4,abc,8", "expected a number in column 2, got 'abc'"),
        ("0.4,,8", "expected a number in column 2, got ''"),
        ("", "expected 3 numbers, got an empty line"),
        ("0.4,nan,8", r"expected a finite number in column 2 \(x\), got nan"),
        ("0.4,4,-inf", r"expected a finite number in column 3 \(y\), got -inf"),
    ],
)
def test_bad_row_names_the_line(tmp_path, line, message):
    # row index 4 is the 6th line of the file (header is line 1)
    f = _write(tmp_path, "t,x,y\n" + "\n".join(_rows(broken={4: line})) + "\n")
    with pytest.raises(InputError, match=rf"p\.csv, line 6: {message}"):
        read_path_csv(f)


def test_too_few_rows(tmp_path):
    f = _write(tmp_path, "t,x,y\n" + "\n".join(_rows(n=7)) + "\n")
    with pytest.raises(InputError, match=r"p\.csv: expected at least 8 path rows, got 7"):
        read_path_csv(f)


def test_header_only(tmp_path):
    f = _write(tmp_path, "t,x,y\n")
    with pytest.raises(InputError, match=r"expected at least 8 path rows, got 0"):
        read_path_csv(f)


def test_t_must_start_at_zero(tmp_path):
    lines = [f"{1 + 0.1 * i!r},{i},{i}" for i in range(10)]
    f = _write(tmp_path, "t,x,y\n" + "\n".join(lines))
    with pytest.raises(InputError, match=r"p\.csv, line 2: expected t to start at 0, got t = 1\.0"):
        read_path_csv(f)


@pytest.mark.parametrize("bad_t", ["0.3", "0.2"])
def test_t_must_increase(tmp_path, bad_t):
    f = _write(tmp_path, "t,x,y\n" + "\n".join(_rows(broken={4: f"{bad_t},4,8"})))
    with pytest.raises(InputError, match=r"p\.csv, line 6: expected t increasing, got t = 0\.[23]"):
        read_path_csv(f)


def test_t_must_be_uniform(tmp_path):
    f = _write(tmp_path, "t,x,y\n" + "\n".join(_rows(broken={4: "0.41,4,8"})))
    with pytest.raises(
        InputError, match=r"p\.csv, line 6: expected uniformly spaced t \(step 0\.1"
    ):
        read_path_csv(f)


def test_uniformity_tolerance_is_relative_to_dt(tmp_path):
    # 1e-7 dt of jitter passes (T_RTOL = 1e-6), 1e-5 dt does not
    dt = 0.004
    base = np.arange(20) * dt
    for jitter, ok in [(1e-7, True), (1e-5, False)]:
        t = base.copy()
        t[7] += jitter * dt
        f = tmp_path / f"j{jitter}.csv"
        f.write_text("t,x,y\n" + "\n".join(f"{float(ti)!r},0,0" for ti in t))
        if ok:
            read_path_csv(f)
        else:
            with pytest.raises(InputError, match="line 9: expected uniformly spaced t"):
                read_path_csv(f)


def test_large_file_parses(tmp_path):
    n = 20_000
    t = np.arange(n) * 0.0005
    v = np.random.default_rng(0).normal(size=(n, 3))
    write_path_csv(tmp_path / "big.csv", t, v)
    t2, v2 = read_path_csv(tmp_path / "big.csv")
    np.testing.assert_array_equal(v2, v)
    np.testing.assert_array_equal(t2, t)


def test_write_table_rejects_bad_shapes_and_values(tmp_path):
    f = tmp_path / "s.csv"
    with pytest.raises(InputError, match=r"s\.csv: expected t of shape \(n,\) and values"):
        write_table(f, ["t", "ux"], np.arange(3.0), np.zeros((4, 1)))
    with pytest.raises(InputError, match=r"s\.csv: expected a header of 3 names, got t,ux"):
        write_table(f, ["t", "ux"], np.arange(3.0), np.zeros((3, 2)))
    with pytest.raises(InputError, match=r"s\.csv: expected finite values to write"):
        write_table(f, ["t", "ux"], np.arange(3.0), np.array([[0.0], [np.nan], [1.0]]))
    assert not f.exists()
    with pytest.raises(InputError, match=r"p\.csv: expected path points of shape \(n, 2\)"):
        write_path_csv(tmp_path / "p.csv", np.arange(3.0), np.zeros((3, 4)))


def test_write_is_atomic_and_replaces(tmp_path):
    f = tmp_path / "p.csv"
    write_path_csv(f, np.arange(8.0), np.zeros((8, 2)))
    write_path_csv(f, np.arange(9.0), np.ones((9, 3)))
    t, p = read_path_csv(f)
    assert p.shape == (9, 3)
    assert [x.name for x in tmp_path.iterdir()] == ["p.csv"]  # no temporary left behind


def test_path_json_round_trip_and_errors(tmp_path):
    f = tmp_path / "c.json"
    write_path_json(f, {"a": [1.5, 2]})
    assert read_path_json(f) == {"a": [1.5, 2]}
    assert json.loads(f.read_text()) == {"a": [1.5, 2]}
    with pytest.raises(InputError, match=r"none\.json: no such path JSON file"):
        read_path_json(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"shape":\n  [1, 2,,]}')
    with pytest.raises(InputError, match=r"bad\.json, line 2: expected JSON, got expecting value"):
        read_path_json(bad)
