"""Figure of a warm start: the path and its segments, u0 with the junction bands, and the RMS
tracking error per ILC iteration from the warm start and from zero."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_warm_start"]


def plot_warm_start(
    out,
    points: np.ndarray,
    t: np.ndarray,
    warm,
    rms_warm: np.ndarray,
    rms_cold: np.ndarray | None = None,
    *,
    rms_inverse: np.ndarray | None = None,
    axes=("x", "y", "z"),
) -> Path:
    """Draw the three panels and save them.

    Parameters
    ----------
    out : path-like
        Figure file (format from the suffix).
    points : array, shape (n, d)
        The new path on the machine's grid.
    t : array, shape (n,)
    warm : WarmStart or None
        Its ``u``, ``sample_segment``, ``bands``, ``methods`` are drawn (None: cold run).
    rms_warm : array, shape (iters + 1,)
        RMS tracking error per trial of the run that was made (warm, or cold).
    rms_cold : array, shape (iters + 1,), optional
        The same from zero, for comparison.
    rms_inverse : array, optional
        The same from the nominal-model inverse.
    axes : sequence of str
        Axis names for the legend.

    Returns
    -------
    Path
    """
    out = Path(out)
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.5))
    p = np.asarray(points)
    seg = np.zeros(p.shape[0], int) if warm is None else np.asarray(warm.sample_segment)
    methods = () if warm is None else warm.methods
    cmap = plt.get_cmap("tab10")
    for j in np.unique(seg):
        sel = seg == j
        unmatched = j < len(methods) and methods[j] == "inverse"
        ax[0].plot(
            p[sel, 0],
            p[sel, 1],
            lw=2.5,
            color="0.6" if unmatched else cmap(j % 10),
            ls=":" if unmatched else "-",
            label=f"seg {j}"
            + (" (unmatched)" if unmatched else f" ({methods[j]})" if j < len(methods) else ""),
        )
    if warm is not None:
        for b in warm.bands:
            i = int(np.argmin(np.abs(t - b.junction)))
            ax[0].plot(p[i, 0], p[i, 1], "ko", ms=4)
    ax[0].set_aspect("equal", adjustable="datalim")
    ax[0].set_xlabel(axes[0])
    ax[0].set_ylabel(axes[1] if len(axes) > 1 else "")
    ax[0].set_title("new path, matched segments (x-y view)")
    ax[0].legend(fontsize=7, loc="best")

    if warm is not None:
        spliced = getattr(warm, "spliced", None)
        for i in range(warm.u.shape[1]):
            line = ax[1].plot(t, warm.u[:, i], lw=1, label=f"u0 {axes[i]}")[0]
            if spliced is not None and not np.array_equal(spliced, warm.u):
                ax[1].plot(t, spliced[:, i], lw=0.8, ls=":", color=line.get_color())
        for b in warm.bands:
            if b.end > b.start:
                ax[1].axvspan(b.start, b.end, color="orange", alpha=0.3, lw=0)
            ax[1].axvline(b.junction, color="k", lw=0.5, ls="--")
        ax[1].set_title("warm-start input u0 (dotted: pieces before correction), bands shaded")
        ax[1].legend(fontsize=7)
    else:
        ax[1].text(
            0.5, 0.5, "cold start: u0 = 0", ha="center", va="center", transform=ax[1].transAxes
        )
    ax[1].set_xlabel("t [s]")

    it = np.arange(len(rms_warm))
    ax[2].semilogy(it, rms_warm, "o-", label="warm start" if warm is not None else "cold start")
    if rms_cold is not None:
        ax[2].semilogy(np.arange(len(rms_cold)), rms_cold, "s-", label="cold start (u0 = 0)")
    if rms_inverse is not None:
        ax[2].semilogy(
            np.arange(len(rms_inverse)), rms_inverse, "^-", label="nominal-model inverse"
        )
    ax[2].set_xlabel("ILC iteration")
    ax[2].set_ylabel("RMS tracking error")
    ax[2].set_title("RMS error per iteration")
    ax[2].grid(True, which="both", alpha=0.3)
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
