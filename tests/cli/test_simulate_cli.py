"""``phri simulate`` end to end with click's CliRunner (docs/model.md sections 7 and 8).

Expected forces come from ``reference_model`` (independent implementation of
the spec); every bad input must give exit 1 (data) or 2 (usage), one line on
stderr naming the file and the key or column, no traceback, no output file or
temporary file left behind, and unchanged inputs.
"""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from support import reference_model as ref
from support.helpers import HARMONY_CONFIG, geometries, harmony_dict, one_line
from phri_cli.main import phri

LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]
WRENCH_COLS = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
EXTRAS = ["contacts_in_touch", "peak_pressure_kPa", "peak_pressure_element",
          "peak_pressure_to_pain_threshold", "solver_iterations"]


# --------------------------------------------------------------------------- helpers
def invoke(*args):
    return CliRunner().invoke(phri, ["simulate", *map(str, args)], catch_exceptions=False)


def write_log(path: Path, time, wrench, names=None):
    names = names or ["time", *WRENCH_COLS]
    df = pd.DataFrame(np.column_stack([time, wrench]), columns=names)
    if path.suffix == ".parquet":
        df.to_parquet(path)
    else:
        df.to_csv(path, index=False, float_format="%.17g")
    return path


def read_table(path: Path) -> pd.DataFrame:
    return pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)


def write_config(path: Path, cfg: dict) -> Path:
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return path


def snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    out = {}
    for root, _dirs, files in os.walk(folder):
        for f in files:
            p = Path(root) / f
            out[str(p.relative_to(folder))] = p.read_bytes()
    return out


def random_log(rng, n, scale=(60, 60, 60, 4, 4, 4)):
    t = np.round(np.arange(n) * 0.01, 10)
    W = rng.normal(size=(n, 6)) * np.asarray(scale)
    return t, W


def check_forces(out: pd.DataFrame, expected, labels, atol=1e-4):
    np.testing.assert_allclose(out[list(labels)].to_numpy(), expected, atol=atol, rtol=0)


def assert_clean_error(result, code, before: dict, folder: Path, *fragments):
    """Exit ``code``, one line on stderr naming ``fragments``, nothing written or changed."""
    err = result.stderr
    assert result.exit_code == code, (result.exit_code, result.output)
    assert one_line(err), err
    assert "Traceback" not in result.output
    for frag in fragments:
        assert str(frag) in err, f"{frag!r} not in {err!r}"
    assert snapshot(folder) == before, "files were created, removed or changed"


@pytest.fixture
def harmony_files(tmp_path):
    cfg = write_config(tmp_path / "harmony.yaml", harmony_dict())
    rng = np.random.default_rng(1)
    t, W = random_log(rng, 40)
    log = write_log(tmp_path / "log.csv", t, W)
    return tmp_path, cfg, log, t, W


# --------------------------------------------------------------------------- success
@pytest.mark.parametrize("in_ext", [".csv", ".parquet"])
@pytest.mark.parametrize("out_ext", [".csv", ".parquet"])
def test_forces_csv_and_parquet(tmp_path, in_ext, out_ext):
    rng = np.random.default_rng(2)
    t, W = random_log(rng, 25)
    W[3] = 0.0
    W[7] = [0, 0, 300, 0, 0, 0]                 # lifts contacts off
    log = write_log(tmp_path / f"log{in_ext}", t, W)
    out = tmp_path / f"forces{out_ext}"
    res = invoke(HARMONY_CONFIG, log, "-o", out)
    assert res.exit_code == 0, res.output
    df = read_table(out)
    assert list(df.columns[:22]) == ["time", *LABELS]
    for name in EXTRAS:
        assert name in df.columns
    np.testing.assert_allclose(df["time"], t, rtol=0, atol=0)
    expected = ref.simulate(harmony_dict(), W)
    check_forces(df, expected, LABELS)
    # extra columns, from the reference forces
    areas = ref.geometry_from_config(harmony_dict()).areas
    pressure = expected / areas / 1000.0
    # (CSV numbers are rounded to 6 decimals by default)
    np.testing.assert_allclose(df["peak_pressure_kPa"], pressure.max(axis=1), rtol=1e-6,
                               atol=1e-6)
    np.testing.assert_allclose(df["peak_pressure_to_pain_threshold"],
                               pressure.max(axis=1) / 120.0, rtol=1e-6, atol=1e-6)
    top2 = np.sort(pressure, axis=1)[:, -2:]
    clear = top2[:, 1] - top2[:, 0] > 1e-3
    assert clear.sum() > 10
    np.testing.assert_array_equal(df["peak_pressure_element"][clear],
                                  np.array(LABELS)[pressure.argmax(axis=1)][clear])
    rm = ref.model_from_config(harmony_dict())
    in_touch = [int((rm.compression(ref.solve_one(rm, w)) > 1e-12).sum())
                for w in ref.loadcell_to_cuff(W, harmony_dict()["load_cell"])]
    np.testing.assert_array_equal(df["contacts_in_touch"], in_touch)
    assert (df["contacts_in_touch"] < 21).any()
    assert (df["solver_iterations"] >= 1).all()
    # no temporary files beside the output
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([log.name, out.name])


