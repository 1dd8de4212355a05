"""The suite's own layout: tests mirror the package and share code only through
``tests/support`` (a test module imported by another would run its tests twice, or not
at all, depending on the order pytest collects them in)."""

from __future__ import annotations

import ast

from support.helpers import TESTS


def _test_modules():
    return sorted(p for p in TESTS.rglob("test_*.py"))


def test_no_test_module_imports_another():
    bad = []
    for path in _test_modules():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            bad += [f"{path.relative_to(TESTS)}:{node.lineno} imports {n}" for n in names
                    if n.split(".")[0].startswith("test_")]
    assert bad == [], "\n".join(bad)


def test_the_checker_sees_an_import_of_a_test_module():
    tree = ast.parse("def f():\n    from test_design import make_study\n")
    found = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
             and (n.module or "").startswith("test_")]
    assert found


def test_tests_mirror_the_package():
    """Every test module sits in a folder named after a layer of the package (or the
    project, faults and cli folders), none at the top of tests/."""
    top = {"physics", "io", "reports", "workflows", "cli", "project", "faults"}
    stray = [str(p.relative_to(TESTS)) for p in _test_modules()
             if p.relative_to(TESTS).parts[0] not in top]
    assert stray == []
