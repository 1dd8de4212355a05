"""Absurd values of the config's numeric keys end in one line naming the key (exit 1).

A value outside what any cuff or arm has (a friction coefficient of 1e308, a strap pulling
with a meganewton, a stiffening rate that overflows the law) used to run and write a log of
NaN, or end in an internal error; docs/model.md section 6 ("Plausible ranges") gives each
range and where it comes from. The refusal names the key and the range.
"""

from __future__ import annotations

import pytest

from support.helpers import (assert_one_line_error, example_log_lines, run_phri, small_human_cuff,
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


def _set(raw: dict, key: str, value) -> None:
    *parents, last = key.split(".")
    for p in parents:
        raw = raw.setdefault(p, {})
    raw[last] = value


#: (key, absurd value, the range's bounds as the message gives them); each of these ran
#: before, writing a log of NaN (or ending in an internal error)
ABSURD = [
    ("interface.friction_coefficient", 1e308, ("0 to 10",)),
    ("tissue.stiffening", 1e300, (">= 0 and <= 10000",)),
    ("strap.tension", 1e6, ("0 to 1000",)),
    ("strap.tension", 1e300, ("0 to 1000",)),
    ("geometry.row_width", 1e-300, ("0.001 to 0.5",)),
    ("geometry.angles.width", 1e-300, ("1e-06 to 360",)),
    ("load_cell.position", [1e300, 0.0, 0.0], ("-2 to 2",)),
    ("tissue.stiffness", 1e-300, (">= 1",)),
    ("cuff.stiffness", 1e-300, (">= 1",)),
    ("tissue.indenter_diameter", 1e300, ("0.0005 to 0.1",)),
    ("interface.shear_ratio", 1e-300, ("0.01 to 100",)),
    ("tissue.continuum.thickness", 1e-300, (">= 0.001",)),
    ("tissue.continuum.young_modulus", 1e-300, ("100 to 1e+08",)),
    ("tissue.continuum.patch_gap", 1e-12, ("1e-05 to 0.05",)),
    ("geometry.rows", {"A": 1e300}, ("-1 to 1",)),
    ("strap.axial_position", 1e300, ("-1 to 1",)),
    ("strap.handle_angles", [1e300, 0.0], ("-720 to 720",)),
    ("tissue.continuum.max_force", 1e300, ("0 to 10000",)),
]


@pytest.mark.parametrize("key, value, needles", ABSURD, ids=[f"{k}={v}" for k, v, _ in ABSURD])
def test_an_absurd_value_is_one_line_naming_the_key_and_its_range(tmp_path, log, key, value,
                                                                   needles):
    raw = small_human_cuff()
    raw["tissue"].pop("stiffening")            # friction runs with the linear law only
    _set(raw, key, value)
    if key.startswith("strap.") and key != "strap.tension":
        raw["strap"]["model"] = "handles"
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, log, "-o", tmp_path / "out.csv")
    assert_one_line_error(res, key, "plausible ranges", *needles)
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("radius", [1e300, 45.0, 1e-300, 0.002])
def test_an_absurd_radius_is_one_line_with_the_limb_range(tmp_path, log, radius):
    # the radius shares the range of every limb section (docs/model.md section 13)
    raw = small_human_cuff()
    raw["geometry"]["radius"] = radius
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, log, "-o", tmp_path / "out.csv")
    assert_one_line_error(res, "geometry.radius", "between 0.005 and 0.3 m")
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("key, value", [("interface.friction_coefficient", 2.0),
                                        ("tissue.stiffening", 5000.0),
                                        ("strap.tension", 200.0),
                                        ("tissue.continuum.patch_gap", 0.0)])
def test_values_at_the_ends_of_human_ranges_still_run(tmp_path, log, key, value):
    raw = small_human_cuff()
    if key != "tissue.stiffening":
        raw["tissue"].pop("stiffening")
    _set(raw, key, value)
    cfg = write_yaml(tmp_path, raw)
    res = run_phri("simulate", cfg, log, "-o", tmp_path / "out.csv")
    assert res.exit_code == 0, res.output