def test_rigid_arm(harmony_files):
    folder, cfg, log, t, W = harmony_files
    out = folder / "rigid.csv"
    res = invoke(cfg, log, "-o", out, "--arm", "rigid")
    assert res.exit_code == 0, res.output
    rigid = ref.simulate(harmony_dict(), W, arm="rigid")
    check_forces(read_table(out), rigid, LABELS)
    # and it differs from the compliant arm (the option is not ignored)
    assert np.abs(rigid - ref.simulate(harmony_dict(), W)).max() > 0.01


def test_column_mapping_option_and_config_key(tmp_path):
    rng = np.random.default_rng(3)
    t, W = random_log(rng, 12)
    ati = ["Time (s)", "Fx (N)", "Fy (N)", "Fz (N)", "Tx (Nm)", "Ty (Nm)", "Tz (Nm)"]
    log = write_log(tmp_path / "ati.csv", t, W, names=ati)
    expected = ref.simulate(harmony_dict(), W)
    mapping = dict(zip(["time", *WRENCH_COLS], ati))
    args = []
    for spec_name, log_name in mapping.items():
        args += ["--column", f"{spec_name}={log_name}"]
    out = tmp_path / "a.csv"
    res = invoke(HARMONY_CONFIG, log, "-o", out, *args)
    assert res.exit_code == 0, res.output
    check_forces(read_table(out), expected, LABELS)
    np.testing.assert_allclose(read_table(out)["time"], t)
    # the same with load_cell.columns
    cfg = harmony_dict()
    cfg["load_cell"]["columns"] = mapping
    cfg_path = write_config(tmp_path / "ati.yaml", cfg)
    out = tmp_path / "b.parquet"
    res = invoke(cfg_path, log, "-o", out)
    assert res.exit_code == 0, res.output
    check_forces(read_table(out), expected, LABELS)
    # the option overrides the config key: swap Fy and Fz through --column
    out = tmp_path / "c.csv"
    res = invoke(cfg_path, log, "-o", out, "--column", "Fy=Fz (N)", "--column", "Fz=Fy (N)")
    assert res.exit_code == 0, res.output
    check_forces(read_table(out), ref.simulate(harmony_dict(), W[:, [0, 2, 1, 3, 4, 5]]), LABELS)


def test_chunking_does_not_change_results(harmony_files):
    folder, cfg, log, t, W = harmony_files
    a, b = folder / "a.csv", folder / "b.csv"
    assert invoke(cfg, log, "-o", a).exit_code == 0
    assert invoke(cfg, log, "-o", b, "--chunk-rows", "3").exit_code == 0
    da, db = read_table(a), read_table(b)
    assert len(db) == len(W)
    np.testing.assert_allclose(db[LABELS].to_numpy(), da[LABELS].to_numpy(), atol=1e-9)
    np.testing.assert_allclose(db["time"], t)


def test_progress_on_request(harmony_files):
    folder, cfg, log, t, W = harmony_files
    out = folder / "p.csv"
    res = invoke(cfg, log, "-o", out, "--progress", "--chunk-rows", "7")
    assert res.exit_code == 0, res.output
    assert "simulate" in res.stderr
    check_forces(read_table(out), ref.simulate(harmony_dict(), W), LABELS)
    assert res.stdout == ""                    # progress and summary go to stderr


def test_comment_lines_before_the_header(tmp_path):
    rng = np.random.default_rng(4)
    t, W = random_log(rng, 5)
    log = write_log(tmp_path / "log.csv", t, W)
    log.write_text("# SYNTHETIC test log\n# units s, N, N*m\n" + log.read_text())
    out = tmp_path / "o.csv"
    assert invoke(HARMONY_CONFIG, log, "-o", out).exit_code == 0
    check_forces(read_table(out), ref.simulate(harmony_dict(), W), LABELS)


