"""The walk-through's figure, read back from the library: paths, errors per trial, inputs.

    python examples/stage/figure.py --db stage.duckdb --out stage.png [--series 1 2 3]

Left: the glyph and the stage's measured path in the first and the last trial. Middle: the
RMS tracking error per trial (log scale) with the noise floor the series estimated, and the
first trials of the moved glyph from the warm start and from the model inverse. Right: the
first and the final input of the glyph.
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from primlib.store import Store, TrialStore  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--db", required=True)
    p.add_argument("--out", required=True)
    p.add_argument(
        "--series", type=int, nargs=3, default=[1, 2, 3], metavar=("GLYPH", "WARM", "INV")
    )
    args = p.parse_args(argv)
    with Store(args.db, read_only=True) as lib:
        store = TrialStore(lib)
        glyph, warm, inv = (store.series(s) for s in args.series)
        trials = [t for t in store.trials(glyph.id) if not t.pending]
        warm_t = [t for t in store.trials(warm.id) if not t.pending]
        inv_t = [t for t in store.trials(inv.id) if not t.pending]
    fig, ax = plt.subplots(1, 3, figsize=(13, 4))
    ax[0].plot(*glyph.points.T, "k-", lw=2, label="path")
    ax[0].plot(*trials[0].measured.T, "C3-", lw=1, label="trial 0 (model inverse)")
    ax[0].plot(*trials[-1].measured.T, "C0-", lw=1, label=f"trial {trials[-1].trial}")
    ax[0].set(xlabel="x [mm]", ylabel="y [mm]", aspect="equal", title="glyph on the stage")
    ax[0].legend(fontsize=8)
    k = [t.trial for t in trials]
    ax[1].semilogy(k, [t.rms for t in trials], "C0o-", label="glyph, tracking")
    ax[1].semilogy(k, [t.contour_rms for t in trials], "C0s--", ms=3, label="glyph, contour")
    floors = [t.noise_floor for t in trials if t.noise_floor is not None]
    if floors:
        ax[1].axhline(floors[-1], color="gray", ls=":", label="noise floor (estimated)")
    ax[1].semilogy([0], [warm_t[0].rms], "C2*", ms=12, label="moved glyph, warm start")
    ax[1].semilogy([0], [inv_t[0].rms], "C3x", ms=10, label="moved glyph, model inverse")
    ax[1].set(xlabel="trial", ylabel="RMS error [mm]", title="error per trial")
    ax[1].legend(fontsize=8)
    t = np.arange(glyph.n_samples) * glyph.dt
    for i, a in enumerate("xy"):
        ax[2].plot(t, trials[0].input[:, i], f"C{i}:", lw=1, label=f"u{a}, trial 0")
        ax[2].plot(t, trials[-1].input[:, i], f"C{i}-", lw=1, label=f"u{a}, trial {k[-1]}")
    ax[2].set(xlabel="t [s]", ylabel="input [V]", title="learned input")
    ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
