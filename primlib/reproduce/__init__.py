"""The source papers' studies, re-run on primlib's own code (``primlib reproduce ...``).

Each study is a pure function returning plain data (dicts of floats and lists) that the CLI
prints as JSON and ``primlib.plot`` draws; where an honest reproduction disagrees with the
paper, the study's module docstring says so and why.
"""
