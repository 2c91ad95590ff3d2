"""The ripple's spatial frequency, searched for the grey-box fit (:mod:`._fit`): on a grid
over the band the data can show (half a period over the positions covered .. four samples a
period at the fastest motion; a quarter period apart), on the input residual
(:func:`_input_search`) and on the output error (:func:`_ripple_search`), cross-validation
choosing (:func:`ripple_choice`), and polished on the output error
(:func:`ripple_polish`)."""

from __future__ import annotations

import numpy as np
from scipy import optimize

from primlib.greybox._features import POSITION, TERMS, ripple_columns, ripple_grid
from primlib.greybox._lsq import RIDGE, fold_totals, rms, solve, standardised, through_model

__all__ = ["RIPPLE", "grid_step", "output_columns", "ripple_choice", "ripple_polish", "sse_batch"]

RIPPLE = [TERMS.index(t) for t in POSITION]  # the last columns: the others come before
_SEARCH_ROWS = 40_000  # rows the ripple-frequency grid is evaluated on
_GRID_MAX = 4000  # ripple frequencies tried at most
_BATCH = 64  # ripple frequencies scored per batch


def _ripple_part(pos: np.ndarray, step: np.ndarray, w: float) -> np.ndarray:
    """The ripple's two columns at ``w`` (:func:`~._features.ripple_columns`), 0 on rows of
    unknown position, shape (n, 2)."""
    known = np.isfinite(pos)
    cols = ripple_columns(np.where(known, pos, 0.0), step, w)
    return np.where(known[:, None], cols, 0.0)


def grid_step(span: float) -> float:
    """The ripple grid's spacing in w: a quarter period over the positions covered."""
    return np.pi / (4 * span)


def sse_batch(A, G00, b0, r2, rr, S: np.ndarray) -> np.ndarray:
    """A ripple search's in-sample SSE at each frequency of a batch at once: the
    ripple columns ``S`` (B, 2, r) of a batch of frequencies, their products with the base
    columns and the bordered normal matrices, solved batched (the grid has up to
    ``_GRID_MAX`` points)."""
    return _bordered(G00, b0, r2, S @ A, S @ S.transpose(0, 2, 1), S @ rr)


def _bordered(G00, b0, r2, SA: np.ndarray, SS: np.ndarray, Sr: np.ndarray) -> np.ndarray:
    """The SSE of least squares on the base columns and two ripple columns, from the normal
    equations' parts: the base's ``G00`` (p, p), ``b0`` (p,), ``r2``; per frequency (leading
    axes ...) the ripple's products ``SA`` (..., 2, p), ``SS`` (..., 2, 2), ``Sr`` (..., 2)."""
    p = G00.shape[-1]
    lead = SA.shape[:-2]
    G = np.empty((*lead, p + 2, p + 2))
    G[..., :p, :p] = G00
    G[..., :p, p:] = np.swapaxes(SA, -1, -2)
    G[..., p:, :p] = SA
    G[..., p:, p:] = SS
    b = np.concatenate([np.broadcast_to(b0, (*lead, p)), Sr], axis=-1)
    ridge = RIDGE * np.maximum(np.trace(G, axis1=-2, axis2=-1) / (p + 2), 1e-300)
    G[..., np.arange(p + 2), np.arange(p + 2)] += ridge[..., None]
    c = np.linalg.solve(G, b[..., None])[..., 0]
    return r2 - np.sum(c * b, axis=-1)


