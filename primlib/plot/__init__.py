"""Figures. The only package importing matplotlib; each study or result draws from its own
private module here, and result objects' ``.plot()`` methods only delegate to these."""

from primlib.plot._identify import plot_identified, save_identified

__all__ = ["plot_identified", "save_identified"]
