"""The objectives table of ``phri design``: complete records, docs that cannot drift, errors.

Every objective is one record of :data:`phri_spring.objectives.OBJECTIVE_TABLE`;
the study file's validation, the evaluation of a design, report.md's footnote
and docs/design.md all read it. These tests keep the records complete, the
docs equal to the table, and an unknown objective a one-line error that
names the key and lists the valid names.
"""

from __future__ import annotations

import ast
import re

import pytest
import yaml

from support.helpers import REPO, one_line
from phri_spring.errors import ConfigError
from phri_spring.io.config import study as io_study
from phri_spring.io.config.study import load_study
from phri_spring.objectives import (OBJECTIVE_BY_NAME, OBJECTIVE_TABLE, OBJECTIVES,
                                    objectives_footnote, objectives_markdown)

DOCS = REPO / "docs" / "design.md"


def test_every_objective_has_a_unit_a_sense_a_description_and_a_function():
    assert OBJECTIVE_TABLE, "the table is empty"
    for o in OBJECTIVE_TABLE:
        assert re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", o.name), o.name
        assert o.unit.strip(), f"{o.name}: no unit"
        assert o.sense in {"min", "max"}, f"{o.name}: sense {o.sense!r}"
        assert len(o.description.strip()) > 10, f"{o.name}: no description"
        assert callable(o.compute), f"{o.name}: no function"
    assert len(OBJECTIVES) == len(OBJECTIVE_TABLE) == len(OBJECTIVE_BY_NAME), "a name repeats"


def test_the_study_file_and_the_evaluation_read_the_same_table():
    from phri_spring.workflows.design import study as design
    from phri_spring.workflows.design import objectives as design_objectives

    assert io_study.OBJECTIVES is OBJECTIVES
    assert design.OBJECTIVES is OBJECTIVES
    assert design_objectives.OBJECTIVE_TABLE is OBJECTIVE_TABLE


def test_the_table_module_imports_nothing_of_the_package():
    """So any layer (io included) may read it."""
    from phri_spring import objectives

    tree = ast.parse(open(objectives.__file__, encoding="utf-8").read())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            assert node.level == 0 and not (node.module or "").startswith("phri_spring"), \
                ast.dump(node)
        elif isinstance(node, ast.Import):
            assert not any(a.name.startswith("phri_spring") for a in node.names)


def test_docs_list_every_objective_with_its_unit():
    text = DOCS.read_text(encoding="utf-8")
    rows = {m.group(1): m.group(2).strip() for m in
            re.finditer(r"^\| `([A-Za-z0-9_]+)` \| ([^|]+) \|", text, flags=re.M)}
    for o in OBJECTIVE_TABLE:
        assert o.name in rows, f"docs/design.md does not list {o.name}"
        assert rows[o.name] == o.unit, f"docs/design.md: {o.name} in {rows[o.name]!r}, " \
                                       f"the table says {o.unit!r}"
    assert objectives_markdown() in text, (
        "docs/design.md's objectives table differs from phri_spring/objectives.py; "
        "regenerate it with `python -m phri_spring.objectives`")


def test_report_footnote_names_every_objective_with_its_unit():
    foot = objectives_footnote()
    assert one_line(foot)
    for o in OBJECTIVE_TABLE:
        assert f"{o.name} [{o.unit}] = {o.description}" in foot


@pytest.mark.parametrize("section,key", [
    ({"minimise": ["peak_presure"]}, "minimise[0]"),
    ({"minimise": ["lift_off_fraction"], "maximise": ["stiffness"]}, "maximise[0]"),
    ({"minimise": ["lift_off_fraction"], "constraints": {"peak_force": ">= 2"}},
     "constraints.peak_force"),
], ids=["minimise", "maximise", "constraints"])
def test_unknown_objective_in_a_study_file_is_one_line_naming_the_key_and_the_valid_names(
        tmp_path, section, key):
    study = {"config": "base.yaml", "loads": ["log.csv"],
             "vary": {"strap.tension": {"values": [5, 10]}}, **section}
    path = tmp_path / "study.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    with pytest.raises(ConfigError) as info:
        load_study(path)
    msg = str(info.value)
    assert one_line(msg), msg
    assert str(path) in msg and key in msg and "unknown objective" in msg, msg
    for name in OBJECTIVES:
        assert name in msg, f"{name} missing from: {msg}"
