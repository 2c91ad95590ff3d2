"""The package's shape, read from its source: sizes a reader can hold, clean boundaries.

No function over 80 lines and no module over 600 in primlib/; no private name or private
module imported across packages; no import cycle between packages; ``store`` imports none of
the stages it only stores for (match, splice, ilc, pipeline). Function-local imports count.
"""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "primlib"


def _modules():
    for f in sorted(PKG.rglob("*.py")):
        yield f, ast.parse(f.read_text(encoding="utf-8"))


def _package(f: Path) -> str:
    parts = f.relative_to(PKG).with_suffix("").parts
    return parts[0] if len(parts) > 1 else parts[0]


def _imports(tree):
    """(module, names) of every ``from primlib... import`` in the tree, at any depth."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("primlib"):
            yield node.module, [a.name for a in node.names]


def _graph():
    graph: dict[str, set[str]] = {}
    for f, tree in _modules():
        own = _package(f)
        for module, _ in _imports(tree):
            target = module.split(".")[1] if "." in module else None
            if target and target != own:
                graph.setdefault(own, set()).add(target)
    return graph


def test_no_function_over_80_lines():
    long = [
        f"{f.relative_to(PKG)}:{n.name} ({n.end_lineno - n.lineno + 1})"
        for f, tree in _modules()
        for n in ast.walk(tree)
        if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
        and n.end_lineno - n.lineno + 1 > 80
    ]
    assert long == []


def test_no_module_over_600_lines():
    long = [
        str(f.relative_to(PKG))
        for f in PKG.rglob("*.py")
        if len(f.read_text(encoding="utf-8").splitlines()) > 600
    ]
    assert long == []


def test_no_private_name_or_module_imported_across_packages():
    bad = []
    for f, tree in _modules():
        own = _package(f)
        for module, names in _imports(tree):
            parts = module.split(".")
            if len(parts) < 2 or parts[1] == own or (len(parts) == 2 and parts[1][0] == "_"):
                continue  # the package itself, or a top-level private module (shared by all)
            private_module = any(p.startswith("_") for p in parts[1:])
            private_names = [n for n in names if n.startswith("_")]
            if private_module or private_names:
                bad.append(f"{f.relative_to(PKG)}: from {module} import {', '.join(names)}")
    assert bad == []


def test_no_import_cycle_between_packages():
    graph = _graph()

    def reach(a, seen):
        for b in graph.get(a, ()):
            if b not in seen:
                seen.add(b)
                reach(b, seen)
        return seen

    assert [a for a in graph if a in reach(a, set())] == []


def test_store_imports_none_of_the_stages():
    assert _graph().get("store", set()) & {"match", "splice", "ilc", "pipeline"} == set()
