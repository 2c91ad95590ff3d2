"""Build primlib's bundled example: a library of primitives for the XYZ machine and new paths.

    python scripts/build_example_library.py            # rewrites data/library and data/paths
    python scripts/build_example_library.py --check    # rebuild in a temp dir, compare

data/library/<stem>.csv          path (t,x,y,z, mm), rest to rest
data/library/<stem>.signal.csv   its input, learned by primlib's own ILC on the XYZ machine
                                 model of the primitive-matching paper (eq. 24)
data/paths/<name>.csv            new paths made of rotated, translated, time-scaled windows of
                                 the primitives, position and velocity continuous, at rest at
                                 both ends
data/paths/<name>.pieces.json    how each new path was made (primitive, window, rotation,
                                 translation, time scale) — the ground truth a match should find

Every primitive follows a minimum-jerk time law s(t) = 10 r^3 - 15 r^4 + 6 r^5, r = t / T,
along its shape, so it starts and ends at rest with zero acceleration. The library is
``primlib ingest data/library/*.csv --machine xyz`` away from a DuckDB file (the ingest pairs
``<stem>.csv`` with ``<stem>.signal.csv``).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from primlib.io import write_path_csv, write_signal_csv  # noqa: E402
from primlib.nurbs import Trajectory  # noqa: E402
from primlib.plant import Machine  # noqa: E402

ILC_ITERATIONS = 30
ILC_TOL = 1e-4  # mm RMS (0.1 um)


def _minjerk(r):
    return 10 * r**3 - 15 * r**4 + 6 * r**5


def _line(d):
    d = np.asarray(d, float)
    return lambda s: s[:, None] * d[None, :]


def _arc(radius, angle, plane="xy", climb=0.0):
    def f(s):
        a = angle * s
        u, v = radius * np.sin(a), radius * (1 - np.cos(a))
        w = climb * s
        if plane == "xy":
            return np.stack([u, v, w], 1)
        return np.stack([u, w, v], 1)

    return f


def _helix(radius, turns, height):
    def f(s):
        a = 2 * np.pi * turns * s
        return np.stack([radius * np.sin(a), radius * (1 - np.cos(a)), height * s], 1)

    return f


def _spiral(r0, r1, turns):
    def f(s):
        a = 2 * np.pi * turns * s
        r = r0 + (r1 - r0) * s
        return np.stack([r * np.cos(a) - r0, r * np.sin(a), 2.0 * s], 1)

    return f


def _lemniscate(a):
    def f(s):
        th = 2 * np.pi * s
        den = 1 + np.sin(th) ** 2
        return np.stack([a * np.sin(th) / den, a * np.sin(th) * np.cos(th) / den, 0 * s], 1)

    return f


def _wave(length, amp, periods, lift=0.0):
    return lambda s: np.stack(
        [length * s, amp * np.sin(2 * np.pi * periods * s), lift * np.sin(np.pi * s) ** 2], 1
    )


def _corner(a, b, r):
    # smooth L: along x, a quarter turn of radius r, along y (a C1 composite shape in s)
    def f(s):
        total = a + np.pi * r / 2 + b
        d = s * total
        out = np.zeros((s.size, 3))
        m1 = d <= a
        out[m1, 0] = d[m1]
        m2 = (d > a) & (d <= a + np.pi * r / 2)
        th = (d[m2] - a) / r
        out[m2, 0] = a + r * np.sin(th)
        out[m2, 1] = r * (1 - np.cos(th))
        m3 = d > a + np.pi * r / 2
        out[m3, 0] = a + r
        out[m3, 1] = r + (d[m3] - a - np.pi * r / 2)
        return out

    return f


# stem, duration (s), shape; the same shape at two durations gives eq. (20) two versions
PRIMITIVES = [
    ("line-x-fast", 1.2, _line([30, 0, 0])),
    ("line-x-slow", 2.4, _line([30, 0, 0])),
    ("line-diagonal", 2.0, _line([20, 12, 6])),
    ("arc-quarter", 2.0, _arc(20, np.pi / 2)),
    ("arc-quarter-slow", 3.5, _arc(20, np.pi / 2)),
    ("arc-half-xz", 2.5, _arc(12, np.pi, plane="xz")),
    ("circle", 3.0, _arc(10, 2 * np.pi)),
    ("helix", 4.0, _helix(8, 1.5, 15)),
    ("spiral", 3.5, _spiral(4, 16, 1.25)),
    ("figure-eight", 4.0, _lemniscate(20)),
    ("s-wave", 3.0, _wave(40, 8, 1.0)),
    ("zigzag-wave", 3.0, _wave(36, 5, 1.5, lift=4)),
    ("rounded-corner", 2.5, _corner(15, 15, 6)),
    ("arc-climb", 2.5, _arc(15, 0.75 * np.pi, climb=8)),
]


def primitive_samples(shape, T: float, dt: float, origin=(0.0, 0.0, 0.0)) -> np.ndarray:
    t = np.arange(round(T / dt) + 1) * dt
    return shape(_minjerk(t / T)) + np.asarray(origin, float)


def learn_signal(
    machine: Machine,
    reference: np.ndarray,
    iterations: int = ILC_ITERATIONS,
    model: Machine | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """ILC on ``machine`` (designed on ``model``) from zero; returns (u, rms per trial)."""
    from primlib.ilc import LearnOptions, learn

    # dense convergence check: primlib.ilc's eigsh route does not converge when the
    # learning matrix's eigenvalues cluster at 1 (n > 400 on this machine)
    res = learn(
        machine,
        reference,
        None,
        model=model,
        law="norm-optimal",
        iterations=iterations,
        tol=ILC_TOL,
        contour=False,
        options=LearnOptions(dense_limit=max(400, reference.shape[0])),
    )
    return np.asarray(res.u), np.asarray(res.rms_total)


def _rotation_aligning(a: np.ndarray, b: np.ndarray, twist: float) -> np.ndarray:
    """A proper rotation taking direction a to direction b, then turned by twist about b."""
    a = a / np.linalg.norm(a)
    b = b / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if np.linalg.norm(v) < 1e-12:
        if c > 0:
            r = np.eye(3)
        else:  # half turn about any axis normal to a
            n = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
            n /= np.linalg.norm(n)
            r = 2 * np.outer(n, n) - np.eye(3)
    else:
        vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        r = np.eye(3) + vx + vx @ vx / (1 + c)
    bx = np.array([[0, -b[2], b[1]], [b[2], 0, -b[0]], [-b[1], b[0], 0]])
    twist_r = np.eye(3) + np.sin(twist) * bx + (1 - np.cos(twist)) * bx @ bx
    return twist_r @ r


def _rot_z(th: float) -> np.ndarray:
    c, s = np.cos(th), np.sin(th)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def compose(prims: dict, plan: list[dict], dt: float) -> tuple[np.ndarray, list[dict]]:
    """Chain primitive windows into one path, position and velocity continuous.

    ``plan`` items: ``{"primitive": stem, "window": [v0, v1], "duration": s}`` for the first
    piece (it also takes ``"angle"`` about z), then for the others either a rest junction
    (window starting at 0 after one ending at 1; ``"duration"``, ``"angle"``) or a moving
    one (the rotation and time scale follow from the velocity to match; ``"twist"``).

    Returns
    -------
    points : array, shape (n, 3)
    pieces : list of dict
        Per piece: primitive, window, rotation, translation, time scale, start/end times.
    """
    pieces: list[dict] = []
    t_now = 0.0
    end_point = np.asarray(plan[0].get("at", np.zeros(3)), dtype=float)
    end_vel = np.zeros(3)
    h = 1e-6
    for step in plan:
        shape, T_l = prims[step["primitive"]]
        v0, v1 = step["window"]

        def p_at(v, shape=shape):
            return shape(_minjerk(np.atleast_1d(float(v))))[0]

        # velocity per second of primitive time at the window's start and end
        vel_start = (p_at(min(v0 + h, 1.0)) - p_at(v0)) / (h * T_l)
        vel_end = (p_at(v1) - p_at(max(v1 - h, 0.0))) / (h * T_l)
        if np.linalg.norm(end_vel) > 1e-9:  # moving junction: match the velocity
            rot = _rotation_aligning(vel_start, end_vel, step.get("twist", 0.0))
            k = float(np.linalg.norm(end_vel) / np.linalg.norm(vel_start))
        else:  # rest junction (or the first piece)
            rot = _rot_z(step.get("angle", 0.0))
            k = (v1 - v0) * T_l / step["duration"]
        dur = (v1 - v0) * T_l / k
        trans = end_point - rot @ p_at(v0)
        pieces.append(
            {
                "primitive": step["primitive"],
                "window": [v0, v1],
                "rotation": rot.tolist(),
                "translation": trans.tolist(),
                "time_scale": k,
                "start_time": t_now,
                "end_time": t_now + dur,
            }
        )
        end_point = rot @ p_at(v1) + trans
        end_vel = np.zeros(3) if v1 >= 1.0 else k * (rot @ vel_end)
        t_now += dur
    # evaluate every piece exactly at the dt grid times it covers
    # the grid ends at the first sample at or after the end: the last sample or so holds the
    # end point, where the minimum-jerk law is at rest with zero acceleration
    t = np.arange(int(np.ceil(t_now / dt - 1e-9)) + 1) * dt
    ends = np.array([p["end_time"] for p in pieces])
    which = np.minimum(np.searchsorted(ends, t, side="right"), len(pieces) - 1)
    grid = np.empty((t.size, 3))
    for i, p in enumerate(pieces):
        sel = which == i
        shape, _ = prims[p["primitive"]]
        v0, v1 = p["window"]
        frac = (t[sel] - p["start_time"]) / (p["end_time"] - p["start_time"])
        v = v0 + (v1 - v0) * np.clip(frac, 0.0, 1.0)
        grid[sel] = shape(_minjerk(v)) @ np.asarray(p["rotation"]).T + p["translation"]
    return grid, pieces


# new paths: lists of steps (see compose)
PATHS = {
    "corner-and-arc": [
        {"primitive": "line-x-fast", "window": [0.0, 0.6], "duration": 1.0},
        {"primitive": "arc-quarter", "window": [0.35, 1.0], "twist": 0.0},
    ],
    "zigzag": [
        {"primitive": "s-wave", "window": [0.0, 0.55], "duration": 1.8},
        {"primitive": "arc-half-xz", "window": [0.4, 0.8], "twist": 0.6},
        {"primitive": "line-diagonal", "window": [0.5, 1.0], "twist": -0.4},
    ],
    "spiral-helix": [
        {"primitive": "spiral", "window": [0.0, 0.7], "duration": 2.6},
        {"primitive": "helix", "window": [0.3, 1.0], "twist": 1.0},
    ],
    "glyph-chain": [
        {"primitive": "arc-quarter", "window": [0.0, 1.0], "duration": 1.6, "angle": 0.5},
        {"primitive": "line-x-slow", "window": [0.0, 1.0], "duration": 1.5, "angle": 2.0},
        {"primitive": "circle", "window": [0.0, 0.6], "duration": 2.2, "angle": -0.7},
        {"primitive": "rounded-corner", "window": [0.3, 1.0], "twist": 0.3},
    ],
    "five-pieces": [
        {"primitive": "figure-eight", "window": [0.0, 0.3], "duration": 1.4},
        {"primitive": "zigzag-wave", "window": [0.25, 0.6], "twist": 0.0},
        {"primitive": "arc-climb", "window": [0.3, 0.7], "twist": 0.8},
        {"primitive": "s-wave", "window": [0.2, 0.5], "twist": -1.2},
        {"primitive": "arc-quarter", "window": [0.5, 1.0], "twist": 0.4},
    ],
}


def build(out: Path, machine: Machine, iterations: int = ILC_ITERATIONS, quiet=False) -> dict:
    lib_dir, path_dir = out / "library", out / "paths"
    lib_dir.mkdir(parents=True, exist_ok=True)
    path_dir.mkdir(parents=True, exist_ok=True)
    dt = machine.dt
    report = {}
    for stem, T, shape in PRIMITIVES:
        pts = primitive_samples(shape, T, dt)
        t = np.arange(pts.shape[0]) * dt
        f = lib_dir / f"{stem}.csv"
        write_path_csv(f, t, pts)
        traj = Trajectory.from_csv(f)  # what `primlib ingest` will store
        ref = traj.sample(dt)
        ref = ref - ref[0]
        u, rms = learn_signal(machine, ref, iterations)
        write_signal_csv(lib_dir / f"{stem}.signal.csv", t, u)
        report[stem] = {"rms0": float(rms[0]), "rms": float(rms[-1]), "iterations": len(rms) - 1}
        if not quiet:
            print(
                f"{stem:>18}  T = {T:4.1f} s  ILC rms {rms[0]:.3g} -> {rms[-1]:.3g} mm "
                f"in {len(rms) - 1} iterations"
            )
    prims = {stem: (shape, T) for stem, T, shape in PRIMITIVES}
    for name, plan in PATHS.items():
        pts, pieces = compose(prims, plan, dt)
        t = np.arange(pts.shape[0]) * dt
        write_path_csv(path_dir / f"{name}.csv", t, pts)
        (path_dir / f"{name}.pieces.json").write_text(json.dumps(pieces, indent=1) + "\n")
        if not quiet:
            print(f"{name:>18}  {len(pieces)} pieces, {t[-1]:.2f} s")
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "data")
    ap.add_argument("--iterations", type=int, default=ILC_ITERATIONS)
    ap.add_argument(
        "--check", action="store_true", help="build in a temporary folder and compare with --out"
    )
    args = ap.parse_args(argv)
    machine = Machine.from_json(ROOT / "data" / "machines" / "xyz.json")
    if not args.check:
        build(args.out, machine, args.iterations)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        build(Path(tmp), machine, args.iterations, quiet=True)
        bad = []
        for sub in ("library", "paths"):
            for f in sorted((Path(tmp) / sub).iterdir()):
                ref = args.out / sub / f.name
                if not ref.exists() or ref.read_bytes() != f.read_bytes():
                    bad.append(str(ref))
        print("up to date" if not bad else "differs: " + ", ".join(bad))
        return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
