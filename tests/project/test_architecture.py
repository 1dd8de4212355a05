"""The team's structural rules, read from the source with ``ast`` (nothing is imported):

- no module uses another module's private name (``from .x import _y``, ``x._y``);
- no import cycle between the modules of ``phri_spring`` (module-level imports);
- no module over 600 lines;
- no measured figure in a code comment or docstring (they belong in ``benchmarks/*.md``).

Each rule has an allow-list of what broke it when the rule came in, in modules that were
being edited on other branches at the time. The lead empties these lists; an entry that no
longer breaks its rule fails the test too, so that it is taken off.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import ast
import io
import re
import tokenize

import pytest

ROOT = REPO
# references/ (the reference FEs, outside the installed package) keeps the same rules
PACKAGES = {"phri_spring": ROOT / "phri_spring", "phri_cli": ROOT / "cli",
            "references": ROOT / "references"}
MAX_LINES = 600

# ------------------------------------------------------------------------------ allow-lists
#: (importing module, defining module, private name) still allowed (none). To keep it
#: empty: make the name public in the defining module (``_x`` -> ``x``) and in its users.
PRIVATE_ALLOWED: set = set()
#: import cycles still allowed, each the sorted modules of one strongly connected component.
#: (physics/model.py <-> physics/solver.py is no cycle at module level: model.py imports
#: the solver inside a function and solver.py imports the model for annotations only.)
CYCLES_ALLOWED: set = set()
#: modules still allowed over MAX_LINES lines (none: split a long module along its jobs)
LONG_ALLOWED: set = set()


# ------------------------------------------------------------------------------ the modules
def modules() -> dict:
    """Dotted module name -> source path, for every module of both packages."""
    out = {}
    for package, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = modules()


def source_of(name: str) -> str:
    return MODULES[name].read_text(encoding="utf-8")


def imported_module(name: str, node: ast.ImportFrom) -> str:
    """The absolute name of the module a ``from ... import`` in module ``name`` reads."""
    if not node.level:
        return node.module or ""
    base = name.split(".")
    if MODULES[name].name != "__init__.py":
        base = base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def private(attr: str) -> bool:
    return attr.startswith("_") and not attr.startswith("__")


def private_uses(name: str, tree: ast.AST) -> set:
    """(module, defining module, name) of every private name of another module used in
    ``tree``: imported by name, or read as an attribute of an imported module."""
    found, aliases = set(), {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = imported_module(name, node)
            for alias in node.names:
                full = f"{source}.{alias.name}"
                if full in MODULES:                     # a module: used through attributes
                    aliases[alias.asname or alias.name] = full
                elif private(alias.name) and source != name and source in MODULES:
                    found.add((name, source, alias.name))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name in MODULES:
                    aliases[alias.asname or alias.name] = alias.name
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and private(node.attr)
                and isinstance(node.value, ast.Name) and node.value.id in aliases
                and aliases[node.value.id] != name):
            found.add((name, aliases[node.value.id], node.attr))
    return found


def module_level_imports(body):
    """The import statements that run when the module is imported: at its top level and in
    its top-level ``if``/``try`` blocks, but not under ``if TYPE_CHECKING`` (annotations)."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, ast.If):
            test = node.test
            if getattr(test, "id", None) == "TYPE_CHECKING" or \
                    getattr(test, "attr", None) == "TYPE_CHECKING":
                continue
            yield from module_level_imports(node.body)
            yield from module_level_imports(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, *(h.body for h in node.handlers), node.orelse,
                          node.finalbody):
                yield from module_level_imports(block)


def import_graph(package: str = "phri_spring") -> dict:
    graph = {}
    for name in MODULES:
        if name.split(".")[0] != package:
            continue
        edges = set()
        for node in module_level_imports(ast.parse(source_of(name)).body):
            if isinstance(node, ast.Import):
                edges.update(a.name for a in node.names if a.name in MODULES)
                continue
            source = imported_module(name, node)
            for alias in node.names:
                if f"{source}.{alias.name}" in MODULES:
                    edges.add(f"{source}.{alias.name}")
                elif source in MODULES:
                    edges.add(source)
        edges.discard(name)
        graph[name] = edges
    return graph


def cycles(graph: dict) -> set:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], set()
    counter = 0
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, edges = work[-1]
            for w in edges:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    component = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        component.append(w)
                        if w == v:
                            break
                    if len(component) > 1:
                        found.add(tuple(sorted(component)))
    return found


