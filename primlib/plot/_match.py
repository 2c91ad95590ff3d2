"""Figure of a match: the new path coloured by segment with each matched stored piece drawn
through its transform, and the RMSD of every segment against the tolerance."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_match"]


def plot_match(out, points: np.ndarray, match, pieces) -> Path:
    """Draw the two panels and save them.

    Parameters
    ----------
    out : path-like
        Figure file (format from the suffix).
    points : array, shape (n, d)
        The new path at uniform time, normalised time v = i / (n − 1).
    match : Match
        Its segments (and ``eps``) are drawn.
    pieces : list of (array, shape (m, d)) or None
        Per segment, the stored piece through its transform
        (:func:`primlib.match.matched_pieces`); None where unmatched.

    Returns
    -------
    Path
    """
    out = Path(out)
    p = np.asarray(points)
    d = p.shape[1]
    fig = plt.figure(figsize=(12, 5))
    ax = fig.add_subplot(1, 2, 1, projection="3d" if d == 3 else None)
    bar = fig.add_subplot(1, 2, 2)
    cmap = plt.get_cmap("tab10")
    n = p.shape[0]
    names, rmsd, colours = [], [], []
    for j, (seg, piece) in enumerate(zip(match.segments, pieces, strict=True)):
        i0, i1 = round(seg.start * (n - 1)), round(seg.end * (n - 1))
        part = p[i0 : i1 + 1]
        colour = "0.6" if seg.primitive is None else cmap(j % 10)
        label = f"{j + 1}: " + ("unmatched" if seg.primitive is None else f"#{seg.primitive}")
        ax.plot(*part.T, color=colour, lw=2.5, alpha=0.55, label=label)
        if piece is not None:
            ax.plot(*np.asarray(piece).T, color=colour, lw=1.0, ls="--")
        names.append(str(j + 1))
        rmsd.append(0.0 if seg.primitive is None else seg.rmsd)
        colours.append(colour)
    ax.set_title("new path by segment (dashed: stored piece, transformed)")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    if d == 3:
        ax.set_zlabel("z")
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8, loc="best")
    bar.bar(names, rmsd, color=colours)
    bar.axhline(match.eps, color="k", ls=":", label=f"eps = {match.eps:g}")
    for j, seg in enumerate(match.segments):
        if seg.primitive is None:
            bar.text(j, 0.0, "none", ha="center", va="bottom", fontsize=8)
    bar.set_xlabel("segment")
    bar.set_ylabel("Kabsch RMSD")
    bar.set_title("RMSD per segment")
    bar.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