class _FoldSums:
    """The normal equations of a ripple search for the whole data and for each fold's
    training rows at once, from per-fold partial sums: rows in fold order (fold j the rows
    ``cuts[j]:cuts[j + 1]``), the base columns ``A`` standardised over all of them, target
    ``rr``. Objective 0 is all rows, objective 1 + j all rows but fold j's: a training set's
    sums are the other folds', so one pass over the rows scores a frequency for
    the whole data and every fold (six searches of the same rows before, one each)."""

    def __init__(self, A: np.ndarray, rr: np.ndarray, cuts: np.ndarray) -> None:
        self.A, self.rr = standardised(A)[0], rr
        parts = [slice(int(lo), int(hi)) for lo, hi in zip(cuts[:-1], cuts[1:], strict=True)]
        self.parts = parts
        G = np.stack([self.A[s].T @ self.A[s] for s in parts])
        b = np.stack([self.A[s].T @ rr[s] for s in parts])
        r2 = np.array([float(rr[s] @ rr[s]) for s in parts])
        self.G00, self.b0, self.r2 = fold_totals(G), fold_totals(b), fold_totals(r2)

    def sse(self, S: np.ndarray) -> np.ndarray:
        """SSE per objective and frequency of the batch ``S`` (B, 2, r), shape (1 + J, B)."""
        SA = np.stack([S[:, :, s] @ self.A[s] for s in self.parts])
        SS = np.stack([S[:, :, s] @ S[:, :, s].transpose(0, 2, 1) for s in self.parts])
        Sr = np.stack([S[:, :, s] @ self.rr[s] for s in self.parts])
        SA, SS, Sr = fold_totals(SA), fold_totals(SS), fold_totals(Sr)
        lead = (slice(None), None)
        return _bordered(self.G00[lead], self.b0[lead], self.r2[lead], SA, SS, Sr)


