"""The package's layers: physics -> io -> reports -> workflows -> cli, no import runs back up.

Every module of ``phri_spring`` and ``cli/`` is parsed (not imported) and
every import it makes, at the top or inside a function, is mapped to the
layer of the module it names: an import from a higher layer fails, naming
the file and line. The imports must also form no cycle, those inside functions
included (a late import cannot deadlock a first import, but two modules that
need each other are one module in two files); imports for annotations only
(``if TYPE_CHECKING:``) do not count.
"""

from __future__ import annotations

import ast
from pathlib import Path

from support.helpers import REPO

#: package -> layer (higher may import lower, never the reverse)
LAYERS = {
    "phri_spring.errors": 0, "phri_spring.objectives": 0,
    # the plug-in records: a registry every layer reads (it imports nothing of the package
    # at module level; the built-in arms are loaded by name on first look-up)
    "phri_spring.plugins": 0,
    "phri_spring.physics": 1,
    "phri_spring.io": 2,
    "phri_spring.reports": 3,
    "phri_spring.workflows": 4, "phri_spring.synthetic": 4,
    "phri_cli": 5, "phri_spring": 6,
}
ROOTS = {"phri_spring": REPO / "phri_spring", "phri_cli": REPO / "cli"}


def _modules() -> dict:
    """Module name -> (path, is a package)."""
    out = {}
    for root, folder in ROOTS.items():
        for path in sorted(folder.rglob("*.py")):
            parts = [root, *path.relative_to(folder).with_suffix("").parts]
            package = parts[-1] == "__init__"
            if package:
                parts.pop()
            out[".".join(parts)] = (path, package)
    return out


def _layer(module: str):
    best = None
    for prefix, layer in LAYERS.items():
        if module == prefix or module.startswith(prefix + "."):
            if best is None or len(prefix) > len(best[0]):
                best = (prefix, layer)
    return None if best is None else best[1]


def _imports(name: str, path: Path, package: bool, modules: dict):
    """(imported module, line, at module level) of every import of the package's own."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    top = {id(node) for node in tree.body}
    # imports for annotations only (``if TYPE_CHECKING:``) never run
    typing_only = {id(inner) for node in ast.walk(tree) if isinstance(node, ast.If)
                   and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"
                   for inner in ast.walk(node)}
    here = name if package else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here
                for _ in range(node.level - 1):
                    base = base.rpartition(".")[0]
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            # ``from package import module`` imports the module
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        else:
            continue
        for target in targets:
            if target.split(".")[0] in ROOTS:
                found.append((target, node.lineno, id(node) in top))
    return found


def test_no_import_runs_up_a_layer_and_no_cycle():
    modules = _modules()
    upward, graph = [], {}
    for name, (path, package) in modules.items():
        mine = _layer(name)
        graph[name] = set()
        for target, line, at_top in _imports(name, path, package, modules):
            theirs = _layer(target)
            if mine is not None and theirs is not None and theirs > mine:
                upward.append(f"{path.relative_to(REPO)}:{line} imports {target}")
            if target in modules and target != name:
                graph[name].add(target)
    assert upward == [], "\n".join(upward)

    # depth-first search for a cycle among all imports that run, inside functions too
    state, stack = {}, []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " +
                                     " -> ".join(stack[stack.index(nxt):] + [nxt]))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)