# ------------------------------------------------------------------------------ the checkers
def test_the_checkers_find_what_they_look_for():
    """Each checker on a small made-up case, so that an empty finding below means
    something."""
    tree = ast.parse("from .mesh import _graded, DEFAULT_PATCH_GAP\n"
                     "from . import tissue\n"
                     "def f():\n    return tissue._hidden() + tissue.__name__\n")
    assert private_uses("phri_spring.physics.continuum.punch", tree) == {
        ("phri_spring.physics.continuum.punch", "phri_spring.physics.continuum.mesh", "_graded"),
        ("phri_spring.physics.continuum.punch", "phri_spring.physics.continuum.tissue", "_hidden")}
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}) == \
        {("a", "b", "c")}
    assert cycles({"a": {"b"}, "b": set()}) == set()
    body = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                     "    from .model import X\ntry:\n    import numpy\nexcept ImportError:\n"
                     "    pass\ndef f():\n    from .solver import S\n").body
    assert [getattr(n, "module", None) or n.names[0].name
            for n in module_level_imports(body)] == ["typing", "numpy"]
    assert sorted(measured_asides("'''Takes 3.5 ms.'''\nx = 1  # (measured 80 B)\n")) == [
        "(measured 80 B)", "Takes 3.5 ms."]
    assert measured_asides("def f():\n    '''in 2.5 s against 5.4 s'''\n") == [
        "in 2.5 s against 5.4 s"]
    assert measured_asides("x = 1  # per cent of the threshold, 5 mm apart\n") == []


def test_no_module_uses_another_modules_private_names():
    found = set()
    for name in MODULES:
        found |= private_uses(name, ast.parse(source_of(name)))
    assert sorted(found - PRIVATE_ALLOWED) == [], "make these names public"
    assert sorted(PRIVATE_ALLOWED - found) == [], "fixed: take these off PRIVATE_ALLOWED"


def test_no_import_cycle_between_modules():
    found = cycles(import_graph())
    assert sorted(found - CYCLES_ALLOWED) == []
    assert sorted(CYCLES_ALLOWED - found) == [], "fixed: take these off CYCLES_ALLOWED"


def test_no_module_over_the_line_limit():
    sizes = {str(path.relative_to(ROOT)): len(path.read_text(encoding="utf-8").splitlines())
             for path in MODULES.values()}
    long = {path for path, n in sizes.items() if n > MAX_LINES}
    assert sorted(f"{p}: {sizes[p]} lines" for p in long - LONG_ALLOWED) == [], "split these"
    assert sorted(LONG_ALLOWED - long) == [], "fixed: take these off LONG_ALLOWED"


# ------------------------------------------------------------------------------ measured figures
#: a measurement in prose: "(measured ...", or a time, a rate or a speed-up with its number
MEASURED = re.compile(
    r"\(measured\b"
    r"|\b\d+(?:\.\d+)?\s?(?:ms|µs|us|ns|s/h|samples/s)\b"
    r"|\b\d+(?:\.\d+)?\s?s (?:against|vs\.?|instead of)\b"
    r"|\b\d+(?:\.\d+)?\s?(?:x|times) (?:faster|slower)\b"
    r"|\b\d+(?:\.\d+)?\s?% (?:faster|slower|of the (?:time|run))\b"
    r"|[Tt]akes \d+(?:\.\d+)?\s?(?:s|ms|min)\b",
    re.IGNORECASE)


def measured_asides(text: str) -> list:
    """Measurements in the comments and docstrings of Python source ``text``."""
    prose = [tok.string for tok in tokenize.generate_tokens(io.StringIO(text).readline)
             if tok.type == tokenize.COMMENT]
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                prose.append(doc)
    found = []
    for chunk in prose:
        for line in chunk.splitlines():
            if MEASURED.search(line):
                found.append(line.strip().lstrip("#").strip().strip("'\""))
    return found


@pytest.mark.parametrize("package", sorted(PACKAGES))
def test_no_measured_figures_in_code_comments(package):
    found = [f"{path.relative_to(ROOT)}: {line}"
             for name, path in MODULES.items() if name.split(".")[0] == package
             for line in measured_asides(path.read_text(encoding="utf-8"))]
    assert found == [], "move these figures to benchmarks/*.md with their command"