def _fold_layout(folds: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of nondecreasing ``folds``: the folds present, where each starts (J + 1 cuts), and
    per objective (all rows, then all but each fold) which rows it trains on (1 + J, r)."""
    labels, first = np.unique(folds, return_index=True)
    cuts = np.append(first, folds.size)
    train = np.vstack([np.ones(folds.size, bool), folds[None, :] != labels[:, None]])
    return labels, cuts, train


def _search_pairs(row: dict) -> tuple[np.ndarray, np.ndarray]:
    """Rows of whole pairs (a filter runs over a whole pair from rest), the pairs of each
    fold together (fold order, then pair order: a pair's rows are all of one fold, or with
    one pair its folds are contiguous blocks), and where each pair starts in that
    selection. Beyond ``_SEARCH_ROWS`` rows, each fold's pairs evenly through them, in
    proportion (the whole data's search and every fold's share the rows; before stop 47 each
    searched its own selection, so on such a bank the frequencies differ slightly)."""
    starts = row["starts"]
    sizes = np.diff(starts)
    fold = row["folds"][starts[:-1]]
    total = int(sizes.sum())
    picked = []
    for k in np.unique(fold):
        mine = np.flatnonzero(fold == k)
        if total > _SEARCH_ROWS:  # each fold its share, evenly through its pairs
            take = max(1, int(mine.size * _SEARCH_ROWS / total))
            mine = mine[np.unique(np.linspace(0, mine.size - 1, take).round().astype(int))]
        picked.append(mine)
    chosen = np.concatenate(picked)
    rows = np.concatenate([np.arange(starts[j], starts[j + 1]) for j in chosen])
    return rows, np.concatenate([[0], np.cumsum(sizes[chosen])])


def pair_rows(starts: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the pairs ``keep`` (bool per pair; pair j is rows starts[j]..starts[j+1])
    in their order, and where each kept pair starts among them."""
    sizes = np.diff(starts)
    rows = np.flatnonzero(np.repeat(keep, sizes))
    return rows, np.concatenate([[0], np.cumsum(sizes[keep])])


def _band(pos, step, known, fitted) -> tuple[float, float, float] | None:
    """(lowest, highest frequency, span) a ripple search covers: half a period over the
    positions covered .. four samples a period at the fastest motion; None where fewer
    than 16 ``fitted`` rows have a known position or the band is empty."""
    if np.sum(fitted) < 16:
        return None
    span = float(np.ptp(pos[known]))
    dx = float(np.percentile(np.abs(step[known]), 99))
    if span <= 0 or dx <= 0:
        return None
    w_lo, w_hi = np.pi / span, np.pi / (2 * dx)
    return None if w_hi <= w_lo else (w_lo, w_hi, span)


def _input_search(row: dict) -> tuple[float, np.ndarray]:
    """Best spatial frequency of a ripple by in-sample fit on the *input* residual beside
    the linear and friction columns (0 when none can be seen), on all rows and on each
    fold's training rows (:class:`_FoldSums`): one normal matrix, each candidate adding its
    two columns' products (on at most ``_SEARCH_ROWS`` evenly spread rows). Where friction
    the fit did not keep dominates the output error (issue 9's all-together y) it found the
    ripple (4.98 mm for 5) where :func:`_ripple_search` did not; which of the two is used
    is for cross-validation to say (:func:`ripple_choice`). Returns (the whole data's
    frequency, the folds present and each one's)."""
    every = max(1, row["r"].size // _SEARCH_ROWS)
    sel = np.arange(0, row["r"].size, every)
    sel = sel[np.argsort(row["folds"][sel], kind="stable")]
    F, r, pos, step = (row[k][sel] for k in ("F", "r", "pos", "step"))
    known = np.isfinite(pos)
    labels, cuts, train = _fold_layout(row["folds"][sel])
    bands = [_band(pos[t], step[t], known[t], known[t]) for t in train]
    if bands[0] is None:
        return 0.0, np.zeros((1, np.unique(row["folds"]).size))
    sums = _FoldSums(F[:, : RIPPLE[0]], r, cuts)
    x = np.where(known, pos, 0.0)

    def sse(ws: np.ndarray) -> np.ndarray:
        return sums.sse(ripple_grid(x, step, ws, known))

    ws = _grid_minima(sse, bands)
    return ws[0], _aligned(row, labels, np.array(ws[1:])[None], np.array([ws[0]]))


def _grid_minima(sse, bands: list, whole: tuple[int, ...] = (0,)) -> list[float]:
    """Per objective, the frequency of least ``sse`` on the grid over its band ``bands[v]``
    ((w_lo, w_hi, span), or None: 0), refined between its neighbours (``sse(ws)``: shape
    (objectives, len(ws)), objectives that share the grid's costly part).

    The grid is objective 0's (the whole data's: a quarter period over its span, the
    widest, from its lowest frequency), extended by the same step up to the highest
    frequency another objective's band reaches (a fold's training rows span no more, so
    none reaches below); each other objective takes the grid's points in its own band, at
    least as fine as its own grid would be. ``whole``: the objectives of the whole data (the
    others, folds, are refined tightly: :func:`_refined`)."""
    w_lo, w_hi, span = bands[0]
    count = max(min(int((w_hi - w_lo) / grid_step(span)) + 1, _GRID_MAX), 2)
    grid = np.linspace(w_lo, w_hi, count)
    top = max(b[1] for b in bands if b is not None)
    extra = min(int(np.ceil((top - w_hi) / (grid[1] - grid[0]))), _GRID_MAX - count)
    batches = [grid[k : k + _BATCH] for k in range(0, grid.size, _BATCH)]
    if extra > 0:
        more = w_hi + (grid[1] - grid[0]) * np.arange(1, extra + 1)
        batches += [more[k : k + _BATCH] for k in range(0, more.size, _BATCH)]
        grid = np.concatenate([grid, more])
    vals = np.concatenate([sse(ws) for ws in batches], axis=1)
    return [
        0.0 if band is None else _refined(sse, v, grid, vals[v], band, v not in whole)
        for v, band in enumerate(bands)
    ]


def _refined(sse, v: int, grid: np.ndarray, vals: np.ndarray, band, tight: bool) -> float:
    """Objective v's least ``vals`` among the grid's points in its ``band``, refined by a
    bounded scalar search between its neighbours there (the band itself when no point
    lies in it); ``tight``: to 1e-9 of the band's top, as :func:`ripple_polish` refines the
    model's own frequency.

    A fold's frequency is refined tightly: scipy's default tolerance, 1e-5 rad per unit
    absolute, is 0.01 rad of phase 1,000 units along, so each held-out primitive's error,
    and the cross-validated error per pair that a warm start weighs its stored signals
    against, moved with where the grid's points fell (on issue 9's ripple library, up to 16 %
    per pair when the folds' grids became the whole data's), while the model's own
    frequency is polished to 1e-9 and has no such error. The whole data's keeps the default:
    the polish refines it where it is used, and the model stays what it was."""
    inside = np.flatnonzero((grid >= band[0]) & (grid <= band[1]))
    opts = {"xatol": 1e-9 * float(band[1])} if tight else {}

    def one(w: float) -> float:
        return float(sse(np.array([w]))[v, 0])

    if inside.size == 0:
        res = optimize.minimize_scalar(one, bounds=band[:2], method="bounded", options=opts)
        return float(res.x)
    k = int(inside[np.argmin(vals[inside])])
    lo, hi = grid[max(k - 1, inside[0])], grid[min(k + 1, inside[-1])]
    if hi <= lo:
        return float(grid[k])
    res = optimize.minimize_scalar(one, bounds=(lo, hi), method="bounded", options=opts)
    return float(res.x) if res.fun <= vals[k] else float(grid[k])


def _ripple_search(
    row: dict, Fo: np.ndarray, ro: np.ndarray, colsets: list[list[int]]
) -> tuple[list[float], np.ndarray]:
    """Best spatial frequency of a ripple on the fit's own objective, the output error
    beside each of ``colsets``, on all rows and on each fold's training rows
    (:class:`_FoldSums`; 0 when none can be seen); the candidates' columns run through the
    model once for all of them.

    Each candidate's sin and cos columns are run through the axis's model like the other
    regressors (whole pairs, at most ``_SEARCH_ROWS`` rows): the search scored them on the
    input residual before, which weighs an input error by its size, not by the tracking
    error it makes, so a high spatial frequency -- a high temporal one at the axis's speed,
    where the input residual holds what the inverse and ILC left -- could win there: issue
    9's ripple setting, z (one way, 6.6 periods over 33 mm), found 3.51 rad/mm for the
    machine's 1.257 on one library learned anew (the machine's frequency not among the
    input side's 30 deepest minima, though on output error the clear best: 0.0085 against
    0.047 mm and more), so the ripple was dropped and rotated paths went from 1e-4 to
    0.05-0.19 mm. On output error the grid costs ~0.1 s an axis there (545 frequencies).
    Returns (per column set the whole data's frequency, per column set and fold present
    each fold's).
    """
    idx, st = _search_pairs(row)
    pos, step = row["pos"][idx], row["step"][idx]
    known = np.isfinite(pos)
    labels, cuts, train = _fold_layout(row["folds"][idx])
    # a fold's band: over the pairs it trains on (with one pair, the whole pair: a pair's
    # held-out rows are run, not fitted), its fitted rows those it trains on
    pair_of = np.repeat(np.arange(st.size - 1), np.diff(st))
    bands = []
    for t in train:
        runs = np.isin(pair_of, pair_of[t])
        bands.append(_band(pos[runs], step[runs], known[runs], (known & t)[runs]))
    m, j = len(colsets), labels.size
    if bands[0] is None:
        return [0.0] * m, np.zeros((m, np.unique(row["folds"]).size))
    x, rr = np.where(known, pos, 0.0), ro[idx]
    sums = [_FoldSums(Fo[np.ix_(idx, cols)], rr, cuts) for cols in colsets]

    def sse(ws: np.ndarray) -> np.ndarray:
        S = ripple_grid(x, step, ws, known)  # (B, 2, r), rows of unknown position 0
        So = through_model(S.reshape(-1, S.shape[2]).T, st, *row["tf"]).T.reshape(S.shape)
        return np.concatenate([s.sse(So) for s in sums])

    whole = tuple(range(0, m * (1 + j), 1 + j))
    ws = np.array(_grid_minima(sse, bands * m, whole)).reshape(m, 1 + j)
    return ws[:, 0].tolist(), _aligned(row, labels, ws[:, 1:], ws[:, 0])


def _aligned(row: dict, labels: np.ndarray, ws: np.ndarray, whole: np.ndarray) -> np.ndarray:
    """Per-fold frequencies ``ws`` (column set by fold ``labels``, the folds a search's rows
    hold) on every fold of ``row`` in increasing order; a fold with no rows among them
    trained on all of them: the whole data's frequency ``whole`` (per column set)."""
    every = np.unique(row["folds"])
    out = np.repeat(np.asarray(whole, float)[:, None], every.size, axis=1)
    out[:, np.searchsorted(every, labels)] = ws
    return out


def ripple_polish(
    row: dict, Fo: np.ndarray, ro: np.ndarray, cols: list[int], w: float, step: float
) -> float:
    """The ripple's frequency refined on the fit's own objective, the output error.

    :func:`_input_search` scores frequencies on the input residual (cheap, one normal
    matrix), :func:`_ripple_search` on the output error of a subset of the rows; their
    minimum sits a little off the full output error's, and a relative error of 5e-5 in
    ``w`` is 0.01 rad of phase 200 mm along the table: with the coefficients refitted to
    it, 0.3-0.5 % of the ripple left in the model-only input (issue 9's ripple setting).
    Searched within one grid ``step`` of ``w``.
    """

    def sse(x: float) -> float:
        G = output_columns(row, Fo, x)
        return float(np.sum((ro - G @ solve(G, ro, cols)) ** 2))

    res = optimize.minimize_scalar(
        sse, bounds=(w - step, w + step), method="bounded", options={"xatol": 1e-9 * w}
    )
    return float(res.x) if res.fun < sse(w) else w


def output_columns(row: dict, Fo: np.ndarray, w: float) -> np.ndarray:
    """``Fo`` with the ripple columns at ``w``, run through the model like the others."""
    G = through_model(_ripple_part(row["pos"], row["step"], w), row["starts"], *row["tf"])
    return np.concatenate([Fo[:, : RIPPLE[0]], G], axis=1)


def ripple_choice(row: dict, Fo: np.ndarray, ro: np.ndarray, colsets: list[list[int]]):
    """Per column set of ``colsets``, (frequency, cross-validated error) of the ripple
    search beside it, on the input residual (:func:`_input_search`) or on the output error
    (:func:`_ripple_search`), whichever predicts the held-out primitives better; (0, None)
    where neither sees one. Neither wins everywhere on issue 9's libraries: on output error
    the ripple setting's z where the input side found 3.51 rad/mm for 1.257; on the input
    side the all-together y, whose output error friction the fit did not keep dominates
    (4.98 mm found, none on output). Each search gives the whole data's frequency and each
    fold's in one pass over the rows; the input side gives every column set the same one."""
    m = len(colsets)
    best: list[tuple[float, np.ndarray | None]] = [(0.0, None)] * m
    for search in (
        lambda: _repeated(*_input_search(row), m),
        lambda: _ripple_search(row, Fo, ro, colsets),
    ):
        ws, per_fold = search()
        if max(ws) <= 0:
            continue
        errs = _cv_ripple(row, Fo, ro, colsets, per_fold)
        for v, (w, err) in enumerate(zip(ws, errs, strict=True)):
            if w > 0 and (best[v][1] is None or rms(err) < rms(best[v][1])):
                best[v] = (w, err)
    return best


def _repeated(w: float, per_fold: np.ndarray, m: int) -> tuple[list[float], np.ndarray]:
    """The input side's one frequency (and each fold's) for each of ``m`` column sets."""
    return [w] * m, np.repeat(per_fold, m, axis=0)


def _cv_ripple(
    row: dict, Fo: np.ndarray, ro: np.ndarray, colsets: list[list[int]], per_fold: np.ndarray
) -> list[np.ndarray]:
    """Per column set, the cross-validated error with a ripple whose frequency each fold
    searched on its own training rows (``per_fold``: column set by fold, the folds in
    increasing order): a frequency chosen on all the data would fit structure in the
    held-out rows too (with few primitives, residual structure in time looks like a short
    pitch). Each frequency's columns are formed once a fold (the input side gives every
    column set the same one)."""
    folds = row["folds"]
    errs = [np.empty_like(ro) for _ in colsets]
    for f, k in enumerate(np.unique(folds)):
        test = folds == k
        train = ~test
        columns: dict[float, np.ndarray] = {}
        for cols, w, err in zip(colsets, per_fold[:, f], errs, strict=True):
            if w > 0 and w not in columns:
                columns[w] = output_columns(row, Fo, w)
            G, use = (Fo, cols) if w <= 0 else (columns[w], cols + RIPPLE)
            c = solve(G[train], ro[train], use)
            err[test] = ro[test] - G[test] @ c
    return errs
