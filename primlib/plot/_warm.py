"""Figure of a warm start: the path and its segments, u0 with the junction bands, and the RMS
tracking error per ILC iteration from the warm start and from zero.

The words are the CLI's: a segment's time scaling is "model-based" or "model-free eq. (20)",
an unmatched one is the model inverse; lengths carry the user's unit (mm) and inputs the
machine's input unit ("input" when the machine does not name one).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

__all__ = ["plot_warm_start", "warm_start_figure", "METHOD_WORDS"]

# splice's method names -> the CLI's words
METHOD_WORDS = {
    "identity": "stored signal",
    "model": "model-based",
    "direct": "model-free eq. (20)",
    "inverse": "unmatched: model inverse",
}

# a transition band narrower than this fraction of the time axis is drawn this wide (it is
# a few samples of a path seconds long: true to scale it would be a hairline)
_MIN_BAND = 0.012


def plot_warm_start(out, points, t, warm, rms_warm, rms_cold=None, **kwargs) -> Path:
    """Draw the three panels of :func:`warm_start_figure` and save them to ``out``.

    Parameters
    ----------
    out : path-like
        Figure file (format from the suffix).
    points, t, warm, rms_warm, rms_cold, **kwargs
        See :func:`warm_start_figure`.

    Returns
    -------
    Path
    """
    out = Path(out)
    warm_start_figure(points, t, warm, rms_warm, rms_cold, **kwargs).savefig(out, dpi=110)
    return out


def warm_start_figure(
    points: np.ndarray,
    t: np.ndarray,
    warm,
    rms_warm: np.ndarray,
    rms_cold: np.ndarray | None = None,
    *,
    rms_inverse: np.ndarray | None = None,
    axes=("x", "y", "z"),
    length_unit: str = "mm",
    input_unit: str | None = None,
) -> Figure:
    """The path by segment, u0 with its transition bands, and RMS per ILC iteration.

    Parameters
    ----------
    points : array, shape (n, d)
        The new path on the machine's grid.
    t : array, shape (n,)
        Its times (s).
    warm : WarmStart or None
        Its ``u``, ``sample_segment``, ``bands``, ``methods``, ``match`` are drawn (None: a
        cold run).
    rms_warm : array, shape (iters + 1,)
        RMS tracking error per trial of the run that was made; row 0 is u0's trial.
    rms_cold, rms_inverse : array, shape (iters + 1,), optional
        The same from zero and from the nominal-model inverse, for comparison.
    axes : sequence of str
        Axis names.
    length_unit : str
        The path's unit.
    input_unit : str, optional
        The machine's input unit; "input" when None.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    ax = fig.subplots(1, 3)
    _draw_path(ax[0], np.asarray(points), np.asarray(t), warm, axes, length_unit)
    _draw_input(ax[1], np.asarray(t), warm, axes, input_unit or "input")
    _draw_rms(ax[2], rms_warm, rms_cold, rms_inverse, warm is not None, length_unit)
    return fig


def _segment_label(warm, j: int) -> str:
    methods = warm.methods if warm is not None else ()
    how = METHOD_WORDS.get(methods[j], methods[j]) if j < len(methods) else ""
    name = None
    segments = getattr(getattr(warm, "match", None), "segments", ())
    if j < len(segments):
        name = segments[j].primitive_name or (
            None if segments[j].primitive is None else f"#{segments[j].primitive}"
        )
    head = f"{j + 1}: {name}" if name else f"{j + 1}"
    return f"{head} ({how})" if how else head


def _draw_path(ax, p, t, warm, axes, unit) -> None:
    seg = np.zeros(p.shape[0], int) if warm is None else np.asarray(warm.sample_segment)
    methods = () if warm is None else warm.methods
    colours = [f"C{k}" for k in range(10)]
    for j in np.unique(seg):
        sel = seg == j
        unmatched = j < len(methods) and methods[j] == "inverse"
        ax.plot(
            p[sel, 0],
            p[sel, 1],
            lw=2.5,
            color="0.6" if unmatched else colours[j % 10],
            ls=":" if unmatched else "-",
            label=_segment_label(warm, j) if warm is not None else "cold start",
        )
    if warm is not None and warm.bands:
        idx = [int(np.argmin(np.abs(t - b.junction))) for b in warm.bands]
        ax.plot(p[idx, 0], p[idx, 1], "ko", ms=4, label="junction")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{axes[0]} ({unit})")
    ax.set_ylabel(f"{axes[1]} ({unit})" if len(axes) > 1 else "")
    ax.set_title("new path by matched segment (x-y view)")
    ax.legend(fontsize=7, loc="best")


def _draw_input(ax, t, warm, axes, unit) -> None:
    ax.set_xlabel("t (s)")
    ax.set_ylabel(f"u0 ({unit})")
    if warm is None:
        ax.text(0.5, 0.5, "cold start: u0 = 0", ha="center", va="center", transform=ax.transAxes)
        return
    span = float(t[-1] - t[0]) if t.size > 1 else 1.0
    widened = False
    for k, b in enumerate(warm.bands):
        lo, hi = float(b.start), float(b.end)
        if hi - lo < _MIN_BAND * span:
            mid = 0.5 * (lo + hi) if hi > lo else float(b.junction)
            lo, hi = mid - 0.5 * _MIN_BAND * span, mid + 0.5 * _MIN_BAND * span
            widened = True
        ax.axvspan(lo, hi, color="0.45", alpha=0.3, lw=0, label="_band" if k else "band")
    if widened:  # say so on the figure: the shading is not to scale
        for patch in ax.patches:
            if patch.get_label() == "band":
                patch.set_label(f"transition band (drawn {100 * _MIN_BAND:g} % of t wide)")
    spliced = getattr(warm, "spliced", None)
    for i in range(warm.u.shape[1]):
        line = ax.plot(t, warm.u[:, i], lw=1, label=f"u0 {axes[i]}")[0]
        if spliced is not None and not np.array_equal(spliced, warm.u):
            ax.plot(t, spliced[:, i], lw=0.8, ls=":", color=line.get_color())
    ax.set_title("warm-start input u0 (dotted: pieces before correction)")
    ax.legend(fontsize=7)


def _draw_rms(ax, rms_warm, rms_cold, rms_inverse, warm: bool, unit) -> None:
    runs = (
        (rms_warm, "o-", "warm start" if warm else "cold start (u0 = 0)"),
        (rms_cold, "s-", "cold start (u0 = 0)"),
        (rms_inverse, "^-", "nominal-model inverse"),
    )
    for rms, style, label in runs:
        if rms is not None:
            ax.semilogy(np.arange(len(rms)), rms, style, label=label)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("ILC iteration (0: the first trial, with u0)")
    ax.set_ylabel(f"RMS tracking error ({unit})")
    ax.set_title("RMS tracking error per iteration")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
