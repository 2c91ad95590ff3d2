"""Figures of the CEE-MFAC study, like the paper's Figs. 4-6.

``plot_cee(study, directory)`` writes ``cee-fig4-contour.png`` (desired and actual contour),
``cee-fig5-tip.png`` (close-up at the ellipse's tip x = 10 mm, where the curvature is
largest; the deviation is drawn magnified) and ``cee-fig6-error.png`` (contour error
against time, four cases). Given the feed-speed sweep (``cee_mfac_sweep``) it writes
``cee-sweep.png``: e_max, e_mad and each estimator's own error against the peak feed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_cee"]

_STYLE = {
    "C1": {"color": "tab:gray", "ls": ":"},
    "C2": {"color": "tab:blue", "ls": "--"},
    "C3": {"color": "tab:red", "ls": "-"},
    "C4": {"color": "tab:green", "ls": "-."},
}
_LABEL = {
    "C1": "C1 MFAC + linear",
    "C2": "C2 MFAC + circular",
    "C3": "C3 MFAC + exact",
    "C4": "C4 PID + exact",
}


def _magnified(run, error, gain):
    """Actual contour drawn with its contour error magnified ``gain`` times."""
    ref = run.reference
    # outward normal of the ellipse x = a sin t, y = b cos t at the reference point
    n = np.c_[ref[:, 0] / 100.0, ref[:, 1] / 25.0]
    n /= np.linalg.norm(n, axis=1)[:, None]
    return ref + gain * error[:, None] * n


_SWEEP_STYLE = {
    "linear": {"color": "tab:gray", "ls": ":", "marker": "s"},
    "circular": {"color": "tab:blue", "ls": "--", "marker": "^"},
    "exact": {"color": "tab:red", "ls": "-", "marker": "o"},
}


def plot_cee(study, directory) -> list[Path]:
    """Write the study's figures into ``directory`` (created if missing).

    Parameters
    ----------
    study : primlib.reproduce.CEEStudy or primlib.reproduce.CEESweep
        The single-point study (Figs. 4-6) or the feed-speed sweep (one figure).
    directory : str or Path

    Returns
    -------
    list of Path
    """
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    if hasattr(study, "feed"):
        return [_plot_sweep(study, out / "cee-sweep.png")]
    written = []
    first = next(iter(study.runs.values()))
    ref = first.reference

    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.subplots()
    ax.plot(ref[:, 0], ref[:, 1], color="k", lw=2.5, alpha=0.4, label="desired")
    for case, run in study.runs.items():
        ax.plot(run.actual[:, 0], run.actual[:, 1], lw=1.0, **_STYLE[case], label=_LABEL[case])
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("Desired and actual contour (Fig. 4)")
    ax.legend(fontsize=7, loc="center")
    written.append(out / "cee-fig4-contour.png")
    fig.savefig(written[-1], dpi=120)

    gain = 20.0
    fig = Figure(figsize=(6, 4), layout="constrained")
    ax = fig.subplots()
    tip = np.argmax(ref[:, 0])
    ax.plot(ref[:, 0], ref[:, 1], color="k", lw=1.5, label="desired")
    for case, run in study.runs.items():
        mag = _magnified(run, study.true_error[case], gain)
        ax.plot(mag[:, 0], mag[:, 1], lw=1.0, **_STYLE[case], label=_LABEL[case])
    ax.set_xlim(ref[tip, 0] - 1.5, ref[tip, 0] + 0.5)
    ax.set_ylim(ref[tip, 1] - 2.0, ref[tip, 1] + 2.0)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"At the tip x = 10 mm, contour error x{gain:g} (Fig. 5)")
    ax.legend(fontsize=7)
    written.append(out / "cee-fig5-tip.png")
    fig.savefig(written[-1], dpi=120)

    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.subplots()
    for case, run in study.runs.items():
        ax.plot(run.t, study.true_error[case] * 1e3, lw=1.0, **_STYLE[case], label=_LABEL[case])
    ax.set_xlabel("t (s)")
    ax.set_ylabel("contour error (µm), + outside")
    ax.set_title("Contour error of the four methods (Fig. 6)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    written.append(out / "cee-fig6-error.png")
    fig.savefig(written[-1], dpi=120)
    return written


def _plot_sweep(sweep, path: Path) -> Path:
    """e_max, e_mad (true contour error) and each estimator's own error against feed."""
    fig = Figure(figsize=(7, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    panels = (
        (sweep.e_max, "e_max (µm)"),
        (sweep.e_mad, "e_mad (µm)"),
        (sweep.estimate_error, "estimate error (µm)"),
    )
    for ax, (values, label) in zip(axes, panels, strict=True):
        for name, style in _SWEEP_STYLE.items():
            y = values[name]
            if ax is axes[2] and name == "exact":
                continue  # exact by construction (the ellipse quartic): zero error
            ax.plot(sweep.feed, y, lw=1.2, ms=4, **style, label=f"MFAC + {name} estimate")
        ax.set_ylabel(label)
        ax.set_yscale("log")
        ax.grid(True, which="both", alpha=0.3)
    axes[2].plot(
        sweep.feed, sweep.lag["exact"], color="k", lw=1.0, alpha=0.6, label="tracking lag (µm)"
    )
    axes[0].set_title("largest |true contour error|", fontsize=9, loc="left")
    axes[1].set_title("mean |true contour error|", fontsize=9, loc="left")
    axes[2].set_title(
        "largest |estimate − true contour error|, and the lag", fontsize=9, loc="left"
    )
    axes[0].legend(fontsize=8)
    axes[2].legend(fontsize=8)
    axes[2].set_xlabel("peak feed speed (mm/s)")
    gain = sweep.settings.get("ccc_gain_V_per_mm")
    fig.suptitle(
        "CEE-MFAC ellipse against feed speed (last revolution"
        + (f", K_p = {gain:g} V/mm)" if gain is not None else ")")
    )
    fig.savefig(path, dpi=120)
    return path
