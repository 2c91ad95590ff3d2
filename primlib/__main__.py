"""``python -m primlib`` is the ``primlib`` command."""

from primlib.cli import main

main(prog_name="primlib")
