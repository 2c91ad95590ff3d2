"""Figures. The only package importing matplotlib; each study or result draws from its own
private module here, and result objects' ``.plot()`` methods only delegate to these."""

from primlib.plot._identify import plot_identified, save_identified
from primlib.plot._warm import plot_warm_start

__all__ = ["plot_identified", "save_identified", "plot_warm_start"]
