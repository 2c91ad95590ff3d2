"""Zero-phase Q-filter of the learning update: Butterworth run forward and backward.

``QFilter(cutoff_hz, dt, order=2)`` is a digital Butterworth low-pass B of the given order
at ``cutoff_hz``, applied with ``scipy.signal.filtfilt``: magnitude |B|^2 (twice the order,
-6 dB at the cutoff), zero phase, so the learned input is not delayed.

Edges: the trial starts and ends at rest, so the signal is extended by *zeros* on both
sides, ``pad`` samples each, long enough for B's impulse response to decay below 1e-13
(``pad`` follows from B's slowest pole), and filtfilt runs on that with no further padding
(its initial conditions, scaled by the first sample, are then zero). The map is then the
symmetric Toeplitz matrix of the kernel |B|^2 (``kernel(n)``) up to that 1e-13: exactly
what the convergence check analyses, and a contraction (||Q|| <= max |B|^2 = 1). filtfilt's
default odd reflection about the end value would keep a non-zero end value, but its edge
rows have gains up to ~1.6 and can make a law that is monotonic in the interior grow at
the edges. The price of zero extension: an input that must end away from zero (a holding
input) is pulled towards zero over the last ~1 / cutoff seconds; none of primlib's machines
needs one (integrating axes, integral action).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft, linalg, signal

from primlib._errors import InputError

__all__ = ["QFilter"]

_DECAY = 1e-13


@dataclass(frozen=True)
class QFilter:
    """Zero-phase Butterworth Q-filter with zero extension (see the module docstring).

    Parameters
    ----------
    cutoff_hz : float
        Cut-off frequency in Hz, 0 < cutoff < Nyquist (0.5 / dt).
    dt : float
        Sample time in seconds.
    order : int
        Order of the Butterworth run in each direction (default 2).
    """

    cutoff_hz: float
    dt: float
    order: int = 2

    def __post_init__(self):
        nyquist = 0.5 / self.dt
        c = self.cutoff_hz
        if isinstance(c, bool) or not isinstance(c, (int, float)) or not 0 < c < nyquist:
            raise InputError(
                f"q_cutoff: expected a cut-off frequency in Hz between 0 and the Nyquist "
                f"frequency {nyquist:g} Hz, got {c!r}"
            )
        if isinstance(self.order, bool) or not isinstance(self.order, int):
            raise InputError(f"q_order: expected an integer from 1 to 8, got {self.order!r}")
        if not 1 <= self.order <= 8:
            raise InputError(f"q_order: expected an integer from 1 to 8, got {self.order!r}")

    @property
    def ba(self) -> tuple[np.ndarray, np.ndarray]:
        """Butterworth (b, a) of one pass."""
        return signal.butter(self.order, self.cutoff_hz, btype="low", fs=1.0 / self.dt)

    @property
    def pad(self) -> int:
        """Zeros added at each end: B's impulse response has decayed below 1e-13 by then."""
        _, a = self.ba
        radius = float(np.max(np.abs(np.roots(a))))
        return int(np.ceil(np.log(_DECAY) / np.log(radius))) + 4 * self.order

    def min_samples(self) -> int:
        return 2

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Filter along axis 0; x : array, shape (n,) or (n, k)."""
        b, a = self.ba
        x = np.asarray(x, dtype=float)
        p = self.pad
        widths = [(p, p)] + [(0, 0)] * (x.ndim - 1)
        y = signal.filtfilt(b, a, np.pad(x, widths), axis=0, padtype=None)
        return y[p : p + x.shape[0]]

    def matrix(self, n: int) -> np.ndarray:
        """Lifted matrix of the filter on n samples, shape (n, n) (the filter applied to the
        identity's columns; symmetric Toeplitz up to 1e-13)."""
        return self(np.eye(n))

    def kernel(self, n: int) -> np.ndarray:
        """Impulse response of |B|^2 at lags 0..n-1 (the first column of ``matrix(n)``)."""
        b, a = self.ba
        m = n + self.pad
        imp = np.zeros(m)
        imp[0] = 1.0
        h = signal.lfilter(b, a, imp)
        size = fft.next_fast_len(2 * m, real=True)
        spec = fft.rfft(h, size)
        return fft.irfft(spec * np.conj(spec), size)[:n]

    def response(self, omega: np.ndarray) -> np.ndarray:
        """|B(e^{i omega})|^2 at normalised frequencies omega (rad/sample)."""
        b, a = self.ba
        _, hb = signal.freqz(b, a, worN=omega)
        return np.abs(hb) ** 2

    def toeplitz(self, n: int) -> np.ndarray:
        """Dense symmetric Toeplitz matrix of ``kernel(n)``."""
        return linalg.toeplitz(self.kernel(n))
