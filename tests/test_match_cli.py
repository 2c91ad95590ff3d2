"""``primlib match`` through CliRunner, read back through the library and the files."""

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from match_helpers import random_primitive
from scipy.spatial.transform import Rotation

from primlib.cli import main
from primlib.io import read_signal_csv, write_path_csv
from primlib.nurbs import Trajectory
from primlib.pipeline import Library
from primlib.plant import Machine, invert
from primlib.store import Store

ROOT = Path(__file__).resolve().parents[1]
EPS = 0.05


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """A library of 4 primitives (signals by model inversion) and a path of 2 pieces."""
    tmp = tmp_path_factory.mktemp("match")
    db = tmp / "lib.duckdb"
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    rng = np.random.default_rng(0)
    trajs = [random_primitive(rng, machine.dt) for _ in range(4)]
    with Store(db) as lib:
        lib.add_machine(machine)
        items = []
        for i, tr in enumerate(trajs):
            pts = tr.sample(machine.dt)
            items.append((tr, invert(machine, pts - pts[0]), f"prim-{i}", None))
        ids = lib.add_many(items, machine.name)
        empty = Machine.from_dict({**machine.to_dict(), "name": "empty"})
        lib.add_machine(empty)
    # path: piece of prim 1 (v 0.1-0.5, as stored) then prim 3 (v 0.3-0.8, 1.25x slower)
    dt = machine.dt
    parts, last = [], np.zeros(3)
    for row, v0, v1, n in ((1, 0.1, 0.5, 161), (3, 0.3, 0.8, 251)):
        pts = trajs[row].at(np.linspace(v0, v1, n))
        pts = pts @ Rotation.from_euler("zyx", [30 * row, 10, -20], degrees=True).as_matrix().T
        pts += last - pts[0]
        last = pts[-1]
        parts.append(pts if not parts else pts[1:])
    pts = np.concatenate(parts)
    csv = tmp / "new.csv"
    write_path_csv(csv, np.arange(len(pts)) * dt, pts)
    flat = tmp / "flat.csv"
    write_path_csv(flat, np.arange(len(pts)) * dt, pts[:, :2])
    return {"db": db, "csv": csv, "flat": flat, "ids": ids, "tmp": tmp, "n": len(pts)}


def _run(setup, *args):
    return CliRunner().invoke(main, ["--db", str(setup["db"]), "match", *map(str, args)])


def test_table_names_every_segment(setup):
    res = _run(setup, setup["csv"], "--machine", "xyz", "--eps", EPS)
    assert res.exit_code == 0, res.output
    out = res.output
    assert "2 segment(s), 0 unmatched" in out
    assert f"#{setup['ids'][1]} prim-1" in out and f"#{setup['ids'][3]} prim-3" in out
    for col in ("path v", "primitive v", "angle", "rmsd"):
        assert col in out


def test_json_reads_back_and_transforms_hold(setup):
    res = _run(setup, setup["csv"], "--machine", "xyz", "--eps", EPS, "--json")
    assert res.exit_code == 0, res.output
    d = json.loads(res.stdout)
    segs = d["segments"]
    assert [s["primitive"] for s in segs] == [setup["ids"][1], setup["ids"][3]]
    assert segs[0]["start"] == 0.0 and segs[-1]["end"] == 1.0
    # the longest prefix within eps may run a few samples past the join (a gentle corner)
    join = 160 / (setup["n"] - 1)
    assert join - 1.0 / setup["n"] <= segs[0]["end"] <= join + 0.02
    assert segs[1]["time_scale"] == pytest.approx(0.5 * 400 / 250, rel=1e-3)
    assert all(s["rmsd"] < EPS for s in segs)
    # each declared transform, checked through the stored trajectory and the CSV path
    with Store(setup["db"], read_only=True) as lib:
        path = Trajectory.from_csv(setup["csv"])
        for s in segs:
            prim = lib.get(s["primitive"]).trajectory
            u = np.linspace(0, 1, 300)
            a = path.at(s["start"] + (s["end"] - s["start"]) * u)
            b = prim.at(s["primitive_start"] + (s["primitive_end"] - s["primitive_start"]) * u)
            b = b @ np.array(s["rotation"]).T + np.array(s["translation"])
            # eps plus the NURBS fit tolerance of the CSV path (1e-4 of its extent)
            dev = np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))
            assert dev < EPS + 2e-4 * path.extent


def test_out_writes_the_warm_start_and_plot_a_figure(setup):
    out = setup["tmp"] / "u0.csv"
    fig = setup["tmp"] / "match.png"
    res = _run(setup, setup["csv"], "--machine", "xyz", "--eps", EPS, "--out", out, "--plot", fig)
    assert res.exit_code == 0, res.output
    t, u = read_signal_csv(out)
    assert u.shape == (setup["n"], 3)
    np.testing.assert_allclose(np.diff(t), 0.005, rtol=1e-9)
    with Library(setup["db"], read_only=True) as lib:
        ws = lib.warm_start(Trajectory.from_csv(setup["csv"]), machine="xyz", eps=EPS)
    np.testing.assert_allclose(u, ws.u, rtol=1e-9, atol=1e-12)
    assert fig.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("args", "msg"),
    [
        (["--eps", "0"], "--eps: expected a tolerance > 0, got 0"),
        (["--eps", "-1"], "--eps: expected a tolerance > 0, got -1"),
        (["--machine", "nope"], "nope"),
        (["--machine", "empty"], "no primitive"),
    ],
)
def test_bad_input_exits_2_with_one_line(setup, args, msg):
    base = ["--machine", "xyz"] if "--machine" not in args else []
    res = _run(setup, setup["csv"], *base, *args)
    assert res.exit_code == 2
    assert msg in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_dimension_mismatch_and_nothing_written(setup):
    out = setup["tmp"] / "never.csv"
    res = _run(setup, setup["flat"], "--machine", "xyz", "--out", out)
    assert res.exit_code == 2
    assert "expected a 3-D path" in res.output and "got 2-D" in res.output
    assert not out.exists()
    res2 = _run(setup, setup["csv"], "--machine", "xyz", "--out", setup["tmp"] / "no" / "u.csv")
    assert res2.exit_code == 2 and "does not exist" in res2.output


