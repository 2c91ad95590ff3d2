"""The pipeline's one owner: match -> warm start -> learn -> store back, over one store.

:class:`WarmStarter` reads a machine's bank from a :class:`~primlib.store.Store`, hands it to
the matcher (:func:`primlib.match.match_path`), carries the matched primitives' stored
inputs over (:func:`primlib.splice.splice`) into a first-iteration input, runs ILC from it
(:func:`~primlib.pipeline.learn_on_model`), and stores the converged input back. Its caches
are attributes of the object, never module globals: the search index of each machine's bank
(a :class:`~primlib.match.BankIndex`) and the refined models (one least-squares fit per
machine model and primitive set). Data flows one way: the store never calls back.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import replace
from os import PathLike
from typing import Any

import numpy as np

from primlib._errors import NoMatchError
from primlib.greybox import GreyBox, fit_greybox, model_residual, polish, refit_greybox
from primlib.match import BankIndex, Match, default_eps, match_path
from primlib.nurbs import Trajectory
from primlib.pipeline._fitted import KeptModels, fit_key
from primlib.pipeline._greywarm import (
    _transformed,
    bank_pairs,
    choose_per_segment,
    linear_parts,
    pair_errors,
    pairs_on,
    ripple_shifts,
)
from primlib.pipeline._learn import LearnRun, check_law, learn_on_model
from primlib.pipeline._warm import WarmStart, stored_signals
from primlib.plant import Machine
from primlib.splice import Correction, RefinedModel, refine_machine, splice
from primlib.store import Bank, Store, check_origin

__all__ = ["WarmStarter", "as_trajectory"]

# primitives a refinement fits on (:func:`refine_ids`), and up to which the models are
# fitted on every primitive (:func:`model_count`)
_REFINE_MAX = 24
_GROWTH = 1.25  # beyond, the models are fitted again when the library has grown by this factor
_REFINE_SAMPLES = 48_000  # samples a refinement fits on, about (24 primitives of 2,000)


def model_count(k: int) -> int:
    """How many of a bank's ``k`` primitives (the oldest) its models are fitted on: ``k`` up
    to 24, then the largest of 24, 30, 38, 48, ... (each ``ceil(1.25 x)`` the last) not
    above ``k``: between two of those the models stay what they are, so a growing library
    fits them O(log k) times, not k times."""
    n = int(k)
    if n <= _REFINE_MAX:
        return max(n, 0)
    c = _REFINE_MAX
    while math.ceil(c * _GROWTH) <= n:
        c = math.ceil(c * _GROWTH)
    return c


def refine_ids(ids: Sequence[int], sizes: Sequence[int] | None = None) -> list[int]:
    """The ids a refinement fits on, sorted: all of ``ids`` while they hold about
    :data:`_REFINE_SAMPLES` samples (``sizes``: per id; unknown, 24 at most), else as many as
    do (never fewer than 24) spread evenly through them, so that every axis and speed the
    library holds has its say.

    Spread, not the primitives a path matched: the same model whichever path asks (the
    matched ones suited their path a little better -- 30 stage loops, 1.05x the error with
    24 spread -- but made every new path fit it again). As many as the budget holds, not
    24: on 60 loops of 401 samples the worst of six new paths was 0.034 mm refined on 24,
    0.026 on all 60 (0.021 on each path's matched ones), the median 0.0138 / 0.0140
    (0.0143)."""
    order = np.argsort(np.asarray(ids, dtype=np.int64), kind="stable")
    ids = [int(ids[j]) for j in order]
    k = len(ids)
    if sizes is None:
        m = min(k, _REFINE_MAX)
    else:
        mean = float(np.mean(np.asarray(sizes, dtype=float))) if k else 1.0
        m = min(k, max(_REFINE_MAX, int(_REFINE_SAMPLES // max(mean, 1.0))))
    if m >= k:
        return ids
    pick = np.unique(np.linspace(0, k - 1, m).round().astype(int))
    return [ids[j] for j in pick]


def as_trajectory(path: Trajectory | str | PathLike) -> Trajectory:
    """The path itself, or a path CSV file read and fitted."""
    if isinstance(path, Trajectory):
        return path
    return Trajectory.from_csv(path)


def _refined_note(machine: Machine, model: RefinedModel) -> str:
    modes = np.zeros((machine.dim, 2)) if model.mode is None else model.mode
    th = ", ".join(
        f"{a}: gain {g:.4g}, time scale {c:.4g}, lag {tau * 1e3:.3g} ms"
        + (f", mode {f:.4g} Hz (damping {z:.3g})" if f > 0 else "")
        + (f" (at its bound: {edge}; the pairs do not determine this axis)" if edge else "")
        for a, (g, c, tau), (f, z), edge in zip(
            machine.axes, model.theta, modes, model.at_bound or ("",) * machine.dim, strict=True
        )
    )
    return f"model refined on the library's stored pairs: {th}"


class WarmStarter:
    """Match, warm start and learn against the primitives of one store.

    Parameters
    ----------
    store : Store
        Where the machines and primitives are read (and learned inputs stored).
    refine_cache : int, default 16
        Refined models kept (least recently used dropped first).

    Attributes
    ----------
    greyboxes : OrderedDict
        The grey-box models (:func:`primlib.greybox.fit_greybox` on all of a machine's
        stored pairs), keyed like ``refined``.
    refined : OrderedDict
        The refined-model cache: :func:`~primlib.pipeline._fitted.fit_key` (machine
        definition, primitive ids, options, code) -> RefinedModel. Ids are never reused
        within a store and stored primitives never change, so the key names the data.
    kept : KeptModels
        The same models kept in the library file, read back by the next process.
    indexes : dict
        Machine name -> the :class:`~primlib.match.BankIndex` of its current bank. The
        store hands out the same Bank object while a machine's primitives are unchanged,
        so an index is rebuilt exactly when they change.
    """

    def __init__(self, store: Store, *, refine_cache: int = 16) -> None:
        self.store = store
        self.refine_cache = int(refine_cache)
        self.refined: OrderedDict[str, RefinedModel] = OrderedDict()
        self.greyboxes: OrderedDict[str, GreyBox] = OrderedDict()
        self.indexes: dict[str, BankIndex] = {}
        self.kept = KeptModels(store)

    def index(self, machine: str) -> BankIndex:
        """The search index of the machine's primitives, kept while they are unchanged."""
        bank = self.store.bank(machine)
        hit = self.indexes.get(machine)
        if hit is None or hit.bank is not bank:
            hit = self.indexes[machine] = BankIndex(bank)
        return hit

    # ------------------------------------------------------------------ match
    def match(
        self, path: Trajectory | str, machine: str, eps: float | None = None, **kw: Any
    ) -> Match:
        """Cut ``path`` into segments matching the machine's primitives.

        Parameters
        ----------
        path : Trajectory or str
            The new path (a CSV file name is read).
        machine : str
        eps : float, optional
            Kabsch RMSD tolerance (user units, > 0); default
            :func:`primlib.match.default_eps` of the path.
        **kw
            ``rotation``, ``time_scale``, ``min_step``, ``min_segment``, ``options`` of
            :func:`primlib.match.match_path`.

        Returns
        -------
        Match
        """
        traj = as_trajectory(path)
        e = default_eps(traj) if eps is None else eps
        return match_path(self.index(machine), traj, eps=e, **kw)

    # ------------------------------------------------------------------ refine
    def refined_model(
        self,
        machine: Machine,
        bank: Bank,
        gb: GreyBox | None = None,
        *,
        modes: bool = True,
    ) -> RefinedModel:
        """The model refined on the bank's stored pairs: all of them while they hold about
        48,000 samples, else as many as do (at least 24) spread evenly through the bank in
        id order (:func:`refine_ids`).

        Whichever path asks, the same pairs: a machine is one machine, and a choice that
        followed the path's matched primitives (as before stop 46) made every new path on a
        library of more than 24 primitives pay its own refinement, 5-8 s on 1,000. With a
        grey-box model ``gb`` the fit sees the stored inputs' linear parts (friction, ripple
        and bias taken out, and the rows their paths do not determine replaced:
        :meth:`~primlib.greybox.GreyBox.clean`), so those do not drive the linear model's
        gain, time constant and lag. ``modes``: a structural mode is searched beside them
        (:func:`~primlib.splice.refine_machine`). ``bank`` is the one the models are fitted
        on (:meth:`model_bank`). Cached on this object, and kept in the library
        (:class:`KeptModels`).
        """
        all_ids = [int(i) for i in np.asarray(bank.ids)]
        # in id order: the set decides the model (in match order a friction 5 % library's
        # refined model, and the grey-box fitted beside it, differed in the 8th digit with
        # the first path a process asked for)
        chosen = refine_ids(all_ids, np.diff(np.asarray(bank.offsets)))
        opts = {"chosen": chosen, "greybox": gb is not None, "modes": modes}
        # the whole bank is in the key: beside a grey-box model the fit depends on every pair
        key = fit_key("refined", machine, all_ids, **opts)

        def fit() -> RefinedModel:
            if gb is None:
                stored = stored_signals(bank, chosen, versions=False)
            else:
                stored = linear_parts(gb, bank, chosen, versions=False, clean=True)
            pairs = [(s.signal, s.points - s.points[0]) for s in stored.values()]
            return refine_machine(machine, pairs, modes=modes)

        return self._cached(self.refined, "refined", machine.name, all_ids, key, fit)

    def greybox(self, machine: Machine, bank: Bank, *, linear: bool = True) -> GreyBox:
        """The grey-box model fitted to all of ``bank``'s stored pairs (cached; ``bank`` the
        one the models are fitted on, :meth:`model_bank`); ``linear``: with the linear terms
        (not beside a refined model)."""
        bank_ids = [int(i) for i in np.asarray(bank.ids)]
        key = fit_key("greybox", machine, bank_ids, linear=linear)

        def fit() -> GreyBox:
            pairs = bank_pairs(bank)
            if not pairs:
                raise NoMatchError(
                    f"machine {machine.name!r} has no stored primitives to fit a model to"
                )
            gb = fit_greybox(machine, pairs, linear=linear)
            if not linear:  # beside a refined model: refitted through its own run
                gb = refit_greybox(gb, pairs, errors=pair_errors(bank))
            return gb

        return self._cached(self.greyboxes, "greybox", machine.name, bank_ids, key, fit)

    def model_bank(self, bank: Bank) -> Bank:
        """The primitives the machine's models are fitted on: the oldest
        :func:`model_count` of ``bank`` -- all of them up to 24, then the library as it
        stood when it last grew by a quarter (24, 30, 38, 48, ... primitives).

        Fitted on every primitive, the models were fitted again after every one a library
        took in: on 1,000 primitives each warm start after an ingest paid 11 s, and under
        ``primlib serve``'s steady ingests every warm start did (p50 35 s where one takes
        0.35 s). A primitive not in the fit is still matched and spliced like any other; its
        pair's cross-validated error is unknown (NaN) to the warm start's choice, as for a
        pair the fit left out.
        """
        return bank.head(model_count(len(bank)))

    def _cached(self, cache: OrderedDict, kind: str, name: str, ids, key: str, fit):
        """``cache[key]``, else the model kept in the library or ``fit()``
        (:meth:`KeptModels.get`), kept in ``cache`` (least recently used dropped first)."""
        hit = cache.get(key)
        if hit is None:
            hit = cache[key] = self.kept.get(kind, name, ids, key, fit)
        cache.move_to_end(key)
        while len(cache) > self.refine_cache:
            cache.popitem(last=False)
        return hit

    def fit_models(self, machine: str) -> tuple[RefinedModel | None, GreyBox, str]:
        """The models a warm start on ``machine`` uses, fitted now or read where kept.

        Returns
        -------
        (refined model or None, grey-box model, note)
            The refined model is None for a machine with feedback (not refined); the note
            says what the refinement found. Every warm start on the machine uses these
            two until the library has grown by a quarter (:meth:`model_bank`).

        Raises
        ------
        NotFoundError, NoMatchError
            An unknown machine; a machine without primitives.
        """
        m = self.store.machine(machine)
        model, gb, _ = self._models(m, self.store.bank(machine), [], True, True)
        return model, gb, "" if model is None else _refined_note(m, model)

    def model_input(
        self, path: Trajectory | str, machine: str, origin: Any = None
    ) -> tuple[np.ndarray, GreyBox]:
        """The model-only input of a path: the grey-box model's inverse, no stored signals.

        Parameters
        ----------
        path : Trajectory or str
        machine : str
        origin : array of shape (d,), optional
            Where the path starts on the machine (absolute); without it the
            position-dependent terms (ripple) are left out.

        Returns
        -------
        (u, GreyBox)

        Raises
        ------
        NoMatchError
            The machine has no primitives to fit a model to.
        """
        traj = as_trajectory(path)
        m = self.store.machine(machine)
        origin = check_origin("origin", origin, m.axes)
        _, gb, _ = self._models(m, self.store.bank(machine), [], True, True)
        ref = traj.sample(m.dt)
        ref = ref - ref[0]
        return polish(gb, ref, gb.inverse(ref, origin), origin)[0], gb

    # ------------------------------------------------------------------ warm start
    def warm_start(
        self,
        path: Trajectory | str,
        machine: str,
        eps: float | None = None,
        *,
        band: float | None = None,
        method: str = "auto",
        refine: bool = True,
        correction: Correction | None = None,
        match: Match | None = None,
        origin: Any = None,
        greybox: bool = True,
        modes: bool = True,
        **kw: Any,
    ) -> WarmStart:
        """First-iteration ILC input for a new path from the machine's primitives.

        Parameters
        ----------
        path : Trajectory or str
            The new path (a CSV file name is read).
        machine : str
            Machine name; only its primitives are used.
        eps : float, optional
            RMSD tolerance of the match (user units, > 0); default
            :func:`primlib.match.default_eps` of the path.
        band, method : optional
            Transition band width (s) and time-scaling method of :func:`primlib.splice.splice`.
        refine, modes : bool
            Transform on the model refined on the stored pairs (:meth:`refined_model`);
            ``modes``: with a structural mode per axis where the pairs show one.
        correction : Correction, optional
            Residual correction of :func:`primlib.splice.splice` (default
            :class:`~primlib.splice.ErrorCorrection`; others: ``benchmarks/_ablations.py``).
        match : Match, optional
            A match already computed for this path and machine.
        origin : array of shape (d,), optional
            Where the path starts on the machine (absolute); ripple terms are evaluated
            there. None: unknown, left out.
        greybox : bool
            Split the stored signals by the machine's grey-box model: the linear part
            carried by superposition, friction, ripple and bias re-evaluated on the new
            motion, per segment that or the model-only input (``WarmStart.model_u``),
            whichever predicts less error. False: spliced whole (the paper's method).
        **kw
            Passed to :meth:`match`.

        Returns
        -------
        WarmStart

        Raises
        ------
        NoMatchError, NotFoundError
            The machine has no primitives; an unknown machine.
        """
        traj = as_trajectory(path)
        m = self.store.machine(machine)
        origin = check_origin("origin", origin, m.axes)
        if match is None:
            match = self.match(traj, machine, eps, **kw)
        ids = sorted({s.primitive for s in match.segments if s.primitive is not None})
        bank = self.store.bank(machine)
        model, gb, stored = self._models(m, bank, ids, refine, greybox, modes)
        pts = traj.sample(m.dt)
        res = splice(
            m if model is None else model.machine,
            pts,
            traj.duration,
            match.segments,
            stored,
            band=band,
            method=method,
            inverse_machine=m,
            correction=correction,
        )
        if gb is None:
            return _warm_start_result(res, m, match, model)
        return _grey_result(res, m, match, model, gb, bank, pts, origin)

    def _models(self, m: Machine, bank: Bank, ids, refine: bool, greybox: bool, modes=True):
        """(refined model or None, grey-box model or None, the stored signals to splice).

        The grey-box terms are fitted beside the nominal model, the linear model is refined
        on what they leave of the stored inputs, and the nonlinear terms are fitted again
        beside the refined model; the splice then carries the stored inputs' linear parts.
        """
        gb = model = None
        fit_on = self.model_bank(bank)
        if greybox:
            gb = self.greybox(m, fit_on)
        if refine and (ids or gb is not None) and not m.feedback:
            model = self.refined_model(m, fit_on, gb, modes=modes)
            if gb is not None:
                gb = self.greybox(model.machine, fit_on, linear=False)
        if gb is not None:
            gb = pairs_on(gb, fit_on, bank)
        if not ids:
            return model, gb, {}
        if gb is None:
            return model, gb, stored_signals(bank, ids)
        return model, gb, linear_parts(gb, bank, ids)

    # ------------------------------------------------------------------ learn
    def learn(
        self,
        path: Trajectory | str,
        machine: str,
        *,
        cold: bool = False,
        iterations: int = 20,
        eps: float | None = None,
        band: float | None = None,
        law: str = "norm-optimal",
        tol: float | None = None,
        contour: bool = True,
        origin: Any = None,
        progress: Callable[[int, int, int], None] | None = None,
    ) -> LearnRun:
        """Warm start (unless ``cold``), then ILC on the machine's model.

        Parameters
        ----------
        path : Trajectory or str
        machine : str
        cold : bool
            Start from zero instead of the warm start.
        iterations : int
            ILC trials at most.
        eps : float, optional
            Match tolerance (default :func:`primlib.match.default_eps`).
        band : float, optional
            Transition band width, seconds.
        law : str
            One of :data:`primlib.pipeline.LAWS`.
        tol : float, optional
            Stop when the RMS error falls below this (user units).
        contour : bool
            Also compute the RMS contour error per trial.
        origin : array of shape (d,), optional
            Where the path starts on the machine (absolute), for the warm start.
        progress : callable, optional
            The match's ``progress(done, total, segments)`` (:func:`primlib.match.match_path`).

        Returns
        -------
        LearnRun
            Where the machine has no primitives (or nothing to start from), the run starts
            from zero and says so in ``notes``.
        """
        traj = as_trajectory(path)
        m = self.store.machine(machine)
        check_law(law, m)
        pts = traj.sample(m.dt)
        ref = pts - pts[0]
        notes: list[str] = []
        ws = None
        if not cold:
            try:
                kw = {} if progress is None else {"progress": progress}
                ws = self.warm_start(traj, machine, eps, band=band, origin=origin, **kw)
            except NoMatchError as exc:
                notes.append(f"no warm start ({exc}); starting from zero")
        res = learn_on_model(
            m,
            ref,
            None if ws is None else ws.u,
            law=law,
            iterations=int(iterations),
            tol=tol,
            contour=contour,
        )
        crms = None if res.rms_contour is None else [float(x) for x in res.rms_contour]
        t = np.arange(pts.shape[0]) * m.dt
        return LearnRun(m, ref, t, ws, res, crms, tuple(notes))


def _grey_result(res, m, match, model, gb, bank, pts, origin) -> WarmStart:
    """The WarmStart with the grey-box model: nonlinear terms added, chosen per segment
    (``pts``: the path's samples in the frame it was matched in)."""
    ref = pts - pts[0]
    u_lin, lin, non = gb.terms(ref, origin, gb.linear_inverse(ref))
    model_u, (before, after) = polish(gb, ref, u_lin + lin + non, origin)
    # what the model-only input misses where the model is the machine: the polished input's
    # own error on the model where it was polished (it stood for the gap, and more: on an
    # in-place path of a friction 5 % library, seed 11, the polish left 2.2e-5 mm on the
    # model where the gap said 1e-7, and the warm start took the model-only input, 2.2e-5 on
    # the machine, over a stored signal of 4.5e-7); else the linear inverse's gap
    gap = model_residual(gb, ref, model_u, origin) if np.isfinite(after) else None
    gap = gb.inverse_gap(ref, u_lin) if gap is None else gap
    u, choices, predicted, shares = choose_per_segment(
        gb, bank, res.segments, res.sample_segment, res.u + non, model_u, gap,
        ripple_shifts(gb, bank, res.segments, origin, pts[0]),
        nominal=model is None,
    )  # fmt: skip
    base = _warm_start_result(res, m, match, model)
    used = [
        _choice_text(c, p, w, seg)
        for c, p, w, seg in zip(choices, predicted, shares, res.segments, strict=True)
    ]
    notes = (*base.notes, f"grey-box model of the machine: {gb.describe()}", *gb.notes)
    if np.isfinite(before):
        notes += (
            f"model-only input corrected on the grey-box model run as a machine (stick and "
            f"reversals within a sample): its error on the model {before:.3g} -> {after:.3g}",
        )
    return replace(
        base,
        u=u,
        notes=notes,
        model_u=model_u,
        greybox=gb,
        choices=choices,
        predicted=tuple(_mixed(p, w) for p, w in zip(predicted, shares, strict=True)),
        weights=shares,
        sources=tuple(f"{s}; {c}" for s, c in zip(base.sources, used, strict=True)),
    )


def _mixed(predicted: tuple[float, float], share: float) -> float:
    """The predicted error of a segment's input: of the one kept, or of the mix of two
    independent errors, sqrt(w^2 s^2 + (1 - w)^2 m^2)."""
    stored, model = predicted
    if share == 0.0:
        return model
    if share == 1.0:
        return stored
    return float(np.hypot(share * stored, (1.0 - share) * model))


def _choice_text(choice: str, predicted: tuple[float, float], share: float, seg) -> str:
    """Why a segment uses what it uses, in one clause."""
    stored, model = predicted
    if not np.isfinite(stored):
        why = "nothing stored matched"
        if seg.primitive is not None:
            why = "rotated or time-scaled, and the library records no stored signal's worth"
        return f"model-only input ({why}; predicted output error {model:.3g})"
    what = {
        "stored": "stored signal carried over",
        "model": "model-only input",
        "blend": f"{share:.2f} stored signal + {1 - share:.2f} model-only input",
    }[choice]
    return (
        f"{what} (predicted output error: stored {stored:.3g}, model-only {model:.3g}; "
        f"{'rotated or time-scaled' if _transformed(seg) else 'in place or translated'})"
    )


def _warm_start_result(res, m: Machine, match: Match, model) -> WarmStart:
    """The WarmStart of a splice result ``res`` on machine ``m`` (``model``: refined or None)."""
    return WarmStart(
        u=res.u,
        t=np.arange(res.u.shape[0]) * m.dt,
        match=match,
        bands=res.bands,
        sample_segment=res.sample_segment,
        sources=res.sources,
        methods=res.methods,
        notes=res.notes if model is None else (*res.notes, _refined_note(m, model)),
        model=model,
        spliced=res.spliced,
    )
