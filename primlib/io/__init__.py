"""File formats at the edge of primlib: path and signal CSV tables, machine JSON.

Every reader checks its file and raises :class:`primlib.InputError` with one sentence naming
the file (and the line) and the fault; every writer writes atomically.
"""

from primlib.io._csv import MIN_ROWS, T_RTOL, parse_uniform_table, read_uniform_table, write_table
from primlib.io._machine import read_machine_json, write_machine_json
from primlib.io._path import (
    PATH_HEADERS,
    check_moving,
    parse_path_csv,
    read_path_csv,
    read_path_json,
    write_path_csv,
    write_path_json,
)
from primlib.io._signal import SIGNAL_HEADERS, parse_signal_csv, read_signal_csv, write_signal_csv

__all__ = [
    "MIN_ROWS",
    "T_RTOL",
    "PATH_HEADERS",
    "SIGNAL_HEADERS",
    "check_moving",
    "read_uniform_table",
    "parse_uniform_table",
    "parse_path_csv",
    "parse_signal_csv",
    "write_table",
    "read_path_csv",
    "write_path_csv",
    "read_path_json",
    "write_path_json",
    "read_signal_csv",
    "write_signal_csv",
    "read_machine_json",
    "write_machine_json",
]
