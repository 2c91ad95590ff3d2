"""``primlib serve``: the library as an HTTP service (needs the ``serve`` extra)."""

from __future__ import annotations

import click

from primlib._errors import InputError
from primlib.cli import main

__all__ = ["serve"]


@main.command("serve")
@click.option(
    "--db",
    "db",
    type=click.Path(dir_okay=False),
    default=None,
    help="Library file (default: the group's --db, $PRIMLIB_DB, ./primlib.duckdb).",
)
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to listen on.")
@click.option("--port", type=click.IntRange(0, 65535), default=8321, show_default=True)
@click.option(
    "--token-file",
    type=click.Path(dir_okay=False),
    default=None,
    help="Bearer tokens, one 'rw TOKEN' or 'ro TOKEN' per line; needed for a host other "
    "than loopback.",
)
@click.option(
    "--readers",
    type=click.IntRange(1, 64),
    default=2,
    show_default=True,
    help="Reader threads (each with its own connection to the library).",
)
@click.option(
    "--max-body",
    type=click.IntRange(min=1024),
    default=64 * 2**20,
    show_default=True,
    help="Largest request body in bytes (larger ones get 413).",
)
@click.pass_context
def serve(
    ctx: click.Context,
    db: str | None,
    host: str,
    port: int,
    token_file: str | None,
    readers: int,
    max_body: int,
) -> None:
    """Serve the library (--db) over HTTP until Ctrl-C or SIGTERM.

    The server owns the file: many readers at once, writes one at a time, no "busy".
    Endpoints: /openapi.json. One JSON log line per request on stderr.

    \b
    primlib serve --db lib.duckdb --port 8321
    curl -s localhost:8321/machines
    """
    try:
        from primlib.serve import serve as run
    except ImportError as exc:
        raise InputError(
            f"primlib serve needs the serve extra (pip install 'primlib[serve]'): {exc}"
        ) from None
    db = db if db is not None else ctx.find_root().obj["db"]
    run(db, host=host, port=port, token_file=token_file, readers=readers, max_body=max_body)
