"""The documentation is part of the product: it parses, it covers the interface, it is current.

Modelled on sqlite-utils' ``test_docs.py``: every command is described in ``docs/cli.rst``,
every top-level name in ``docs/api.rst``, every public name has a docstring, and the
generated reference pages match the code (``python scripts/build_docs.py`` rewrites them).
The examples in the pages and docstrings run as doctests (``pyproject.toml``).
"""

from __future__ import annotations

import importlib
import inspect
import io
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(ROOT / "scripts"))

import build_docs  # noqa: E402

docutils_core = pytest.importorskip("docutils.core")


def test_docs_pages_parse_without_warnings():
    # one document, as a site builder would see it: citations resolve across pages; the
    # Python roles of docstrings (:func:, :class:...) are what Sphinx adds to docutils
    from docutils import nodes
    from docutils.parsers.rst import roles

    for role in ("func", "class", "meth", "mod", "data", "attr", "exc", "obj", "doc"):
        roles.register_generic_role(role, nodes.literal)
    text = "\n\n".join(p.read_text(encoding="utf-8") for p in sorted(DOCS.glob("*.rst")))
    err = io.StringIO()
    docutils_core.publish_doctree(
        text, settings_overrides={"warning_stream": err, "report_level": 2, "halt_level": 5}
    )
    assert err.getvalue() == ""


@pytest.mark.parametrize("page", ["maths.rst", "references.rst"])
def test_the_three_papers_are_cited_in_full(page):
    text = (DOCS / page).read_text(encoding="utf-8")
    for key in ("[KXZZW]", "[LMFX]", "[ZCH]"):
        assert key in text


def test_maths_uses_math_blocks():
    assert (DOCS / "maths.rst").read_text(encoding="utf-8").count(".. math::") >= 10


def test_every_top_level_name_is_in_the_api_page():
    import primlib

    text = (DOCS / "api.rst").read_text(encoding="utf-8")
    missing = [n for n in primlib.__all__ if n not in text and "Error" not in n]
    assert missing == [], f"docs/api.rst does not mention {missing}"


def test_every_public_name_has_a_docstring():
    missing = []
    for modname in build_docs.public_packages():
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", []):
            obj = getattr(mod, name)
            if (inspect.isclass(obj) or inspect.isfunction(obj)) and not inspect.getdoc(obj):
                missing.append(f"{modname}.{name}")
    assert missing == [], f"public names without a docstring: {missing}"


def test_reference_pages_are_current():
    # a new command, option or public name changes them: python scripts/build_docs.py. In a
    # fresh interpreter, so that nothing an earlier test did to the CLI objects leaks in.
    import subprocess

    res = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "build_docs.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert res.returncode == 0, res.stdout + res.stderr


def test_every_command_is_in_the_command_tour():
    import click

    from primlib.cli import main

    text = (DOCS / "cli.rst").read_text(encoding="utf-8")
    missing = []
    for full, cmd in build_docs._commands(main, "primlib"):
        if full != "primlib" and not isinstance(cmd, click.Group) and full not in text:
            missing.append(full)
    assert missing == [], f"docs/cli.rst does not describe {missing}"


def test_nothing_cites_a_document_outside_the_repository():
    # the interface used to live in ../shared/API.md; it is docs/ now
    files = [ROOT / "README.md", *ROOT.glob("primlib/**/*.py"), *DOCS.glob("*.rst")]
    citing = [str(f.relative_to(ROOT)) for f in files if "API.md" in f.read_text("utf-8")]
    assert citing == []
