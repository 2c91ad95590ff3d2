"""Trial-by-trial learning from measured outputs that carry noise.

A real stage returns y_j = G u_j + d + v_j: the repeatable response (the model G and a
disturbance d that is the same every trial) plus non-repeatable noise v_j. A law that
learns from the last error, u_{j+1} = Q (u_j + L e_j), feeds v_j into the input every
trial; in its learning band the true (noise-free) error then settles at about the noise
itself. :class:`TrialLearner` keeps the law of :func:`primlib.ilc.learn` and adds, from the
trials themselves:

- **Trial averaging.** The errors of the last m trials are moved to the current input with
  the model, e~_i = e_i - G (u_last - u_i), and averaged: e_bar = mean_i e~_i. Their
  repeatable part is the same, the noise averages down (variance / m), so the update
  u_next = Q (u_last + L e_bar) puts sigma / sqrt(m) of noise into the true error instead
  of sigma. A trial joins the average only while its move, the RMS of G (u_last - u_i), is
  below half the last trial's RMS error: a larger move brings in more model error than
  averaging removes noise (a real stage is only near its model, and friction is not in it).
- **The noise floor.** The residuals r_i = e~_i - e_bar are the non-repeatable part; per
  axis sigma_a^2 = sum_i ||r_i,a||^2 / ((m - 1) n), and the floor is
  sqrt(sum_a sigma_a^2): the RMS (Euclidean) tracking error a perfect input would still
  measure.
- **The Q-filter's bandwidth** from two Hann-windowed spectra (axes summed):
  N(f) = sum_i |FFT(r_i)(f)|^2 / (m - 1), the non-repeatable power of one trial, and
  P(f) = |FFT(e_bar + G u_last)(f)|^2 - N(f) / m, the repeatable target the input must
  produce (the error with no input). Q acts on the input, so above the cut-off it removes
  both the noise learned there and the target's content; below it the input carries the
  averaged noise. The cut-off minimises the sum,
  cost(f_c) = sum_{f < f_c} N(f) / m + sum_{f >= f_c} P(f),
  snapped to 12 values per decade (so it does not dither) within [2 / T, 0.4 / dt]. Q is
  the zero-phase Butterworth of :class:`primlib.ilc.QFilter` of order 4 (passband
  |B|^2 = 0.996 at half the cut-off: the second order's 0.94 there biases the converged
  input by 6 % of what it needs at that frequency).
- **The stop rule**: converged when the true error's estimate for the last input run,
  sqrt(R^2 + floor^2 phi / m_eff), is within ``margin`` times the floor, from at least 3
  averaged trials. R^2 = max(mean ||e_bar||^2 - floor^2 / m, 0) is the repeatable error
  left; phi = sum_f |g(f)|^2 N(f) / sum_f N(f) the share of one trial's noise power an
  update puts into the motion (g: the model's response to the update of an impulse error in
  mid-trial); m_eff = (m + 1) / 2 for the m trials the update that made that input
  averaged (1 for the plain law; see :meth:`TrialLearner.remaining`). Diverging: the
  measured error grew over each of the last two trials by more than ``margin`` times the
  floor (10 % without a floor).

Every quantity is a function of the recorded inputs and outputs only, so a series resumed
in another process computes exactly the same next input.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import fft

from primlib._errors import InputError
from primlib.ilc._laws import law_from_name
from primlib.ilc._learn import _prepare, _update
from primlib.ilc._qfilter import QFilter
from primlib.ilc._settled import settled_runs, trial_rms

__all__ = ["TrialLearner", "TrialUpdate", "NoiseEstimate", "estimate_noise", "pooled_noise"]

LAWS = ("p", "pd", "pid", "norm-optimal")  # the laws a trial series learns with
_PER_DECADE = 12  # cut-off grid
_GROWTH = 0.1  # relative growth that counts as diverging when no floor is known yet
_MOVE = 0.5  # largest model move of an averaged trial's error, relative to the last error
_Q_ORDER = 4  # Butterworth order of the noise-aware Q (module docstring)
MEAN_GAIN = 0.4  # a stored mean input's estimate below this of the best trial's
_MIN_VERDICT = 3  # trials in the window before the stop rule trusts the floor


@dataclass(frozen=True)
class NoiseEstimate:
    """What the last trials say about the noise.

    Attributes
    ----------
    floor : float
        RMS (Euclidean over axes) of the non-repeatable part of one trial's error.
    floor_axes : array, shape (d,)
    averaged : array, shape (n, d)
        e_bar, the last trials' errors moved to the last input and averaged.
    noise_power : array, shape (n // 2 + 1,)
        N(f), non-repeatable power per trial, summed over axes (rfft bins).
    repeatable_power : array, shape (n // 2 + 1,)
        R(f), the power of e_bar's repeatable part, |FFT(e_bar)|^2 - N(f) / m, summed over
        axes.
    trials : int
        m, the number of trials used.
    """

    floor: float
    floor_axes: np.ndarray
    averaged: np.ndarray
    noise_power: np.ndarray
    repeatable_power: np.ndarray
    target_power: np.ndarray
    trials: int

    @property
    def repeatable_rms(self) -> float:
        """RMS (Euclidean) of the repeatable error at the last input, the true error's
        estimate: sqrt(max(mean ||e_bar||^2 - floor^2 / m, 0))."""
        ms = float(np.mean(np.sum(self.averaged**2, axis=1)))
        return float(np.sqrt(max(ms - self.floor**2 / self.trials, 0.0)))


@dataclass(frozen=True)
class TrialUpdate:
    """One learning step from the recorded trials.

    Attributes
    ----------
    u : array, shape (n, d)
        The next trial's input.
    q_cutoff : float or None
        The Q-filter cut-off (Hz) the update used; None for no Q-filter.
    noise : NoiseEstimate or None
        None until two trials are recorded (or without noise awareness and averaging).
    rms : float
        The last trial's measured RMS tracking error (Euclidean).
    converged, diverging : bool
        The stop rule's verdicts (see the module docstring).
    """

    u: np.ndarray
    q_cutoff: float | None
    noise: NoiseEstimate | None
    rms: float
    converged: bool
    diverging: bool

    @property
    def noise_floor(self) -> float | None:
        return None if self.noise is None else self.noise.floor


def _model_response(h: np.ndarray, du: np.ndarray) -> np.ndarray:
    """G du per axis (causal convolution with the impulse response), shape (n, d)."""
    n = du.shape[0]
    size = fft.next_fast_len(2 * n, real=True)
    return fft.irfft(fft.rfft(h, size, axis=0) * fft.rfft(du, size, axis=0), size, axis=0)[:n]


def estimate_noise(
    h: np.ndarray, reference: np.ndarray, inputs: np.ndarray, outputs: np.ndarray
) -> NoiseEstimate:
    """Split the last trials' errors into repeatable and non-repeatable parts.

    Parameters
    ----------
    h : array, shape (n, d)
        The model's impulse response (Markov parameters) per axis.
    reference : array, shape (n, d)
        Desired output relative to the start.
    inputs, outputs : array, shape (m, n, d)
        The trials' inputs and measured outputs (relative to the start), m >= 2, the last
        one last.

    Returns
    -------
    NoiseEstimate
    """
    m, n, d = inputs.shape
    if m < 2:
        raise InputError(f"trials: expected at least 2 recorded trials to estimate noise, got {m}")
    errors = reference[None] - outputs
    du = (inputs[-1][None] - inputs).transpose(1, 0, 2).reshape(n, m * d)
    moved = _model_response(np.tile(h, (1, m)), du).reshape(n, m, d).transpose(1, 0, 2)
    corrected = errors - moved  # eq. e~_i = e_i - G (u_last - u_i)
    averaged = corrected.mean(axis=0)
    resid = corrected - averaged[None]
    floor_axes = np.sqrt(np.sum(resid**2, axis=(0, 1)) / ((m - 1) * n))
    # Hann-windowed spectra: a path does not end where it starts, and the jump would leak
    # a 1/f tail over the whole band (the window's leakage falls as 1/f^3)
    win = np.hanning(n)[:, None]
    noise = np.sum(np.abs(fft.rfft(resid * win, axis=1)) ** 2, axis=(0, 2)) / (m - 1)
    power = np.sum(np.abs(fft.rfft(averaged * win, axis=0)) ** 2, axis=1) - noise / m
    target = averaged + _model_response(h, inputs[-1])  # the error with no input
    tpower = np.sum(np.abs(fft.rfft(target * win, axis=0)) ** 2, axis=1) - noise / m
    return NoiseEstimate(
        floor=float(np.sqrt(np.sum(floor_axes**2))),
        floor_axes=floor_axes,
        averaged=averaged,
        noise_power=noise,
        repeatable_power=np.maximum(power, 0.0),
        target_power=np.maximum(tpower, 0.0),
        trials=m,
    )


def pooled_noise(
    h: np.ndarray, reference: np.ndarray, inputs: np.ndarray, outputs: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """(floor_axes, noise_power) pooled over every settled pair of consecutive trials.

    Each pair (j - 1, j) gives the difference of its errors with trial j - 1 moved to
    u_j, G (v_j - v_{j-1}) for non-repeatable parts v: one trial's noise power twice. The
    pairs of the settled trials -- past the learning transient, whose large moves would
    bring in the model's error -- are averaged. Two trials give one draw of the noise, and a
    slow disturbance (a few cycles per trial) has few degrees of freedom per draw: the noise
    a series' best trial is judged by must not come from that trial's pair alone, which its
    low measured error selected (the pair whose two disturbances happened to agree). None:
    no settled pair.

    A trial is settled when its measured RMS error is within 3x the series' lowest, or
    within 3 floors of it (the floor pooled so far; repeated, the limit never lowered, until
    the settled trials stop changing). The second rule matters where a trial's noise has few
    degrees of freedom: there the lowest trial is a lucky draw, and 3x of it kept only the
    trials whose draws were small. On the example XYZ machine with a 2 % 2 Hz input
    disturbance (``python benchmarks/bench_realism.py --settings disturbance``'s machine,
    the circle's series) the 3x rule alone pooled a floor of 0.108 mm where the disturbance
    moves the machine by 0.25 mm RMS a draw, and the stored input's recorded error was 0.29x
    what it leaves; with the floors, 0.27 mm and 0.70x. Without noise (friction 5 %, the
    floor the model's error in the moved pairs) it moves the records by 1-2.5x, upwards.
    """
    rms = trial_rms(reference, outputs)
    lowest = float(rms.min())
    pairs: dict[int, NoiseEstimate] = {}  # each pair is what estimate_noise makes of two trials
    out, seen, limit = None, None, 3.0 * lowest
    for _ in range(rms.size):  # the settled set only grows: it stops within k rounds
        settled = rms <= limit
        ends = tuple(int(e) for e in np.flatnonzero(settled[1:] & settled[:-1]) + 2)
        if not ends or ends == seen:
            break
        seen = ends
        for e in ends:
            if e not in pairs:
                pairs[e] = estimate_noise(h, reference, inputs[e - 2 : e], outputs[e - 2 : e])
        # a pair's floor^2 and N(f) are one trial's noise power, so the pool is their mean
        floor_axes = np.sqrt(np.mean([pairs[e].floor_axes ** 2 for e in ends], axis=0))
        out = floor_axes, np.mean([pairs[e].noise_power for e in ends], axis=0)
        limit = max(limit, lowest + 3.0 * float(np.sqrt(np.sum(floor_axes**2))))
    return out


def _choose_cutoff(est: NoiseEstimate, n: int, dt: float) -> float:
    """The cut-off (Hz) that minimises learned noise plus removed target (module docstring).

    cost(f_c) = sum_{f < f_c} N(f) / m + sum_{f >= f_c} P(f); snapped to 12 values per
    decade, within [2 / T, 0.4 / dt].
    """
    freqs = fft.rfftfreq(n, dt)
    learned = np.concatenate([[0.0], np.cumsum(est.noise_power / est.trials)])
    removed = np.concatenate([np.cumsum(est.target_power[::-1])[::-1], [0.0]])
    k = int(np.argmin(learned + removed))
    lo, hi = 2.0 / (n * dt), 0.4 / dt
    f = freqs[min(k, freqs.size - 1)]
    snapped = 10 ** (np.round(np.log10(np.clip(f, lo, hi)) * _PER_DECADE) / _PER_DECADE)
    return float(np.clip(snapped, lo, hi))


@dataclass
class TrialLearner:
    """The next input of a trial series from its recorded trials (module docstring).

    Parameters
    ----------
    model : Machine
        The model the law is designed on (its impulse response and dt).
    reference : array, shape (n, d)
        Desired output relative to the start, on the model's grid.
    law : {"p", "pd", "pid", "norm-optimal"}
        As for :func:`primlib.ilc.learn` (gains from the model).
    noise_aware : bool
        Q-filter cut-off from the trials' spectra and the noise floor; False: the plain law
        (a fixed ``q_cutoff`` or none) learning from the last error.
    average : int
        Trials averaged per update (>= 1; 1 = the last error only).
    margin : float
        The stop rule's margin over the noise floor (> 0).
    q_cutoff : float, optional
        A fixed Q-filter cut-off in Hz (the plain law's; with ``noise_aware`` it is the
        cut-off used until two trials are recorded).

    Examples
    --------
    >>> learner = TrialLearner(m, reference)
    >>> step = learner.update(u[None], m.simulate(u)[None])  # one trial: (k, n, d) each
    >>> step.u.shape, step.converged
    ((201, 3), False)
    """

    model: object
    reference: np.ndarray
    law: str = "norm-optimal"
    noise_aware: bool = True
    average: int = 32
    margin: float = 0.1
    q_cutoff: float | None = None
    _laws: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise InputError(f"law: expected one of {', '.join(LAWS)}, got {self.law!r}")
        if isinstance(self.average, bool) or not isinstance(self.average, (int, np.integer)):
            raise InputError(f"average: expected an integer >= 1, got {self.average!r}")
        if self.average < 1:
            raise InputError(f"average: expected an integer >= 1, got {self.average}")
        if not (isinstance(self.margin, (int, float)) and 0 < self.margin < 10):
            raise InputError(f"margin: expected a number in (0, 10), got {self.margin!r}")
        ref = np.asarray(self.reference, dtype=float)
        if ref.ndim != 2 or ref.shape[1] != self.model.dim or not np.isfinite(ref).all():
            raise InputError(
                f"reference: expected a finite array (n, {self.model.dim}), got {ref.shape}"
            )
        self.reference = ref
        self._h = self.model.impulse_response(ref.shape[0])

    def _law(self, q_cutoff: float | None):
        """The prepared law (per-axis factorisations) for a cut-off, kept on this object."""
        key = None if q_cutoff is None else round(q_cutoff, 9)
        if key not in self._laws:
            q = None if q_cutoff is None else QFilter(q_cutoff, self.model.dt)
            spec = law_from_name(self.law)
            axes, _, _ = _prepare(self.model, self.reference.shape[0], spec, q)
            self._laws[key] = (axes, q)
        return self._laws[key]

    def _check_history(self, inputs, outputs) -> tuple[np.ndarray, np.ndarray]:
        u = np.asarray(inputs, dtype=float)
        y = np.asarray(outputs, dtype=float)
        shape = self.reference.shape
        if u.ndim != 3 or u.shape[1:] != shape or y.shape != u.shape or u.shape[0] < 1:
            raise InputError(
                f"trials: expected inputs and outputs of shape (k, {shape[0]}, {shape[1]}), "
                f"k >= 1, got {u.shape} and {y.shape}"
            )
        if not (np.isfinite(u).all() and np.isfinite(y).all()):
            raise InputError("trials: expected finite inputs and outputs, got NaN or inf")
        return u, y

    def window(self, inputs: np.ndarray, outputs: np.ndarray) -> int:
        """How many of the last trials to average (1 = the last only).

        Going back from the last trial, at most ``max(average, 2)`` trials, while moving a
        trial's error to the last input changes it by less than half the last trial's
        RMS error: a larger move would bring in more model error than averaging removes noise
        (on a real stage the model is only near, and friction is not in it).
        """
        k = inputs.shape[0]
        m_max = min(max(int(self.average), 2), k)
        du = inputs[-1][None] - inputs[k - m_max :]
        n, d = self.reference.shape
        flat = du.transpose(1, 0, 2).reshape(n, m_max * d)
        moved = _model_response(np.tile(self._h, (1, m_max)), flat).reshape(n, m_max, d)
        move_rms = np.sqrt(np.mean(np.sum(moved**2, axis=2), axis=0))  # (m_max,)
        last = np.sqrt(np.mean(np.sum((self.reference - outputs[-1]) ** 2, axis=1)))
        m = 1
        while m < m_max and move_rms[m_max - 1 - m] <= _MOVE * last:
            m += 1
        return m

    def noise(self, inputs, outputs) -> NoiseEstimate | None:
        """The noise estimate from the trials :meth:`window` picks (None for fewer than 2)."""
        u, y = self._check_history(inputs, outputs)
        m = self.window(u, y)
        if m < 2:
            return None
        return estimate_noise(self._h, self.reference, u[-m:], y[-m:])

    def cutoff(self, est: NoiseEstimate | None) -> float | None:
        """The Q-filter cut-off (Hz) of the next update: from the spectra when noise-aware
        and two trials are averaged, else the fixed ``q_cutoff``."""
        if self.noise_aware and est is not None:
            return _choose_cutoff(est, self.reference.shape[0], self.model.dt)
        return self.q_cutoff

    def _step(self, error: np.ndarray, u_last: np.ndarray, q_cutoff: float | None) -> np.ndarray:
        if self.noise_aware:
            axes, _ = self._law(None)
            new = _update(u_last, error, axes, None, [])
            return new if q_cutoff is None else QFilter(q_cutoff, self.model.dt, _Q_ORDER)(new)
        axes, q = self._law(q_cutoff)
        return _update(u_last, error, axes, q, [])

    def learned_fraction(self, est: NoiseEstimate, q_cutoff: float | None) -> float:
        """phi: the share of one trial's noise power that an update puts into the motion.

        The update's map from error to the model's output change, sum_f |g(f)|^2 N(f) /
        sum_f N(f), with g the response of an impulse error in mid-trial (axes averaged).
        """
        n, d = self.reference.shape
        key = ("phi", None if q_cutoff is None else round(q_cutoff, 9))
        if key not in self._laws:
            delta = np.zeros((n, d))
            delta[n // 2] = 1.0
            zero = np.zeros((n, d))
            moved = _model_response(self._h, self._step(delta, zero, q_cutoff))
            self._laws[key] = np.mean(np.abs(fft.rfft(moved, axis=0)) ** 2, axis=1)
        gain = self._laws[key]
        total = float(np.sum(est.noise_power))
        return float(np.sum(gain * est.noise_power) / total) if total > 0 else 0.0

    def update(self, inputs, outputs) -> TrialUpdate:
        """The next input from every recorded trial (inputs and measured outputs).

        Parameters
        ----------
        inputs, outputs : array, shape (k, n, d)
            Trials 0..k-1: inputs run and outputs measured (relative to the start).

        Returns
        -------
        TrialUpdate
        """
        u, y = self._check_history(inputs, outputs)
        est, converged, diverging = self.assess(u, y)
        q_cutoff = self.cutoff(est)
        error = self.reference - y[-1]
        if est is not None and self.average > 1:
            error = est.averaged
        return TrialUpdate(
            u=self._step(error, u[-1], q_cutoff),
            q_cutoff=q_cutoff,
            noise=est,
            rms=float(np.sqrt(np.mean(np.sum((self.reference - y[-1]) ** 2, axis=1)))),
            converged=converged,
            diverging=diverging,
        )

    def remaining(self, est: NoiseEstimate, averaged: int) -> float:
        """The true error's estimate of the last input: sqrt(R^2 + floor^2 phi / m_eff).

        Parameters
        ----------
        est : NoiseEstimate
        averaged : int
            m, the trials the update that made the last input averaged (1 for the plain
            law). Its learning gain g < 1 also keeps part of the noise of the updates
            before, averages of fewer trials: m_eff = (m + 1) / 2 (on the example stage's
            model this predicts the true error of trials 9 to 14 within 15 %,
            ``tests/test_ilc_noise.py``).
        """
        m_eff = (max(int(averaged), 1) + 1) / 2 if self.average > 1 else 1.0
        phi = self.learned_fraction(est, self.cutoff(est))
        return float(np.sqrt(est.repeatable_rms**2 + est.floor**2 * phi / m_eff))

    def _remaining_last(self, u: np.ndarray, y: np.ndarray, est: NoiseEstimate) -> float:
        # the update that made the last input averaged the window of the trials before it
        return self.remaining(est, self.window(u[:-1], y[:-1]) if u.shape[0] > 1 else 1)

    def input_error(self, inputs, outputs) -> float | None:
        """The true (noise-free) RMS error the last input run leaves, estimated from the
        trials: :meth:`remaining` (what the stop rule compares with the floor), the noise
        estimated from at least the last two trials; None for one trial (it cannot tell
        its error from its noise).

        It is what a stored signal is worth where it ran: the library keeps it as the
        primitive's ``error_rms`` (:func:`primlib.trials.finish`), so a warm start can weigh
        the stored signal against a model (noise ILC learned into the input shows here, not
        in the measured error alone).

        Parameters
        ----------
        inputs, outputs : array, shape (k, n, d)

        Returns
        -------
        float or None
        """
        u, y = self._check_history(inputs, outputs)
        return self._worth(u, y, u.shape[0], pooled_noise(self._h, self.reference, u, y))

    def _worth(self, u: np.ndarray, y: np.ndarray, upto: int, pooled) -> float | None:
        """input_error of trial ``upto - 1``'s input; ``pooled``: the noise pooled over all
        trials (:func:`pooled_noise` of ``u``, ``y``)."""
        if upto < 2:
            return None
        # at least the last two trials, moved to the last input with the model, even where
        # the update's window took one (a large last move): a worth needs a noise estimate
        m = max(self.window(u[:upto], y[:upto]), 2)
        est = estimate_noise(self._h, self.reference, u[upto - m : upto], y[upto - m : upto])
        if pooled is not None:
            # the noise is the machine's, not the trial's: every settled pair says what it
            # is (pooled_noise), where the last m alone are one or two draws
            floor_axes, noise = pooled
            est = replace(
                est,
                floor=float(np.sqrt(np.sum(floor_axes**2))),
                floor_axes=floor_axes,
                noise_power=noise,
            )
        return self._remaining_last(u[:upto], y[:upto], est)

    def best_input(self, inputs, outputs) -> tuple[int, float | None]:
        """(index, error): the trial whose measured RMS error is the lowest, and the true
        error its input is estimated to leave (:meth:`input_error` on the trials up to it).

        A law designed on a model can pass through its best input and then slowly diverge
        (an unmodelled resonance grows trial after trial above the model's band): a library
        keeps the best input a series ran, not the last (:func:`primlib.trials.finish`). On
        a noisy stage every trial's measured RMS carries the same noise, so the lowest
        still points at the best input.

        Parameters
        ----------
        inputs, outputs : array, shape (k, n, d)

        Returns
        -------
        (int, float or None)
        """
        u, y = self._check_history(inputs, outputs)
        return self._best(u, y, pooled_noise(self._h, self.reference, u, y))

    def _best(self, u: np.ndarray, y: np.ndarray, pooled) -> tuple[int, float | None]:
        best = int(np.argmin(self._measured_rms(y)))
        return best, self._worth(u, y, best + 1, pooled)

    def stored_input(self, inputs, outputs) -> tuple[np.ndarray, float | None, tuple[int, int]]:
        """(input, error, (k0, k1)): what a finished series stores -- the best trial's input
        (:meth:`best_input`; (k0, k1) = (best, best + 1)), or the mean of the inputs of the
        settled trials k0..k1-1 where that is estimated to leave less than ``MEAN_GAIN`` of
        it (:mod:`primlib.ilc._settled`: near the floor each trial's input carries a copy of
        the last trial's non-repeatable part, and their mean averages the copies out) --
        and the true error it is estimated to leave.

        Parameters
        ----------
        inputs, outputs : array, shape (k, n, d)

        Returns
        -------
        (array (n, d), float or None, (int, int))
        """
        u, y = self._check_history(inputs, outputs)
        pooled = pooled_noise(self._h, self.reference, u, y)
        best, worth = self._best(u, y, pooled)
        if worth is None or pooled is None:
            return u[best], worth, (best, best + 1)
        # the mean's estimate rests on r - G mean(u) = mean(e) + mean(n), a linear machine's
        # identity, and on a floor the model's error in the moved pairs can pass for: it must
        # be clearly better (``MEAN_GAIN``). Friction 5 %, no noise: means estimated at 0.5
        # and 0.63 of the best trial left as much or 4x more; the all-together series' means
        # are at 0.19-0.46 of their best trials (module notes of ._settled)
        sigma2 = float(np.sum(pooled[0] ** 2))
        run = settled_runs(self.reference, y, sigma2)
        if run is None or run[2] >= MEAN_GAIN * worth:
            return u[best], worth, (best, best + 1)
        k0, k1, err = run
        return u[k0:k1].mean(axis=0), err, (k0, k1)

    def _measured_rms(self, y: np.ndarray) -> np.ndarray:
        """Each trial's measured RMS tracking error (Euclidean over the axes), shape (k,)."""
        return trial_rms(self.reference, y)

    def assess(self, inputs, outputs) -> tuple[NoiseEstimate | None, bool, bool]:
        """(noise estimate, converged, diverging) after the last recorded trial.

        Converged: the true error's estimate of the last input (:meth:`remaining`) within
        ``margin`` times the noise floor, from at least 3 averaged trials. Diverging: the
        measured error grew over each of the last two trials by more than ``margin``
        times the floor (10 % without a floor).
        """
        u, y = self._check_history(inputs, outputs)
        est = self.noise(u, y)
        rms = self._measured_rms(y)
        floor = None if est is None else est.floor
        converged = False
        if est is not None and est.trials >= _MIN_VERDICT:
            converged = self._remaining_last(u, y, est) <= self.margin * est.floor
        diverging = False
        if len(rms) >= 3:
            step = self.margin * floor if floor is not None else _GROWTH * rms[-3]
            diverging = bool(rms[-1] - rms[-2] > step and rms[-2] - rms[-3] > step)
        return est, converged, diverging
