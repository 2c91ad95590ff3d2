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
from primlib.greybox._lsq import RIDGE, rms, solve, standardised, through_model

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
    AS = (S @ A).transpose(0, 2, 1)  # (B, p, 2)
    SS = S @ S.transpose(0, 2, 1)
    p = A.shape[1]
    G = np.empty((S.shape[0], p + 2, p + 2))
    G[:, :p, :p] = G00
    G[:, :p, p:] = AS
    G[:, p:, :p] = AS.transpose(0, 2, 1)
    G[:, p:, p:] = SS
    b = np.concatenate([np.broadcast_to(b0, (S.shape[0], p)), S @ rr], axis=1)
    ridge = RIDGE * np.maximum(np.trace(G, axis1=1, axis2=2) / (p + 2), 1e-300)
    G[:, np.arange(p + 2), np.arange(p + 2)] += ridge[:, None]
    c = np.linalg.solve(G, b[..., None])[..., 0]
    return r2 - np.sum(c * b, axis=1)


def _search_pairs(row: dict, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the whole pairs with a row in ``keep`` (a filter runs over a whole pair from
    rest), evenly through them up to ``_SEARCH_ROWS`` rows, and where each starts in that
    selection."""
    starts = row["starts"]
    sizes = np.diff(starts)
    chosen = np.flatnonzero(np.add.reduceat(keep.astype(int), starts[:-1]) > 0)
    total = int(sizes[chosen].sum())
    if total > _SEARCH_ROWS:
        take = max(1, int(chosen.size * _SEARCH_ROWS / total))
        chosen = chosen[np.unique(np.linspace(0, chosen.size - 1, take).round().astype(int))]
    pick = np.zeros(sizes.size, bool)
    pick[chosen] = True
    return pair_rows(starts, pick)


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


def _normal(A: np.ndarray, rr: np.ndarray):
    """A ripple search's base: the columns ``A`` standardised (those of no size dropped,
    :func:`~._lsq.standardised`), their normal matrix, their products with ``rr`` and
    ``rr``'s squared norm."""
    A = standardised(A)[0]
    return A, A.T @ A, A.T @ rr, float(rr @ rr)


