"""Option parsers the commands share."""

from __future__ import annotations

import click

__all__ = ["parse_origin", "parse_origins"]


def parse_origins(ctx: click.Context, param: click.Parameter, values: tuple[str, ...]):
    """``--origin X,Y[,Z]`` values as tuples of floats (the store checks the count)."""
    out = []
    for text in values:
        try:
            out.append(tuple(float(v) for v in text.split(",")))
        except ValueError:
            raise click.BadParameter(
                f"expected comma-separated numbers X,Y[,Z], got {text!r}"
            ) from None
    return tuple(out)


def parse_origin(ctx: click.Context, param: click.Parameter, value: str | None):
    """One ``--origin X,Y[,Z]`` as a tuple of floats, or None when not given."""
    return None if value is None else parse_origins(ctx, param, (value,))[0]
