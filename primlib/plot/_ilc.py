"""Figure of an ILC run: RMS tracking error per trial, one line per axis, log scale, plus the
Euclidean total and the RMS contour error when the run recorded it.
``primlib.ilc.ILCResult.plot`` delegates here."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_ilc_result"]


def plot_ilc_result(result, ax=None, axis_names=None):
    """Draw the learning curves of an :class:`primlib.ilc.ILCResult`.

    Parameters
    ----------
    result : ILCResult
        Uses ``rms`` (trials, d), ``rms_total`` (trials,), ``rms_contour`` (trials,) or None,
        ``law`` and ``stopped``.
    ax : matplotlib Axes, optional
        Drawn into; None: a new figure.
    axis_names : sequence of str, optional
        Legend names of the axes (default ``axis 0``, ``axis 1``, ...).

    Returns
    -------
    matplotlib Axes
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    rms = np.asarray(result.rms)
    trials = np.arange(rms.shape[0])
    names = (
        list(axis_names) if axis_names is not None else [f"axis {i}" for i in range(rms.shape[1])]
    )
    for i in range(rms.shape[1]):
        ax.plot(trials, rms[:, i], marker="o", ms=3, label=f"{names[i]} RMS")
    if rms.shape[1] > 1:
        ax.plot(trials, result.rms_total, "k-", lw=2, label="total RMS")
    if result.rms_contour is not None:
        ax.plot(trials, result.rms_contour, "k--", marker="s", ms=3, label="contour RMS")
    ax.set_yscale("log")
    ax.set_xlabel("trial")
    ax.set_ylabel("RMS error")
    ax.set_title(f"ILC {result.law}: stopped on {result.stopped}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return ax