def test_library_match_api_and_its_errors(setup):
    from primlib import InputError, NoMatchError, NotFoundError
    from primlib.match import Match

    path = Trajectory.from_csv(setup["csv"])
    with Library(setup["db"], read_only=True) as lib:
        mt = lib.match(path, machine="xyz", eps=EPS)
        assert isinstance(mt, Match) and mt.machine == "xyz" and mt.eps == EPS
        assert mt.rotation_mode == "full" and mt.path is path
        json.dumps(mt.to_dict())  # plain JSON
        with pytest.raises(InputError, match="eps: expected a tolerance > 0"):
            lib.match(path, machine="xyz", eps=0.0)
        with pytest.raises(NotFoundError, match="nope"):
            lib.match(path, machine="nope", eps=EPS)
        with pytest.raises(NoMatchError, match="'empty': no primitive stored"):
            lib.match(path, machine="empty", eps=EPS)
        flat = Trajectory.from_csv(setup["flat"])
        with pytest.raises(InputError, match="expected 3-D like machine 'xyz', got 2-D"):
            lib.match(flat, machine="xyz", eps=EPS)
        with pytest.raises(InputError, match="rotation"):
            lib.match(path, machine="xyz", eps=EPS, rotation="spin")


def _probe(setup, name: str, points: np.ndarray):
    csv = setup["tmp"] / f"{name}.csv"
    write_path_csv(csv, np.arange(len(points)) * 0.005, points)
    return csv


def _base_points(setup) -> np.ndarray:
    from primlib.io import read_path_csv

    return read_path_csv(setup["csv"])[1]


@pytest.mark.parametrize(
    ("case", "msg"),
    [
        # the path reader's door: file, line and column of the first value out of range
        ("one_value_1e308", "line 12: expected a magnitude at most 1e+09"),
        ("all_values_x1e300", "expected a magnitude at most 1e+09"),
        ("all_values_x1e50", "expected a magnitude at most 1e+09"),
        ("constant", "expected a path that moves"),
    ],
)
def test_match_refuses_a_path_with_huge_values_or_no_extent_at_once(setup, case, msg):
    # issue 12: 1e308 gave 'cannot convert float NaN to integer', x1e300 an OverflowError,
    # a constant path took 14 s and 500 MB; now one sentence before any search
    pts = _base_points(setup)
    if case == "one_value_1e308":
        pts = pts.copy()
        pts[10, 0] = 1e308
    elif case == "all_values_x1e300":
        pts = pts * 1e300
    elif case == "all_values_x1e50":
        pts = pts * 1e50
    else:
        pts = np.full_like(pts, 3.0)
    csv = _probe(setup, case, pts)
    out = setup["tmp"] / f"{case}-u0.csv"
    res = _run(setup, csv, "-m", "xyz", "--out", out)
    assert res.exit_code == 2, res.output
    assert msg in res.output and str(csv) in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert not out.exists()


def test_match_out_pointed_at_its_own_input_is_refused_before_working(setup):
    # issue 12: `match --out` pointed at its own input overwrote the path
    csv = _probe(setup, "own-input", _base_points(setup))
    before = csv.read_bytes()
    res = _run(setup, csv, "-m", "xyz", "--out", csv)
    assert res.exit_code == 2
    assert res.output.strip() == f"Error: --out {csv}: is also an input of this command; " \
        "choose another file"  # fmt: skip
    assert csv.read_bytes() == before


@pytest.mark.parametrize(
    ("opt", "name", "msg"),
    [
        ("--plot", "fig.foo", "expected a file ending in .png"),
        ("--out", "u0.txt", "expected a file ending in .csv, got .txt"),
        ("--plot", "no/fig.png", "does not exist"),
    ],
)
def test_match_output_formats_and_folders_are_checked_before_working(setup, opt, name, msg):
    target = setup["tmp"] / name
    res = _run(setup, setup["csv"], "-m", "xyz", opt, target)
    assert res.exit_code == 2 and msg in res.output
    assert not target.exists()


def test_match_takes_m_for_machine_like_learn(setup):
    short = _run(setup, setup["csv"], "-m", "xyz", "--eps", EPS, "--json")
    long = _run(setup, setup["csv"], "--machine", "xyz", "--eps", EPS, "--json")
    assert short.exit_code == 0 == long.exit_code
    a, b = json.loads(short.output), json.loads(long.output)
    assert [s["end"] for s in a["segments"]] == [s["end"] for s in b["segments"]]
    learn_help = CliRunner().invoke(main, ["learn", "--help"]).output
    assert "-m, --machine" in learn_help
