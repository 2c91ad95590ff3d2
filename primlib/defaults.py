"""The defaults every stage shares, in one place.

Each is a plain module constant; a function that takes the matching argument documents
``None`` as "use the default from :mod:`primlib.defaults`".
"""

from __future__ import annotations

__all__ = [
    "EPS_FRACTION",
    "TIME_SCALE",
    "BAND_SAMPLES",
    "MIN_SEGMENT_BANDS",
    "FIT_RTOL",
    "ILC_BAND",
    "MAX_ABS_VALUE",
    "MIN_EXTENT_REL",
]

# Match tolerance relative to the path's extent. One number for `primlib match`, the warm
# start and `primlib learn`: the warm start's first-trial error follows the pieces' shape
# error, so a tight match pays (3e-4 of a 70 mm path is 0.02 mm).
EPS_FRACTION = 3e-4

# Range of time scales (primitive interval duration / segment duration) the matcher allows.
TIME_SCALE: tuple[float, float] = (0.25, 4.0)

# Width of a splice's transition band, in samples of the machine's dt.
BAND_SAMPLES = 8

# Shortest matched piece worth a junction, in transition bands (BAND_SAMPLES dt each). The
# band is centred on each junction, so a piece one band long is blended over its whole length
# (half a band at each end) and nothing of its stored input survives: shorter matches are
# left to the model inverse that fills unmatched stretches.
MIN_SEGMENT_BANDS = 1.0

# NURBS fit tolerance relative to the path's size.
FIT_RTOL = 1e-4

# ILC learning band without a Q-filter, as a fraction of the Nyquist frequency.
ILC_BAND = 0.1

# Largest magnitude accepted for a coordinate or an input sample, in the user's units.
# Far beyond any stage (1e9 mm is 1000 km; 1e9 V or N), it keeps every sum primlib forms
# finite with a wide margin: Kabsch second moments of 1e6 samples stay below 1e9² · 1e6 = 1e24,
# far from double precision's 1.8e308, and a coordinate keeps a resolution of 1e-7 there.
MAX_ABS_VALUE = 1e9

# A path whose extent (largest distance from its centroid) is below this fraction of its
# largest coordinate magnitude (or of 1 unit, whichever is larger) does not move: it cannot be
# matched or learned, and is refused.
MIN_EXTENT_REL = 1e-9