def _input_search(row: dict, keep: np.ndarray | None = None) -> float:
    """Best spatial frequency of a ripple by in-sample fit on the *input* residual beside
    the linear and friction columns (0 when none can be seen): one normal matrix, each
    candidate adding its two columns' products (on at most ``_SEARCH_ROWS`` evenly spread
    rows). Where friction the fit did not keep dominates the output error (issue 9's
    all-together y) it found the ripple (4.98 mm for 5) where :func:`_ripple_search` did
    not; which of the two is used is for cross-validation to say (:func:`ripple_choice`)."""
    keep = np.ones(row["r"].size, bool) if keep is None else keep
    F, r, pos, step = (row[k][keep] for k in ("F", "r", "pos", "step"))
    known = np.isfinite(pos)
    band = _band(pos, step, known, known)
    if band is None:
        return 0.0
    w_lo, w_hi, span = band
    every = max(1, F.shape[0] // _SEARCH_ROWS)
    A, x, rr = F[::every, : RIPPLE[0]], np.where(known, pos, 0.0)[::every], r[::every]
    dxs, on = step[::every], known[::every]
    A, G00, b0, r2 = _normal(A, rr)

    def sse(ws: np.ndarray) -> np.ndarray:
        return sse_batch(A, G00, b0, r2, rr, ripple_grid(x, dxs, ws, on))[None]

    return _grid_minima(sse, w_lo, w_hi, span)[0]


def _grid_minima(sse, w_lo: float, w_hi: float, span: float) -> list[float]:
    """Per objective, the frequency of least ``sse`` on the grid over [w_lo, w_hi], refined
    between its neighbours (``sse(ws)``: shape (objectives, len(ws)), objectives that share
    the grid's costly part)."""
    count = min(int((w_hi - w_lo) / grid_step(span)) + 1, _GRID_MAX)
    grid = np.linspace(w_lo, w_hi, max(count, 2))
    vals = np.concatenate([sse(grid[k : k + _BATCH]) for k in range(0, grid.size, _BATCH)], axis=1)
    out = []
    for v, row_vals in enumerate(vals):
        k = int(np.argmin(row_vals))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        if hi <= lo:
            out.append(float(grid[k]))
            continue
        res = optimize.minimize_scalar(
            lambda w, v=v: float(sse(np.array([w]))[v, 0]), bounds=(lo, hi), method="bounded"
        )
        out.append(float(res.x) if res.fun <= row_vals[k] else float(grid[k]))
    return out


def _ripple_search(
    row: dict, Fo: np.ndarray, ro: np.ndarray, colsets: list[list[int]], keep=None
) -> list[float]:
    """Best spatial frequency of a ripple on the fit's own objective, the output error
    beside each of ``colsets``, on the rows ``keep`` (0 when none can be seen); the
    candidates' columns run through the model once for all of them.

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
    """
    keep = np.ones(ro.size, bool) if keep is None else keep
    idx, st = _search_pairs(row, keep)
    pos, step = row["pos"][idx], row["step"][idx]
    known = np.isfinite(pos)
    fit = keep[idx]  # the rows the least squares take (a pair's held-out rows are run, not fitted)
    band = _band(pos, step, known, known & fit)
    if band is None:
        return [0.0] * len(colsets)
    w_lo, w_hi, span = band
    x, rr = np.where(known, pos, 0.0), ro[idx[fit]]
    bases = [_normal(Fo[np.ix_(idx[fit], cols)], rr) for cols in colsets]

    def sse(ws: np.ndarray) -> np.ndarray:
        S = ripple_grid(x, step, ws, known)  # (B, 2, r), rows of unknown position 0
        So = through_model(S.reshape(-1, S.shape[2]).T, st, *row["tf"]).T
        So = So.reshape(S.shape)[:, :, fit]
        return np.stack([sse_batch(A, G00, b0, r2, rr, So) for A, G00, b0, r2 in bases])

    return _grid_minima(sse, w_lo, w_hi, span)


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
    (4.98 mm found, none on output). The column sets share each search's costly part (the
    input side does not depend on them; the output side runs its candidates through the
    model once)."""
    m = len(colsets)
    best: list[tuple[float, np.ndarray | None]] = [(0.0, None)] * m
    for search in (
        lambda keep=None: [_input_search(row, keep)] * m,
        lambda keep=None: _ripple_search(row, Fo, ro, colsets, keep),
    ):
        ws = search()
        if max(ws) <= 0:
            continue
        errs = _cv_ripple(row, Fo, ro, colsets, search)
        for v, (w, err) in enumerate(zip(ws, errs, strict=True)):
            if w > 0 and (best[v][1] is None or rms(err) < rms(best[v][1])):
                best[v] = (w, err)
    return best


def _cv_ripple(
    row: dict, Fo: np.ndarray, ro: np.ndarray, colsets: list[list[int]], search
) -> list[np.ndarray]:
    """Per column set, the cross-validated error with a ripple whose frequency each fold
    searches (``search``, of the rows it may use: one frequency per column set) on its own
    training rows: a frequency chosen on all the data would fit structure in the held-out
    rows too (with few primitives, residual structure in time looks like a short pitch).
    Each frequency's columns are formed once a fold (the input side gives every column set
    the same one)."""
    folds = row["folds"]
    errs = [np.empty_like(ro) for _ in colsets]
    for k in np.unique(folds):
        test = folds == k
        train = ~test
        columns: dict[float, np.ndarray] = {}
        for cols, w, err in zip(colsets, search(train), errs, strict=True):
            if w > 0 and w not in columns:
                columns[w] = output_columns(row, Fo, w)
            G, use = (Fo, cols) if w <= 0 else (columns[w], cols + RIPPLE)
            c = solve(G[train], ro[train], use)
            err[test] = ro[test] - G[test] @ c
    return errs