def test_quick_start_example_log(tmp_path):
    """The bundled example log with the Harmony config (README quick start)."""
    log = REPO / "examples" / "wrench_log.csv"
    if not log.exists():
        pytest.skip("no bundled example log")
    before = log.read_bytes()
    out = tmp_path / "forces.csv"
    res = invoke(HARMONY_CONFIG, log, "-o", out, "--baseline", "first:2")
    assert res.exit_code == 0, res.output
    assert log.read_bytes() == before
    raw = pd.read_csv(log, comment="#")
    df = read_table(out)
    assert len(df) == len(raw)
    t, W = raw["time"].to_numpy(), raw[WRENCH_COLS].to_numpy()
    base = ref.simulate(harmony_dict(), W[t <= t[0] + 2.0].mean(axis=0))
    idx = np.linspace(0, len(raw) - 1, 40).astype(int)
    check_forces(df.iloc[idx], ref.simulate(harmony_dict(), W[idx]) - base, LABELS)


# --------------------------------------------------------------------------- baselines
def test_baseline_zero_at_zero_wrench_gives_zeros(tmp_path):
    t = np.arange(6) * 0.1
    log = write_log(tmp_path / "zero.csv", t, np.zeros((6, 6)))
    out = tmp_path / "o.csv"
    res = invoke(HARMONY_CONFIG, log, "-o", out, "--baseline", "zero")
    assert res.exit_code == 0, res.output
    np.testing.assert_allclose(read_table(out)[LABELS].to_numpy(), 0.0, atol=1e-12)
    # baseline none: the preload, f0 = 15 N * radians(35) / 3 on every element
    res = invoke(HARMONY_CONFIG, log, "-o", out)
    assert res.exit_code == 0
    # (CSV forces are written to 1 uN by default)
    np.testing.assert_allclose(read_table(out)[LABELS].to_numpy(),
                               15 * math.radians(35) / 3, atol=1e-6)
    res = invoke(HARMONY_CONFIG, log, "-o", out, "--decimals", "-1")
    assert res.exit_code == 0
    np.testing.assert_allclose(read_table(out)[LABELS].to_numpy(),
                               15 * math.radians(35) / 3, rtol=1e-12)


def test_baseline_zero_subtracts_the_forces_at_zero_wrench(harmony_files):
    folder, cfg, log, t, W = harmony_files
    out = folder / "o.csv"
    assert invoke(cfg, log, "-o", out, "--baseline", "zero").exit_code == 0
    expected = ref.simulate(harmony_dict(), W) - ref.simulate(harmony_dict(), np.zeros(6))
    check_forces(read_table(out), expected, LABELS)


@pytest.mark.parametrize("spec, t0", [("first:0.055", 100.0), ("window:0.105:0.205", 0.0),
                                      ("window:100.105:100.305", 100.0)])
@pytest.mark.parametrize("arm", ["compliant", "rigid"])
def test_baseline_windows(tmp_path, spec, t0, arm):
    rng = np.random.default_rng(5)
    t, W = random_log(rng, 40)
    t = t + t0                                  # the log need not start at 0 s
    log = write_log(tmp_path / "log.csv", t, W)
    out = tmp_path / "o.parquet"
    res = invoke(HARMONY_CONFIG, log, "-o", out, "--baseline", spec, "--arm", arm)
    assert res.exit_code == 0, res.output
    kind, *bounds = spec.split(":")
    if kind == "first":
        mask = t <= t[0] + float(bounds[0])
    else:
        mask = (t >= float(bounds[0])) & (t <= float(bounds[1]))
    assert 2 <= mask.sum() < len(t)
    base = ref.simulate(harmony_dict(), W[mask].mean(axis=0), arm=arm)
    expected = ref.simulate(harmony_dict(), W, arm=arm) - base
    df = read_table(out)
    check_forces(df, expected, LABELS)
    # peak pressure stays absolute (preload included) under a baseline
    absolute = ref.simulate(harmony_dict(), W, arm=arm)
    areas = ref.geometry_from_config(harmony_dict()).areas
    np.testing.assert_allclose(df["peak_pressure_kPa"], (absolute / areas).max(axis=1) / 1e3,
                               rtol=1e-6, atol=1e-6)


