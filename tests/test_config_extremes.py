"""Absurd values of the config's numeric keys end in one line naming the key (exit 1).

A value outside what any cuff or arm has (a friction coefficient of 1e308, a strap pulling
with a meganewton, a stiffening rate that overflows the law) used to run and write a log of
NaN, or end in an internal error; docs/model.md section 6 ("Plausible ranges") gives each
range and where it comes from. The refusal names the key and the range.
"""

from __future__ import annotations

import pytest

from conftest import (assert_one_line_error, example_log_lines, run_phri, small_human_cuff,
                      write_yaml)


@pytest.fixture
def log(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(example_log_lines(5)) + "\n")
    return path


@pytest.mark.parametrize("law", ["neo_hookean", "ogden"])
def test_tiled_plates_under_a_hyperelastic_layer_are_refused_in_one_line(tmp_path, log, law):
    # the hyperelastic FE moves each plate's skin nodes rigidly: tiled plates would share
    # their edge nodes (was: internal error: ValueError); refused before any FE is built
    raw = small_human_cuff(law=law, patch_gap=0, ogden_alpha=10.0 if law == "ogden" else None)
    if law != "ogden":
        raw["tissue"]["continuum"].pop("ogden_alpha")
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, log, "-o", tmp_path / "out.csv", "--arm", "coupled")
    assert_one_line_error(res, "tissue.continuum.patch_gap", "> 0", "share edge nodes")
