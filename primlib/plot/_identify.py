"""Figure of an identification: measured and model output per axis over the record, the
held-out part shaded, each axis titled with its structure and held-out error.
``primlib.identify.Identified.plot`` delegates here."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np

__all__ = ["plot_identified", "save_identified"]


def plot_identified(result, ax=None):
    """Draw measured vs model output of an :class:`primlib.identify.Identified`.

    Parameters
    ----------
    result : Identified
        Uses ``y`` (n, d), ``y_model`` (n, d), ``dt``, ``n_est``, ``fits`` and
        ``machine.axes``.
    ax : array of matplotlib Axes, shape (d,), optional
        One per axis; None: a new figure with d rows.

    Returns
    -------
    array of matplotlib Axes, shape (d,)
    """
    y = np.asarray(result.y)
    y_model = result.y_model
    n, d = y.shape
    if ax is None:
        _, ax = plt.subplots(d, 1, figsize=(7, 2.2 * d + 0.6), sharex=True, squeeze=False)
        ax = ax[:, 0]
    ax = np.atleast_1d(ax)
    t = np.arange(n) * result.dt
    t_split = result.n_est * result.dt
    for i, (a, fit) in enumerate(zip(result.machine.axes, result.fits, strict=True)):
        ax[i].plot(t, y[:, i], color="0.55", lw=1.0, label="measured")
        ax[i].plot(t, y_model[:, i], color=f"C{i}", lw=1.2, ls="--", label="model")
        ax[i].axvspan(t_split, t[-1], color="0.92", zorder=0, label="held out")
        ax[i].set_ylabel(f"{a}")
        ax[i].set_title(
            f"{a}: {fit.structure}, held-out NRMSE {100 * fit.nrmse:.2f} %", fontsize="small"
        )
        ax[i].grid(True, alpha=0.3)
    ax[0].legend(fontsize="small", loc="upper left")
    ax[-1].set_xlabel("t [s]")
    return ax


def save_identified(result, path) -> None:
    """Draw :func:`plot_identified` into a new figure, save it to ``path`` and close it."""
    ax = plot_identified(result)
    fig = ax[0].figure
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