# --------------------------------------------------------------------------- random configs
@st.composite
def random_setups(draw):
    geo = draw(geometries(max_rows=3, max_count=8))
    rows = geo["rows"]
    if draw(st.booleans()):
        rows = {f"R{lab}": x for lab, x in rows.items()}      # multi-letter row labels
    n_rows, count = len(rows), geo["count"]
    angles = {"start": geo["start"], "step": geo["step"], "count": count}
    if geo["width"] is not None:
        angles["width"] = geo["width"]
    labels = [f"{r}{j}" for r in rows for j in range(count)]
    arm = draw(st.sampled_from(["compliant", "rigid"]))

    def stiffness(lo, hi, allow_inf):
        val = st.floats(math.log(lo), math.log(hi)).map(lambda v: round(math.exp(v), 3))
        if allow_inf:
            val = st.one_of(val, val, val, st.just(math.inf))
        form = draw(st.sampled_from(["scalar", "per_row", "per_angle", "nested", "labels",
                                     "csv"]))
        if form == "scalar":
            return form, draw(val)
        if form == "per_row":
            return form, {"per_row": draw(st.lists(val, min_size=n_rows, max_size=n_rows))}
        if form == "per_angle":
            return form, {"per_angle": draw(st.lists(val, min_size=count, max_size=count))}
        if form == "nested":
            return form, [draw(st.lists(val, min_size=count, max_size=count))
                          for _ in range(n_rows)]
        vals = draw(st.lists(val, min_size=len(labels), max_size=len(labels)))
        return form, dict(zip(labels, vals))

    basis = draw(st.sampled_from(["indenter", "element"]))
    t_form, tissue = stiffness(*((800, 12000) if basis == "indenter" else (2e3, 1e5)), False)
    c_form, cuff = stiffness(1e4, 1e7, arm == "compliant")
    load_cell = {"position": draw(st.lists(st.floats(-0.1, 0.1), min_size=3, max_size=3)),
                 "convention": draw(st.sampled_from(["robot_on_cuff", "cuff_on_robot"])),
                 "force_unit": draw(st.sampled_from(["N", "lbf"])),
                 "moment_unit": draw(st.sampled_from(["N*m", "N*mm"]))}
    rot = draw(st.sampled_from(["none", "euler", "matrix"]))
    angles3 = draw(st.lists(st.floats(-180, 180), min_size=3, max_size=3))
    if rot == "euler":
        load_cell["euler_xyz_deg"] = angles3
    elif rot == "matrix":
        load_cell["rotation"] = Rotation.from_euler("zxy", angles3, degrees=True).as_matrix() \
            .tolist()
    strap = {"tension": draw(st.floats(0.0, 30.0)),
             "model": draw(st.sampled_from(["hoop", "handles"]))}
    if strap["model"] == "handles" and draw(st.booleans()):
        a = draw(st.floats(-180, 180))
        strap["handle_angles"] = [a, a + draw(st.floats(30, 330))]
        strap["axial_position"] = draw(st.floats(-0.03, 0.03))
    tissue_section = {"stiffness": tissue, "basis": basis,
                      "poisson_ratio": draw(st.floats(0.0, 0.5))}
    if basis == "indenter" and draw(st.booleans()):
        tissue_section["indenter_diameter"] = draw(st.floats(0.004, 0.02))
    cfg = {"name": "random", "geometry": {"radius": geo["radius"], "rows": rows,
                                          "row_width": geo["row_width"], "angles": angles},
           "load_cell": load_cell, "tissue": tissue_section, "cuff": {"stiffness": cuff},
           "strap": strap}
    if draw(st.booleans()):
        cfg["interface"] = {"shear_ratio": draw(st.floats(0.05, 1.0))}
    n = draw(st.integers(1, 25))
    seed = draw(st.integers(0, 2 ** 32 - 1))
    big = draw(st.floats(1.0, 500.0))
    return cfg, labels, arm, t_form, c_form, n, seed, big


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(setup=random_setups())
def test_random_configs_and_logs_agree_with_reference(setup):
    cfg, labels, arm, t_form, c_form, n, seed, big = setup
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        rows_of = [(r, j) for r in cfg["geometry"]["rows"] for j in range(len(labels) // len(
            cfg["geometry"]["rows"]))]
        for section, form in (("tissue", t_form), ("cuff", c_form)):
            if form == "csv":                    # the drawn label mapping, as a CSV file
                # (a fit-stiffness CSV holds measured, finite values)
                values = {k: (1e7 if math.isinf(v) else v)
                          for k, v in cfg[section]["stiffness"].items()}
                (folder / "maps").mkdir(exist_ok=True)
                lines = ["location,row,angle_index,stiffness_N_per_m,std_N_per_m,n_trials"]
                lines += [f"{r}{j},{r},{j},{values[f'{r}{j}']!r},1.0,3" for r, j in rows_of]
                (folder / "maps" / f"{section}.csv").write_text("\n".join(lines) + "\n")
                cfg[section]["stiffness"] = f"maps/{section}.csv"
        rmodel = ref.model_from_config(cfg, arm, base_dir=folder)
        assume(ref.scaled_shear_conditioning(rmodel) > 1e-5)
        rng = np.random.default_rng(seed)
        # wrenches in the cuff frame up to `big` N, then expressed as the load cell reads them
        Wc = rng.normal(size=(n, 6))
        Wc[:, :3] *= big / np.maximum(np.linalg.norm(Wc[:, :3], axis=1, keepdims=True), 1e-9)
        Wc[:, 3:] *= 0.05 * big / np.maximum(np.linalg.norm(Wc[:, 3:], axis=1, keepdims=True),
                                             1e-9)
        lc = cfg["load_cell"]
        R = ref.rotation_from_config(lc)
        p = np.array(lc["position"])
        s = 1.0 if lc["convention"] == "robot_on_cuff" else -1.0
        fu = ref.LBF_IN_N if lc["force_unit"] == "lbf" else 1.0
        mu = 1e-3 if lc["moment_unit"] == "N*mm" else 1.0
        F_lc = (s * Wc[:, :3]) @ R / fu                 # R^T F
        M_lc = (s * Wc[:, 3:] - np.cross(p, s * Wc[:, :3])) @ R / mu
        W_lc = np.hstack([F_lc, M_lc])
        np.testing.assert_allclose(ref.loadcell_to_cuff(W_lc, lc), Wc, atol=1e-9)
        t = np.arange(n) * 0.01
        ext = ".parquet" if seed % 2 else ".csv"
        log = write_log(folder / f"log{ext}", t, W_lc)
        cfg_path = write_config(folder / "cfg.yaml", cfg)
        out = folder / ("out.csv" if seed % 3 else "out.parquet")
        res = invoke(cfg_path, log, "-o", out, "--arm", arm)
        assert res.exit_code == 0, res.output
        df = read_table(out)
        assert list(df.columns[:1 + len(labels)]) == ["time", *labels]
        expected = ref.solve_forces(rmodel, Wc)
        check_forces(df, expected, labels)


