"""The primitive store: one DuckDB file of machines and learned motion primitives.

Persistence only (it imports none of ``match``, ``splice``, ``ilc`` or ``pipeline``):
:class:`Store` keeps, per machine, NURBS paths with the converged ILC input learned for each,
both sampled on the machine's grid; :class:`Bank` is a machine's whole set as flat arrays for
the matcher; :class:`PrimitiveInfo` / :class:`Primitive` are single records; :class:`AddResult`
says what a batch write stored. This is the only package that imports duckdb.

Modules: ``_connection`` (opening, locking, schema check, transactions), ``_schema`` (the
ordered, recorded migrations), ``_codec`` (Arrow buffers both ways), ``_validate`` (checks
before any write), ``_insert`` (batch writes), ``_machines`` (the machines table), ``_fitted`` (the
fitted models a warm start keeps), ``_store`` (the public class).
"""

from primlib.store._connection import WriteCancelled
from primlib.store._fitted import fitted_rows, keep_fitted, read_fitted
from primlib.store._schema import MIGRATIONS, SCHEMA_VERSION, migrate
from primlib.store._store import Store
from primlib.store._trials import SeriesRecord, TrialRecord, TrialStore
from primlib.store._types import AddResult, Bank, Primitive, PrimitiveInfo
from primlib.store._validate import check_name, check_origin, content_hash

__all__ = [
    "Store",
    "TrialStore",
    "SeriesRecord",
    "TrialRecord",
    "Bank",
    "Primitive",
    "PrimitiveInfo",
    "AddResult",
    "read_fitted",
    "keep_fitted",
    "fitted_rows",
    "WriteCancelled",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "migrate",
    "content_hash",
    "check_name",
    "check_origin",
]
