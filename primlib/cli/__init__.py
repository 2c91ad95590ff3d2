"""The ``primlib`` command line: a thin click layer over the library.

Every command takes ``--db FILE`` (default: ``$PRIMLIB_DB``, else ``primlib.duckdb`` in the
current directory). Exit status: 0 done; 2 bad usage or bad input (one line on stderr saying
what and where, nothing written); 1 anything else.

Commands live in private modules (``_library``, ``_match``, ``_learn``, ``_reproduce``...),
each registering itself on :data:`main`; this module only builds the group and turns
primlib's errors into exit codes. It is the only package importing click.
"""

from __future__ import annotations

import os
import sys

import click

from primlib._errors import InputError, LibraryBusyError, NotFoundError, PrimlibError

__all__ = ["main", "DEFAULT_DB"]

DEFAULT_DB = "primlib.duckdb"


class _Group(click.Group):
    """A click group that reports primlib errors in one line with the right exit status."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except (InputError, NotFoundError, LibraryBusyError) as exc:
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(2)
        except PrimlibError as exc:
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(1)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.option(
    "--db",
    "db",
    envvar="PRIMLIB_DB",
    default=DEFAULT_DB,
    show_default=True,
    type=click.Path(dir_okay=False),
    help=f"Library file (DuckDB). Default: $PRIMLIB_DB, else ./{DEFAULT_DB}.",
)
@click.option(
    "--remote",
    "remote",
    envvar="PRIMLIB_REMOTE",
    default=None,
    metavar="URL",
    help="Run read commands (list, show, match, machine list, trials status/list/input) "
    "against a `primlib serve` at URL instead of --db (token: $PRIMLIB_TOKEN).",
)
@click.version_option(package_name="primlib")
@click.pass_context
def main(ctx: click.Context, db: str, remote: str | None) -> None:
    """primlib: a library of learned motion primitives for warm-starting ILC.

    Store paths with the converged ILC input each needed, match a new path against them
    (rotation, translation, time scale), and build its first-iteration input.
    """
    ctx.ensure_object(dict)
    ctx.obj["db"] = os.fspath(db)
    ctx.obj["remote"] = remote


def _register() -> None:
    # Each module adds its commands to ``main`` on import; one line per module.
    import importlib

    for name in _COMMAND_MODULES:
        importlib.import_module(f"primlib.cli.{name}")


# Helpers append their module here (one entry each).
_COMMAND_MODULES: list[str] = [
    "_reproduce",
    "_library",
    "_ingest",
    "_learn",
    "_reproduce_pdccilc",
    "_reproduce_cee",
    "_match",
    "_machine_identify",
    "_machine_fit",
    "_serve",
    "_trials",
]


_register()

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
