"""The primitive library: one DuckDB file of machines and learned motion primitives.

``Library`` stores, per machine, NURBS paths with the converged ILC input learned for each,
both sampled on the machine's grid; ``Bank`` is a machine's whole set as flat arrays for the
matcher; ``PrimitiveInfo`` / ``Primitive`` are single records. This is the only package that
imports duckdb. Schema and migrations: :mod:`primlib.store._schema`.
"""

from primlib.store._library import Library
from primlib.store._schema import MIGRATIONS, SCHEMA_VERSION
from primlib.store._types import Bank, Primitive, PrimitiveInfo

__all__ = ["Library", "Bank", "Primitive", "PrimitiveInfo", "MIGRATIONS", "SCHEMA_VERSION"]
