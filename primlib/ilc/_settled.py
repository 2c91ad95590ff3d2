"""The input a finished trial series stores: its best trial's, or the mean of a run of its
settled trials (:meth:`primlib.ilc.TrialLearner.stored_input`).

Near its floor a series learns each trial's non-repeatable part into the next input: with a
trial-varying disturbance d_j (an input force that is new every trial, a few cycles per
trial) the law's update copies the last draw, so the inputs of the settled trials scatter
about the one the machine needs, u_j = u* + w_j, by about the disturbance itself. The
trial averaging of :class:`primlib.ilc.TrialLearner` does not stop it there: a trial joins
an update's average only while its move is small against the last error, and the moves
are the copied draws. Any one of those inputs is worth about the disturbance; their mean
over K trials is worth about 1/sqrt(K) of it (the copies of independent draws average out),
and it needs no model: on a linear machine

    r - G mean_j(u_j) = mean_j(e_j) + mean_j(n_j),    e_j = r - y_j,  n_j = y_j - G u_j,

so the mean of the measured errors ebar over the same trials is that input's error less
the mean nbar of the trials' non-repeatable parts (power sigma^2 / K; sigma^2, one trial's:
the floor^2 pooled over the series' settled pairs, :func:`._noise.pooled_noise`):

    err^2 = mean_t |ebar(t)|^2 + sigma^2 / K.

That is its expectation where the mean input's error and nbar are independent. Where each
update copied the whole last draw (G u_j = r - n_{j-1}) the errors telescope, ebar =
(n_{k0-1} - n_{k1-1}) / K, and ebar alone would say almost nothing is left while the input
still holds mean_j n_{j-1}, of power sigma^2 / K: the second term is what is left there.
Measured mean errors alone, or less sigma^2 / K, put 0.004-0.006 mm on inputs that left
0.013-0.048 (scratch, below).

Windows of at least ``MIN_RUN`` consecutive settled trials -- measured RMS within 3x the
median of the series' second half: a draw that happened to cancel makes the lowest trial no
scale for the others -- are candidates; the one of the least err is kept only where that is
below what the best trial is estimated to be worth
(:meth:`primlib.ilc.TrialLearner.best_input`) by a clear margin (below ``MEAN_GAIN`` = 0.4
of it). The estimate rests on the identity above, a linear machine's, and on a floor that the
model's error in the moved pairs can pass for where nothing varies from trial to trial: on
the friction 5 % library, without noise, means estimated at 0.63 and 0.5 of their best
trials left 4x more (1.0e-4 mm for 2.4e-5) and as much, and the rotated paths' model-only
input fitted to those pairs went 0.21 -> 0.66 um; the all-together series' means are
estimated at 0.19-0.46 of their best trials (13 of 14 below 0.3).

Measured with ``python benchmarks/bench_realism.py --settings "all together"`` (every
departure: friction, ripple, noise, a 2 % 2 Hz trial-varying disturbance, a 20 Hz mode): the
stored inputs of the three paths run in place leave 0.038 mm by themselves (median), where
the best trials' inputs left 0.24; scratch, the first four primitives' series: 0.034 / 0.10 /
0.12 / 0.15 mm for the best trial's input against 0.013 / 0.048 / 0.022 / 0.034 for a mean.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MIN_RUN", "settled_runs", "trial_rms"]

MIN_RUN = 4  # trials averaged at least (a mean of fewer is judged by too few draws)
_SETTLED = 3.0  # a settled trial's measured RMS within this of the second half's median


def trial_rms(reference: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """Each trial's RMS tracking error (Euclidean over the axes), shape (k,)."""
    return np.sqrt(np.mean(np.sum((reference[None] - outputs) ** 2, axis=2), axis=1))


def settled_runs(reference: np.ndarray, outputs: np.ndarray, sigma2: float):
    """(k0, k1, err) of the run of settled trials [k0, k1) whose mean input is estimated to
    leave the least error (module docstring), or None where no run of ``MIN_RUN`` settled
    trials exists.

    Parameters
    ----------
    reference : array, shape (n, d)
    outputs : array, shape (k, n, d)
        The measured outputs, relative to the start.
    sigma2 : float
        One trial's non-repeatable power, summed over the axes (the pooled floor squared).
    """
    err = reference[None] - outputs  # (k, n, d)
    k, n = err.shape[:2]
    rms = trial_rms(reference, outputs)
    settled = rms <= _SETTLED * np.median(rms[k // 2 :])
    # a window [k0, k1) holds settled trials only: k0 at or after the last unsettled one
    unsettled = np.flatnonzero(~settled)
    k0, k1 = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    last_bad = np.full(k + 1, -1)  # the last unsettled trial before k1
    if unsettled.size:
        at = np.searchsorted(unsettled, np.arange(k + 1), side="left") - 1
        last_bad = np.where(at >= 0, unsettled[np.maximum(at, 0)], -1)
    ok = (k1 - k0 >= MIN_RUN) & (k0 > last_bad[k1])
    if not ok.any():
        return None
    # the mean error of every window from the cumulative sums' Gram matrix: |T1 - T0|^2
    total = np.concatenate([np.zeros((1, err[0].size)), np.cumsum(err.reshape(k, -1), axis=0)])
    gram = total @ total.T
    sq = np.diag(gram)
    count = np.maximum(k1 - k0, 1)
    e2 = (sq[k1] - 2.0 * gram + sq[k0]) / (count**2 * n) + sigma2 / count
    e2 = np.where(ok, np.maximum(e2, 0.0), np.inf)
    i0, i1 = np.unravel_index(int(np.argmin(e2)), e2.shape)
    return int(i0), int(i1), float(np.sqrt(e2[i0, i1]))
