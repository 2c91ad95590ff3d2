"""Figure of a match: the new path coloured by segment with each matched stored piece drawn
through its transform, and the RMSD of every segment against the tolerance.

Segments are numbered from 1 as ``primlib match`` prints them and named by their primitive;
lengths carry the user's unit; a 3-D view keeps equal scales on its three axes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_match", "match_figure"]


def plot_match(out, points: np.ndarray, match, pieces, *, unit: str = "mm") -> Path:
    """Draw the two panels of :func:`match_figure` and save them.

    Parameters
    ----------
    out : path-like
        Figure file (format from the suffix).
    points, match, pieces, unit
        See :func:`match_figure`.

    Returns
    -------
    Path
    """
    out = Path(out)
    match_figure(points, match, pieces, unit=unit).savefig(out, dpi=110)
    return out


def _name(seg) -> str:
    if seg.primitive is None:
        return "unmatched"
    return seg.primitive_name or f"#{seg.primitive}"


def match_figure(points: np.ndarray, match, pieces, *, unit: str = "mm") -> Figure:
    """The path by segment (stored pieces dashed) and the RMSD per segment.

    Parameters
    ----------
    points : array, shape (n, d)
        The new path at uniform time, normalised time v = i / (n − 1).
    match : Match
        Its segments (and ``eps``) are drawn.
    pieces : list of (array, shape (m, d)) or None
        Per segment, the stored piece through its transform
        (:func:`primlib.match.matched_pieces`); None where unmatched.
    unit : str
        The path's length unit.

    Returns
    -------
    matplotlib.figure.Figure
    """
    p = np.asarray(points)
    d = p.shape[1]
    fig = Figure(figsize=(13, 5.5), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, projection="3d" if d == 3 else None)
    bar = fig.add_subplot(1, 2, 2)
    n = p.shape[0]
    labels, rmsd, colours = [], [], []
    for j, (seg, piece) in enumerate(zip(match.segments, pieces, strict=True)):
        i0, i1 = round(seg.start * (n - 1)), round(seg.end * (n - 1))
        colour = "0.6" if seg.primitive is None else f"C{j % 10}"
        label = f"{j + 1}: {_name(seg)}"
        ax.plot(*p[i0 : i1 + 1].T, color=colour, lw=2.5, alpha=0.55, label=label)
        if piece is not None:
            ax.plot(*np.asarray(piece).T, color=colour, lw=1.0, ls="--")
        labels.append(label)
        rmsd.append(0.0 if seg.primitive is None else seg.rmsd)
        colours.append(colour)
    ax.set_title("new path by segment (dashed: stored piece, transformed)")
    ax.set_xlabel(f"x ({unit})")
    ax.set_ylabel(f"y ({unit})")
    if d == 3:
        ax.set_zlabel(f"z ({unit})")
        ax.set_box_aspect(np.maximum(np.ptp(p, axis=0), 1e-9 * max(np.ptp(p), 1.0)))
    else:
        ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8, loc="best")
    positions = np.arange(len(labels))
    bar.bar(positions, rmsd, color=colours)
    bar.set_xticks(positions, labels, rotation=30, ha="right", fontsize=8)
    bar.axhline(match.eps, color="k", ls=":", label=f"eps = {match.eps:.3g} {unit}")
    for j, seg in enumerate(match.segments):
        if seg.primitive is None:
            bar.text(j, 0.0, "none", ha="center", va="bottom", fontsize=8)
    bar.set_xlabel("segment")
    bar.set_ylabel(f"Kabsch RMSD ({unit})")
    bar.set_title("RMSD per segment")
    bar.legend()
    return fig