# --------------------------------------------------------------------------- bad inputs
def _good_log(folder):
    return write_log(folder / "log.csv", np.arange(5) * 0.1,
                     np.tile([0, 0, 10.0, 0, 0, 0], (5, 1)))


BAD_LOG_TEXT = {
    "text_in_number": ("time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,1,0,0,0\n0.1,0,abc,1,0,0,0\n",
                       ["Fy", "abc"]),
    "nan_in_number": ("time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,1,0,0,0\n0.1,0,0,nan,0,0,0\n",
                      ["Fz", "NaN"]),
    "empty_cell": ("time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,1,0,0,0\n0.1,0,0,1,,0,0\n", ["Mx"]),
    "inf_in_number": ("time,Fx,Fy,Fz,Mx,My,Mz\n0,inf,0,1,0,0,0\n", ["Fx"]),
    "text_in_time": ("time,Fx,Fy,Fz,Mx,My,Mz\nnoon,0,0,1,0,0,0\n", ["time"]),
    "missing_column": ("time,Fx,Fy,Fz,Mx,My\n0,0,0,1,0,0\n", ["Mz"]),
    "empty_file": ("", []),
    "header_only": ("time,Fx,Fy,Fz,Mx,My,Mz\n", []),
    "duplicate_column": ("time,Fx,Fy,Fz,Mx,My,Mz,Fx\n0,0,0,1,0,0,0,5\n", ["Fx"]),
}


@pytest.mark.parametrize("case", sorted(BAD_LOG_TEXT))
def test_bad_csv_logs(tmp_path, case):
    text, fragments = BAD_LOG_TEXT[case]
    log = tmp_path / "bad.csv"
    log.write_text(text)
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv")
    assert_clean_error(res, 1, before, tmp_path, "bad.csv", *fragments)


