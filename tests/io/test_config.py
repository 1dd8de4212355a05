"""The config of docs/model.md section 6: safe loading, every value form, one-line errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from support import reference_model as ref
from support.helpers import HARMONY_CONFIG, harmony_dict, one_line
from phri_spring.errors import ConfigError, DataError, PhriError
from phri_spring.io.config import config_from_dict, load_config

LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]


def write(path: Path, cfg) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(cfg if isinstance(cfg, str) else yaml.safe_dump(cfg, sort_keys=False))
    return path


def load_error(tmp_path, cfg, name="cfg.yaml", file=None) -> PhriError:
    """Load a bad config: a one-line error naming the file (the config, or ``file``)."""
    path = write(tmp_path / name, cfg)
    with pytest.raises(PhriError) as exc:
        load_config(path)
    err = exc.value
    msg = str(err)
    assert one_line(msg), msg
    assert str(file or path) in msg, msg
    assert "Traceback" not in msg
    assert err.exit_code == 1
    return err


def assert_names(err, *fragments):
    msg = str(err)
    for frag in fragments:
        assert frag in msg, f"{frag!r} not in {msg!r}"


# --------------------------------------------------------------------------- the bundled config
def test_bundled_config_loads_as_the_spec_example():
    cfg = load_config(HARMONY_CONFIG)
    assert cfg.labels == tuple(LABELS)
    np.testing.assert_allclose(cfg.row_x, [-0.025, 0.0, 0.025])
    np.testing.assert_allclose(cfg.radius, 0.045)
    np.testing.assert_allclose(cfg.row_width, 0.025)
    assert (cfg.angle_start_deg, cfg.angle_step_deg, cfg.angle_count) == (75.0, 35.0, 7)
    np.testing.assert_allclose(cfg.tissue_stiffness, 4242.0)
    assert cfg.tissue_basis == "indenter" and cfg.indenter_diameter == 0.009
    np.testing.assert_allclose(
        cfg.cuff_stiffness, np.tile([31250, 62500, 125000, 250000, 500000, 1.0e6, 500000], 3))
    np.testing.assert_allclose(cfg.loadcell_position, [0.0, -0.07, 0.0])
    np.testing.assert_allclose(cfg.loadcell_rotation, np.eye(3), atol=1e-15)
    assert cfg.loadcell_sign == 1.0
    assert (cfg.strap_tension, cfg.strap_model) == (15.0, "hoop")
    assert cfg.pain_threshold_kpa == 120.0
    assert cfg.max_iterations == 100


def test_bundled_config_comments_sources_and_assumptions():
    text = HARMONY_CONFIG.read_text()
    for number in ("4242", "0.009", "15", "35", "120"):
        assert number in text
    assert "[paper]" in text and "[assumption]" in text
    # the cuff stiffness map is an assumption and says so
    cuff_block = text[text.index("cuff:"):text.index("interface:")]
    assert "assumption" in cuff_block


def test_defaults_of_optional_sections(tmp_path):
    d = {"geometry": harmony_dict()["geometry"], "tissue": {"stiffness": 4000.0},
         "cuff": {"stiffness": 1e5}}
    cfg = load_config(write(tmp_path / "min.yaml", d))
    assert cfg.tissue_basis == "indenter" and cfg.indenter_diameter == 0.009
    assert cfg.poisson_ratio == 0.45 and cfg.shear_ratio is None
    assert cfg.strap_tension == 15.0 and cfg.strap_model == "hoop"
    assert cfg.pain_threshold_kpa == 120.0
    assert cfg.loadcell_sign == 1.0 and cfg.force_unit == "N" and cfg.moment_unit == "N*m"
    np.testing.assert_allclose(cfg.loadcell_position, 0.0)
    np.testing.assert_allclose(cfg.loadcell_rotation, np.eye(3))


# --------------------------------------------------------------------------- value forms
def _geom():
    return ref.geometry_from_config(harmony_dict())


@pytest.mark.parametrize("value, expected", [
    (3000.0, [3000.0] * 21),
    ({"per_row": [1000.0, 2000.0, 3000.0]}, [1000.0] * 7 + [2000.0] * 7 + [3000.0] * 7),
    ({"per_angle": [1, 2, 3, 4, 5, 6, 7]}, list(range(1, 8)) * 3),
    ([[float(10 * r + j + 1) for j in range(7)] for r in range(3)],
     [float(10 * r + j + 1) for r in range(3) for j in range(7)]),
    ({lab: float(i + 1) for i, lab in enumerate(reversed(LABELS))},
     [float(21 - i) for i in range(21)]),
])
def test_stiffness_value_forms(tmp_path, value, expected):
    for section in ("tissue", "cuff"):
        d = harmony_dict()
        d[section]["stiffness"] = value
        cfg = load_config(write(tmp_path / f"{section}.yaml", d))
        got = cfg.tissue_stiffness if section == "tissue" else cfg.cuff_stiffness
        np.testing.assert_allclose(got, expected, rtol=1e-15)
        np.testing.assert_allclose(got, ref.resolve_stiffness(value, _geom()), rtol=1e-15)


def _fit_csv(path: Path, values: dict, extra_rows=()):
    lines = ["location,row,angle_index,stiffness_N_per_m,std_N_per_m,n_trials"]
    for lab, v in values.items():
        lines.append(f"{lab},{lab[0]},{lab[1:]},{v},{0.05 * v:.3f},3")
    lines.extend(extra_rows)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_stiffness_from_fit_stiffness_csv_relative_to_config(tmp_path, monkeypatch):
    values = {lab: 3000.0 + 37.5 * i for i, lab in enumerate(LABELS)}
    # rows in a shuffled order: matched by location, not by position
    shuffled = dict(sorted(values.items(), key=lambda kv: (kv[0][1:], kv[0][0])))
    _fit_csv(tmp_path / "lab" / "data" / "stiffness.csv", shuffled)
    d = harmony_dict()
    d["tissue"]["stiffness"] = "data/stiffness.csv"
    cfg_path = write(tmp_path / "lab" / "cfg.yaml", d)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)                      # relative to the config, not the cwd
    cfg = load_config(cfg_path)
    np.testing.assert_allclose(cfg.tissue_stiffness, [values[lab] for lab in LABELS])
    np.testing.assert_allclose(
        cfg.tissue_stiffness,
        ref.resolve_stiffness("data/stiffness.csv", _geom(), base_dir=cfg_path.parent))
    # a relative path from another cwd: the config's folder still wins
    monkeypatch.chdir(tmp_path)
    cfg = load_config(Path("lab") / "cfg.yaml")
    np.testing.assert_allclose(cfg.tissue_stiffness, [values[lab] for lab in LABELS])


def test_stiffness_csv_with_integer_values(tmp_path):
    # a hand-written table: whole numbers are numbers too
    _fit_csv(tmp_path / "k.csv", {lab: 4000 + i for i, lab in enumerate(LABELS)})
    d = harmony_dict()
    d["cuff"]["stiffness"] = "k.csv"
    cfg = load_config(write(tmp_path / "cfg.yaml", d))
    np.testing.assert_allclose(cfg.cuff_stiffness, 4000.0 + np.arange(21))


def test_stiffness_csv_errors_name_the_file_and_column(tmp_path):
    values = {lab: 4000.0 for lab in LABELS}
    d = harmony_dict()
    d["tissue"]["stiffness"] = "k.csv"
    # a location missing
    _fit_csv(tmp_path / "k.csv", {k: v for k, v in values.items() if k != "B4"})
    csv_path = tmp_path / "k.csv"
    err = load_error(tmp_path, d, file=csv_path)
    assert_names(err, "B4", "location")
    # a non-positive value
    _fit_csv(tmp_path / "k.csv", {**values, "C2": -10.0})
    err = load_error(tmp_path, d, file=csv_path)
    assert_names(err, "C2", "stiffness_N_per_m")
    # text in a number
    (tmp_path / "k.csv").write_text((tmp_path / "k.csv").read_text().replace("-10.0", "abc"))
    err = load_error(tmp_path, d, file=csv_path)
    assert_names(err, "stiffness_N_per_m")
    # a location twice
    _fit_csv(tmp_path / "k.csv", values, extra_rows=["A3,A,3,4100.0,1.0,3"])
    err = load_error(tmp_path, d, file=csv_path)
    assert_names(err, "A3")
    # not a fit-stiffness CSV
    (tmp_path / "k.csv").write_text("label,k\nA0,1\n")
    err = load_error(tmp_path, d, file=csv_path)
    assert_names(err, "location")
    # no such file
    (tmp_path / "k.csv").unlink()
    err = load_error(tmp_path, d)
    assert_names(err, "k.csv", "tissue.stiffness")


def test_cuff_inf_allowed_in_every_form(tmp_path):
    for value in (".inf", "{per_angle: [.inf, 1e5, 1e5, 1e5, 1e5, 1e5, .inf]}",
                  "{per_row: [1.0e6, .inf, 2e5]}"):
        text = HARMONY_CONFIG.read_text().replace(
            "stiffness: {per_angle: [31250, 62500, 125000, 250000, 500000, 1.0e6, 500000]}",
            f"stiffness: {value}")
        assert text != HARMONY_CONFIG.read_text()
        cfg = load_config(write(tmp_path / "c.yaml", text))
        assert np.isinf(cfg.cuff_stiffness).any()
        assert np.all(cfg.cuff_stiffness > 0)


def test_yaml_exponent_numbers_are_numbers(tmp_path):
    # YAML 1.1 reads 1e5 (no dot) as text; a lab writes it as a number
    text = HARMONY_CONFIG.read_text().replace("stiffness: 4242.0", "stiffness: 4.242e3")
    cfg = load_config(write(tmp_path / "e.yaml", text))
    np.testing.assert_allclose(cfg.tissue_stiffness, 4242.0)
    text = HARMONY_CONFIG.read_text().replace(
        "{per_angle: [31250, 62500, 125000, 250000, 500000, 1.0e6, 500000]}", "2e5")
    cfg = load_config(write(tmp_path / "e.yaml", text))
    np.testing.assert_allclose(cfg.cuff_stiffness, 2e5)


# --------------------------------------------------------------------------- safety
@pytest.mark.parametrize("snippet", [
    "name: !!python/object/apply:os.system ['touch {marker}']\n",
    "name: x\ntissue:\n  stiffness: !!python/object/apply:os.system ['touch {marker}']\n",
    "name: !!python/object/new:subprocess.check_output [['touch', '{marker}']]\n",
    "name: !!python/name:os.system\n",
])
def test_python_tags_are_errors_and_never_run(tmp_path, snippet):
    marker = tmp_path / "PWNED"
    err = load_error(tmp_path, snippet.format(marker=marker))
    assert not marker.exists()
    assert_names(err, "python")


# --------------------------------------------------------------------------- errors
@pytest.mark.parametrize("mutate, fragments", [
    (lambda d: d["tissue"].update(poison_ratio=0.4), ["tissue.poison_ratio", "'poisson_ratio'"]),
    (lambda d: d.update(strapp={"tension": 10}), ["strapp", "'strap'"]),
    (lambda d: d["geometry"]["angles"].update(cnt=7), ["geometry.angles.cnt", "'count'"]),
    (lambda d: d["load_cell"].update(postion=[0, 0, 0]), ["load_cell.postion", "'position'"]),
])
def test_unknown_key_suggests_the_closest(tmp_path, mutate, fragments):
    d = harmony_dict()
    mutate(d)
    assert_names(load_error(tmp_path, d), *fragments)


@pytest.mark.parametrize("path", [("tissue", "stiffness"), ("cuff", "stiffness"), ("geometry",),
                                  ("geometry", "rows"), ("geometry", "angles", "count"),
                                  ("tissue",)])
def test_missing_key(tmp_path, path):
    d = harmony_dict()
    node = d
    for p in path[:-1]:
        node = node[p]
    del node[path[-1]]
    assert_names(load_error(tmp_path, d), ".".join(path), "missing")


@pytest.mark.parametrize("mutate, key", [
    (lambda d: d["cuff"].update(stiffness={"per_angle": [1e5] * 6}), "cuff.stiffness.per_angle"),
    (lambda d: d["tissue"].update(stiffness={"per_row": [4e3] * 2}), "tissue.stiffness.per_row"),
    (lambda d: d["tissue"].update(stiffness=[[4e3] * 7] * 2), "tissue.stiffness"),
    (lambda d: d["tissue"].update(stiffness=[[4e3] * 6] * 3), "tissue.stiffness"),
    (lambda d: d["tissue"].update(stiffness={"per_row": [4e3] * 3, "per_angle": [4e3] * 7}),
     "tissue.stiffness"),
    (lambda d: d["geometry"].update(radius=[0.04, 0.05]), "geometry.radius"),
    (lambda d: d["geometry"].update(row_width=[0.02, 0.02, 0.02, 0.02]), "geometry.row_width"),
    (lambda d: d["cuff"].update(stiffness={lab: 1e5 for lab in LABELS if lab != "C6"}),
     "cuff.stiffness"),
    (lambda d: d["cuff"].update(stiffness={**{lab: 1e5 for lab in LABELS}, "D0": 1e5}),
     "cuff.stiffness.D0"),
    (lambda d: d["load_cell"].update(position=[0.0, 0.0]), "load_cell.position"),
])
def test_wrong_shapes(tmp_path, mutate, key):
    d = harmony_dict()
    mutate(d)
    assert_names(load_error(tmp_path, d), key)


@pytest.mark.parametrize("section", ["tissue", "cuff"])
@pytest.mark.parametrize("value", [0.0, -4242.0, math.nan, {"per_angle": [1e5] * 6 + [0.0]},
                                   {"per_row": [1e5, math.nan, 1e5]},
                                   [[1e5] * 7, [1e5] * 7, [1e5] * 6 + [-1.0]]])
def test_non_positive_or_nan_stiffness(tmp_path, section, value):
    d = harmony_dict()
    d[section]["stiffness"] = value
    err = load_error(tmp_path, d)
    assert_names(err, f"{section}.stiffness")
    assert "np.float64" not in str(err)       # plain numbers in messages


def test_inf_allowed_for_cuff_but_not_tissue(tmp_path):
    d = harmony_dict()
    d["cuff"]["stiffness"] = math.inf
    cfg = load_config(write(tmp_path / "ok.yaml", d))
    assert np.isinf(cfg.cuff_stiffness).all()
    for value in (math.inf, {"per_angle": [4e3] * 6 + [math.inf]},
                  {lab: (math.inf if lab == "B2" else 4e3) for lab in LABELS}):
        d = harmony_dict()
        d["tissue"]["stiffness"] = value
        assert_names(load_error(tmp_path, d), "tissue.stiffness")


@pytest.mark.parametrize("value", [True, "yes"])
def test_boolean_or_text_stiffness_is_an_error(tmp_path, value):
    d = harmony_dict()
    d["tissue"]["stiffness"] = value
    assert_names(load_error(tmp_path, d), "tissue.stiffness")


def test_both_rotation_and_euler_is_an_error(tmp_path):
    d = harmony_dict()
    d["load_cell"]["rotation"] = np.eye(3).tolist()
    assert_names(load_error(tmp_path, d), "load_cell", "rotation", "euler_xyz_deg")


def test_improper_rotation_is_an_error(tmp_path):
    d = harmony_dict()
    del d["load_cell"]["euler_xyz_deg"]
    d["load_cell"]["rotation"] = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]      # a reflection
    assert_names(load_error(tmp_path, d), "load_cell.rotation")


@pytest.mark.parametrize("mutate, key", [
    (lambda d: d["load_cell"].update(convention="robot_on_arm"), "load_cell.convention"),
    (lambda d: d["load_cell"].update(force_unit="kN"), "load_cell.force_unit"),
    (lambda d: d["load_cell"].update(moment_unit="Nm"), "load_cell.moment_unit"),
    (lambda d: d["tissue"].update(basis="indentor"), "tissue.basis"),
    (lambda d: d["strap"].update(model="belt"), "strap.model"),
])
def test_bad_enum(tmp_path, mutate, key):
    d = harmony_dict()
    mutate(d)
    assert_names(load_error(tmp_path, d), key)


@pytest.mark.parametrize("mutate, key", [
    (lambda d: d["geometry"]["angles"].update(count=0), "geometry.angles.count"),
    (lambda d: d["geometry"]["angles"].update(count=-3), "geometry.angles.count"),
    (lambda d: d["geometry"]["angles"].update(count="seven"), "geometry.angles.count"),
    (lambda d: d["geometry"].update(radius=-0.045), "geometry.radius"),
    (lambda d: d["geometry"].update(radius=math.nan), "geometry.radius"),
    (lambda d: d["geometry"].update(row_width=0.0), "geometry.row_width"),
    (lambda d: d["geometry"].update(rows={}), "geometry.rows"),
    (lambda d: d["geometry"]["angles"].update(step=60.0), "geometry.angles"),
    (lambda d: d["geometry"]["angles"].update(start=math.nan), "geometry.angles.start"),
    (lambda d: d["tissue"].update(poisson_ratio=0.7), "tissue.poisson_ratio"),
    (lambda d: d["tissue"].update(indenter_diameter=0.0), "tissue.indenter_diameter"),
    (lambda d: d["tissue"].update(indenter_diameter=math.inf), "tissue.indenter_diameter"),
    (lambda d: d["interface"].update(shear_ratio=0.0), "interface.shear_ratio"),
    (lambda d: d["interface"].update(shear_ratio=math.inf), "interface.shear_ratio"),
    (lambda d: d["interface"].update(pain_threshold_kpa=-1), "interface.pain_threshold_kpa"),
    (lambda d: d["strap"].update(tension=-15.0), "strap.tension"),
    (lambda d: d["strap"].update(tension=math.nan), "strap.tension"),
    (lambda d: d["strap"].update(model="handles", handle_angles=[math.nan, 300.0]),
     "strap.handle_angles"),
    (lambda d: d["strap"].update(model="handles", axial_position=math.nan),
     "strap.axial_position"),
    (lambda d: d["load_cell"].update(euler_xyz_deg=[math.nan, 0, 0]), "load_cell.euler_xyz_deg"),
    (lambda d: d["load_cell"].update(position=[0, math.inf, 0]), "load_cell.position"),
    (lambda d: d["solver"].update(max_iterations=0), "solver.max_iterations"),
    (lambda d: d["load_cell"].update(columns={"Fxx": "Fx (N)"}), "load_cell.columns.Fxx"),
])
def test_bad_values(tmp_path, mutate, key):
    d = harmony_dict()
    mutate(d)
    assert_names(load_error(tmp_path, d), key)


def test_duplicate_keys(tmp_path):
    text = HARMONY_CONFIG.read_text() + "\nstrap:\n  tension: 10.0\n"
    assert_names(load_error(tmp_path, text), "duplicate", "strap")
    text = HARMONY_CONFIG.read_text().replace("  row_width: 0.025",
                                              "  row_width: 0.025\n  row_width: 0.030")
    assert_names(load_error(tmp_path, text), "duplicate", "row_width")


@pytest.mark.parametrize("text", ["", "- a\n- b\n", "geometry: [1, 2\n", "\t bad: : yaml\n"])
def test_not_a_config(tmp_path, text):
    load_error(tmp_path, text)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path / "nope.yaml")
    assert one_line(str(exc.value)) and "nope.yaml" in str(exc.value)
    with pytest.raises(ConfigError) as exc:
        load_config(tmp_path)                                  # a folder
    assert one_line(str(exc.value)) and str(tmp_path) in str(exc.value)
    bad = tmp_path / "latin1.yaml"
    bad.write_bytes("name: caf\xe9\n".encode("latin-1"))
    with pytest.raises(ConfigError) as exc:
        load_config(bad)
    assert one_line(str(exc.value)) and "latin1.yaml" in str(exc.value)


def test_errors_are_typed_value_errors(tmp_path):
    d = harmony_dict()
    d["tissue"]["stiffness"] = -1.0
    with pytest.raises(ValueError):                   # ConfigError is a ValueError too
        config_from_dict(d, path="x.yaml")
    assert issubclass(ConfigError, DataError)
