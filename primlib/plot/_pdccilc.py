"""Figures of the master–slave PDCCILC study, like the paper's Figs. 7-12.

``plot_pdccilc(study, directory)`` writes, per contour, ``pdccilc-<contour>-rms.png`` (RMS
contour error per iteration, four laws: Figs. 7, 9, 11) and ``pdccilc-<contour>-steady.png``
(last trial: (a) the xy plane, (b) contour error against the master position x, (c), (d)
close-ups A and B: Figs. 8, 10, 12).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_pdccilc"]

_STYLE = {
    "TDILC": {"color": "tab:gray", "ls": ":"},
    "TDCCILC": {"color": "tab:blue", "ls": "--"},
    "PDILC": {"color": "tab:green", "ls": "-."},
    "PDCCILC": {"color": "tab:red", "ls": "-"},
}


def _zoom(ax, ref, outputs, centre, half):
    ax.plot(ref[:, 0], ref[:, 1], color="k", lw=1.0, label="reference")
    for law, y in outputs.items():
        ax.plot(y[:, 0], y[:, 1], lw=1.0, **_STYLE.get(law, {}), label=law)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")


def plot_pdccilc(study, directory) -> list[Path]:
    """Write the study's figures into ``directory`` (created if missing).

    Parameters
    ----------
    study : primlib.reproduce._pdccilc.PdccilcStudy
    directory : str or Path

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for contour, laws in study.rms_contour.items():
        fig = Figure(figsize=(6, 4), layout="constrained")
        ax = fig.subplots()
        for law, rms in laws.items():
            ax.semilogy(np.arange(len(rms)), rms * 1e3, lw=1.5, label=law, **_STYLE.get(law, {}))
        ax.set_xlabel("iteration")
        ax.set_ylabel("RMS contour error (µm)")
        ax.set_title(f"{contour}: RMS contour error per iteration")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        path = out / f"pdccilc-{contour}-rms.png"
        fig.savefig(path, dpi=120)
        written.append(path)

        ref = study.references[contour]
        outputs = study.final_output[contour]
        fig = Figure(figsize=(10, 8), layout="constrained")
        axs = fig.subplots(2, 2)
        a, b, c, d = axs.ravel()
        a.plot(ref[:, 0], ref[:, 1], color="k", lw=1.0, label="reference")
        for law, y in outputs.items():
            a.plot(y[:, 0], y[:, 1], lw=1.0, label=law, **_STYLE.get(law, {}))
        a.set_aspect("equal")
        a.set_xlabel("x (mm)")
        a.set_ylabel("y (mm)")
        a.set_title("(a) xy plane, last iteration")
        a.legend(fontsize=8)
        for law, eps in study.final_contour[contour].items():
            b.plot(ref[:, 0], eps * 1e3, lw=1.0, label=law, **_STYLE.get(law, {}))
        b.set_xlabel("x (mm)")
        b.set_ylabel("contour error (µm)")
        b.set_title("(b) contour error against the master position")
        b.grid(True, alpha=0.3)
        # close-ups: A a quarter of the way along, B three quarters (box 2 % of the extent)
        extent = float(np.max(np.ptp(ref, axis=0)))
        for ax, frac, label in ((c, 0.25, "A"), (d, 0.75, "B")):
            k = int(frac * (len(ref) - 1))
            _zoom(ax, ref, outputs, ref[k], 0.02 * extent)
            ax.set_title(f"({'c' if label == 'A' else 'd'}) close-up {label} at t/T = {frac}")
            a.annotate(label, ref[k], fontsize=10, fontweight="bold")
        fig.suptitle(f"{contour}: steady tracking results")
        path = out / f"pdccilc-{contour}-steady.png"
        fig.savefig(path, dpi=120)
        written.append(path)
    return written