def test_bad_value_late_in_a_long_log_leaves_nothing_behind(tmp_path):
    lines = ["time,Fx,Fy,Fz,Mx,My,Mz"] + [f"{0.01 * i:.2f},0,0,{i % 30},0,0,0" for i in range(60)]
    lines.append("0.60,0,0,oops,0,0,0")
    log = tmp_path / "late.csv"
    log.write_text("\n".join(lines) + "\n")
    # a previous result at the output path survives a failed run untouched
    out = tmp_path / "out.csv"
    out.write_text("previous result\n")
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", out, "--chunk-rows", "5")
    assert_clean_error(res, 1, before, tmp_path, "late.csv", "Fz", "oops", "62")


@pytest.mark.parametrize("case", ["string_column", "nan", "empty", "garbage"])
def test_bad_parquet_logs(tmp_path, case):
    log = tmp_path / "bad.parquet"
    df = pd.DataFrame({c: [0.0, 1.0, 2.0] for c in ["time", *WRENCH_COLS]})
    fragments = []
    if case == "string_column":
        df = df.astype({"Fy": str})
        fragments = ["Fy"]
    elif case == "nan":
        df.loc[1, "Mz"] = np.nan
        fragments = ["Mz"]
    elif case == "empty":
        df = df.iloc[:0]
    if case == "garbage":
        log.write_bytes(b"this is not a parquet file\n" * 10)
    else:
        df.to_parquet(log)
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.parquet")
    assert_clean_error(res, 1, before, tmp_path, "bad.parquet", *fragments)


def test_missing_or_unreadable_config_and_log(tmp_path):
    log = _good_log(tmp_path)
    (tmp_path / "folder.yaml").mkdir()
    (tmp_path / "latin1.yaml").write_bytes("name: caf\xe9\n".encode("latin-1"))
    (tmp_path / "folder.csv").mkdir()
    before = snapshot(tmp_path)
    out = tmp_path / "out.csv"
    for cfg in ("nope.yaml", "folder.yaml", "latin1.yaml"):
        res = invoke(tmp_path / cfg, log, "-o", out)
        assert_clean_error(res, 1, before, tmp_path, cfg)
    for bad_log in ("nope.csv", "folder.csv", "nope.parquet"):
        res = invoke(HARMONY_CONFIG, tmp_path / bad_log, "-o", out)
        assert_clean_error(res, 1, before, tmp_path, bad_log)


def test_invalid_config_names_file_and_key(tmp_path):
    log = _good_log(tmp_path)
    d = harmony_dict()
    d["cuff"]["stiffness"] = {"per_angle": [1e5] * 6}
    cfg = write_config(tmp_path / "bad.yaml", d)
    before = snapshot(tmp_path)
    res = invoke(cfg, log, "-o", tmp_path / "out.csv")
    assert_clean_error(res, 1, before, tmp_path, "bad.yaml", "cuff.stiffness.per_angle")


def test_infinitely_stiff_element_in_the_rigid_arm(tmp_path):
    log = _good_log(tmp_path)
    d = harmony_dict()
    d["cuff"]["stiffness"] = {"per_angle": [1e5, 1e5, 1e5, math.inf, 1e5, 1e5, 1e5]}
    cfg = write_config(tmp_path / "stiff.yaml", d)
    assert invoke(cfg, log, "-o", tmp_path / "ok.csv").exit_code == 0     # compliant: fine
    (tmp_path / "ok.csv").unlink()
    before = snapshot(tmp_path)
    res = invoke(cfg, log, "-o", tmp_path / "out.csv", "--arm", "rigid")
    assert_clean_error(res, 1, before, tmp_path, "stiff.yaml", "cuff.stiffness", "A3")


def test_singular_geometry_is_a_config_error(tmp_path):
    log = _good_log(tmp_path)
    d = harmony_dict()
    d["geometry"]["angles"] = {"start": 90.0, "step": 30.0, "count": 1, "width": 30.0}
    d["cuff"]["stiffness"] = 1e5
    cfg = write_config(tmp_path / "one.yaml", d)
    before = snapshot(tmp_path)
    res = invoke(cfg, log, "-o", tmp_path / "out.csv")
    assert_clean_error(res, 1, before, tmp_path, "one.yaml", "geometry")


