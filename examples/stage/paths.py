"""Write the example paths of the stage walk-through (absolute coordinates, mm).

    python examples/stage/paths.py

``glyph.csv``: a loop drawn in 2 s starting at rest at (40, 25); ``glyph-moved.csv``: the
same shape rotated by 35 degrees and moved to start at (120, 60), where the force ripple
has another phase. Both at the stage's 2 ms sample time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DT = 0.002
DURATION = 2.0


def glyph(start=(40.0, 25.0), angle_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(t, points): the loop, rotated by ``angle_deg`` about its start, starting at ``start``."""
    t = np.arange(round(DURATION / DT) + 1) * DT
    s = t / DURATION
    s = s**3 * (10 - 15 * s + 6 * s**2)  # rest to rest
    x = 30.0 * s + 12.0 * np.sin(2 * np.pi * s)
    y = 16.0 * (1 - np.cos(2 * np.pi * s)) - 6.0 * np.sin(4 * np.pi * s)
    a = np.deg2rad(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return t, np.c_[x, y] @ R.T + np.asarray(start)


def main() -> None:
    from primlib.io import write_path_csv

    write_path_csv(HERE / "glyph.csv", *glyph())
    write_path_csv(HERE / "glyph-moved.csv", *glyph((120.0, 60.0), 35.0))


if __name__ == "__main__":
    main()
