"""``primlib machine fit``, and keeping the models a read-only command fitted.

A warm start fits a grey-box and a refined model to the machine's stored pairs (most of a
minute on a library learned under friction) and the library keeps them
(:mod:`primlib.pipeline._fitted`). ``match`` and ``learn`` read with the file open
read-only, so that other readers are not locked out; :func:`keep_models` then opens it for
writing once, for the moment it takes to keep what they fitted. ``machine fit`` fits them
ahead, e.g. after ingesting.
"""

from __future__ import annotations

import json
import time
from typing import Any

import click

from primlib._errors import PrimlibError
from primlib.cli._library import _db, _open_library, _open_waiting, machine

__all__ = ["machine_fit", "keep_models", "KEEP_WAIT"]

KEEP_WAIT = 5.0
"""Seconds a command waits for other processes to release the file before it gives up
keeping its fitted models (they are fitted again next time; nothing else is lost)."""


def keep_models(db: str, lib: Any, say: bool = True) -> None:
    """Keep the models ``lib`` fitted while open read-only (closed by now), or say why not
    (on stderr; ``say``: also that they were kept -- not beside ``--json``)."""
    kept = getattr(getattr(lib, "starter", None), "kept", None)  # None for --remote
    if kept is None or not kept.pending:
        return
    count = sum(len(rows) for _, rows in kept.pending.values())
    try:
        with _open_waiting(db, KEEP_WAIT, create=False) as store:
            kept.keep_pending(store)
    except PrimlibError as exc:  # busy, not writable: the result is already written
        click.echo(
            f"note: the {count} model(s) fitted to the machine's primitives were not kept "
            f"({exc}); the next warm start fits them again",
            err=True,
        )
        return
    if not say:
        return
    click.echo(
        f"note: kept the {count} model(s) fitted to the machine's primitives in {db}; "
        "the next warm start reads them",
        err=True,
    )


@machine.command("fit")
@click.argument("name")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.pass_context
def machine_fit(ctx: click.Context, name: str, as_json: bool) -> None:
    """Fit the models a warm start on machine NAME uses to its stored primitives, and keep
    them in the library.

    The grey-box model (friction, ripple and bias beside the linear model) and the linear
    model refined on the stored pairs: what `match --out` and `learn` otherwise fit on
    their first warm start (13 s on 14 loops learned under friction and ripple). Up to
    24 primitives they are fitted on all of them; beyond, on the library as it stood when
    it last grew by a quarter (24, 30, 38, 48, ... primitives), so that a growing library
    does not fit them again after every primitive it takes in. Kept until that set of
    primitives or primlib changes; models already kept are read, not fitted again.
    """
    with _open_library(ctx) as lib:
        t0 = time.perf_counter()
        model, gb, note = lib.starter.fit_models(name)
        seconds = time.perf_counter() - t0
        kept = lib.starter.kept
        count = len(lib.bank(name).ids)
    from primlib.pipeline import model_count  # the pipeline is loaded by now

    used = model_count(count)
    fitted = kept.fitted > 0
    if as_json:
        out = {
            "machine": name,
            "primitives": count,
            "fitted_on": used,
            "fitted": kept.fitted,
            "read": kept.read,
            "seconds": seconds,
            "refined": None if model is None else model.theta.tolist(),
            "greybox": gb.describe(),
        }
        click.echo(json.dumps(out, indent=2))
        return
    what = "fitted and kept" if fitted else "already kept (read back, nothing fitted)"
    click.echo(
        f"machine '{name}': {count} primitives; {kept.fitted + kept.read} model(s) {what} "
        f"in {_db(ctx)} ({seconds:.1f} s)"
    )
    if note:
        click.echo(note)
    click.echo(f"grey-box model: {gb.describe()}")
    if used < count:
        click.echo(
            f"note: fitted on the oldest {used} of the {count} primitives (the library as it "
            f"stood when it last grew by a quarter); fitted again at {_next_fit(used)}"
        )


def _next_fit(used: int) -> int:
    """The library size at which models fitted on ``used`` primitives are fitted again."""
    from primlib.pipeline import model_count

    k = used + 1
    while model_count(k) == used:
        k += 1
    return k