def test_baseline_window_without_samples(tmp_path):
    log = _good_log(tmp_path)                    # 0 ... 0.4 s
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv", "--baseline", "window:5:6")
    assert_clean_error(res, 1, before, tmp_path, "log.csv", "--baseline")
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv", "--baseline",
                 "window:0.15:0.18")             # between two samples
    assert_clean_error(res, 1, before, tmp_path, "log.csv", "--baseline")


@pytest.mark.parametrize("spec", ["window:a:b", "window:1", "window:1:2:3", "first:-1", "first:",
                                  "first:0", "first", "bogus", "window:nan:1", "window:0:inf",
                                  "zero:1", ""])
def test_malformed_baseline_is_usage(tmp_path, spec):
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv", "--baseline", spec)
    assert_clean_error(res, 2, before, tmp_path, "--baseline")


def test_reversed_or_empty_window_is_usage_and_says_why(tmp_path):
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    for spec in ("window:0.3:0.1", "window:0.2:0.2"):
        res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv", "--baseline", spec)
        assert_clean_error(res, 2, before, tmp_path, "--baseline", spec, "T0 < T1")


def test_output_equal_to_an_input_is_usage(tmp_path):
    log = _good_log(tmp_path)
    pq_log = write_log(tmp_path / "log.parquet", np.arange(3) * 0.1, np.zeros((3, 6)))
    cfg = write_config(tmp_path / "cfg.yaml", harmony_dict())
    before = snapshot(tmp_path)
    for lg, out in ((log, log), (log, tmp_path / "." / "log.csv"), (pq_log, pq_log),
                    (log, Path(os.path.relpath(log)))):
        res = invoke(cfg, lg, "-o", out)
        assert_clean_error(res, 2, before, tmp_path, "-o")
    res = invoke(cfg, log, "-o", cfg)
    assert_clean_error(res, 2, before, tmp_path, "-o")


def test_output_equal_to_the_stiffness_csv_is_usage(tmp_path):
    # the stiffness map the config reads is an input too
    rows = ["location,row,angle_index,stiffness_N_per_m,std_N_per_m,n_trials"]
    rows += [f"{lab},{lab[0]},{lab[1:]},4242.0,100.0,3" for lab in LABELS]
    (tmp_path / "k.csv").write_text("\n".join(rows) + "\n")
    d = harmony_dict()
    d["tissue"]["stiffness"] = "k.csv"
    cfg = write_config(tmp_path / "cfg.yaml", d)
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    res = invoke(cfg, log, "-o", tmp_path / "k.csv")
    assert_clean_error(res, 2, before, tmp_path, "-o", "k.csv")


@pytest.mark.parametrize("name", ["out.json", "out.xlsx", "out", "out.csv.bak"])
def test_unknown_output_extension_is_usage(tmp_path, name):
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / name)
    assert_clean_error(res, 2, before, tmp_path, name, "-o")


def test_other_usage_errors(tmp_path):
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    out = tmp_path / "out.csv"
    cases = [
        (["-o", tmp_path / "no_such_folder" / "out.csv"], ["-o"]),
        (["-o", out, "--arm", "soft"], ["--arm"]),
        (["-o", out, "--column", "Fx"], ["--column"]),
        (["-o", out, "--column", "Fq=Fx"], ["--column", "Fq"]),
        ([], ["-o"]),                                            # no output given
    ]
    for extra, fragments in cases:
        res = invoke(HARMONY_CONFIG, log, *extra)
        assert_clean_error(res, 2, before, tmp_path, *fragments)
    (tmp_path / "folder_out.csv").mkdir()
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "folder_out.csv")
    assert res.exit_code == 2 and one_line(res.stderr)


def test_column_mapped_to_a_missing_log_column(tmp_path):
    log = _good_log(tmp_path)
    before = snapshot(tmp_path)
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "out.csv", "--column", "Fx=Fx (N)")
    assert_clean_error(res, 1, before, tmp_path, "log.csv", "Fx (N)")


# --------------------------------------------------------------------------- help
def test_help_shows_units_and_an_example():
    res = CliRunner().invoke(phri, ["simulate", "--help"])
    assert res.exit_code == 0
    text = res.output
    assert "[N]" in text and "[s]" in text and ("N*m" in text or "N*mm" in text)
    assert "Example" in text and "phri simulate" in text
    for option in ("--arm", "--baseline", "--column", "-o"):
        assert option in text
    res = CliRunner().invoke(phri, ["--help"])
    assert res.exit_code == 0 and "simulate" in res.output
