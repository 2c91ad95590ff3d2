"""Figures. The only package importing matplotlib; each study or result draws from its own
private module here, and result objects' ``.plot()`` methods only delegate to these.

Importing this package imports matplotlib, so callers elsewhere import it inside the
function that draws (``import primlib`` stays free of matplotlib).
"""

from primlib.plot._cee import plot_cee
from primlib.plot._identify import plot_identified, save_identified
from primlib.plot._ilc import plot_ilc_result
from primlib.plot._match import plot_match
from primlib.plot._pdccilc import plot_pdccilc
from primlib.plot._warm import plot_warm_start

__all__ = [
    "plot_cee",
    "plot_identified",
    "plot_ilc_result",
    "plot_match",
    "plot_pdccilc",
    "plot_warm_start",
    "save_identified",
]
