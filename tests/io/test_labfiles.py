"""Lab formats (TDMS, MATLAB .mat v5 and v7.3) for ``phri simulate`` and ``phri compare``.

The reference is the CSV path: the same numbers in a TDMS or MAT file give
forces (and RMSE tables) identical to the last bit (``==``, no tolerance).
Every bad file gives exit 1 and one line naming the file and the channel or
group, and leaves no output behind.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from support.helpers import HARMONY_CONFIG, REPO, one_line
from phri_cli.main import phri

pytest.importorskip("nptdms")
pytest.importorskip("scipy.io")

sys.path.insert(0, str(REPO / "examples"))
import make_lab_logs as mk  # noqa: E402

EXAMPLE = REPO / "examples" / "wrench_log.csv"
WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]
LABELS = [f"{r}{j}" for r in "ABC" for j in range(7)]


def invoke(*args):
    return CliRunner().invoke(phri, [*map(str, args)], catch_exceptions=False)


def simulate(log, out, *extra):
    res = invoke("simulate", HARMONY_CONFIG, log, "-o", out, "-q", *extra)
    assert res.exit_code == 0, res.stderr
    return pd.read_parquet(out)


def bad(tmp_path, log, *extra, key=None):
    out = tmp_path / "bad_out.parquet"
    res = invoke("simulate", HARMONY_CONFIG, log, "-o", out, *extra)
    assert res.exit_code == 1, res.output
    assert one_line(res.stderr), res.stderr
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr
    assert str(log) in res.stderr
    if key:
        assert key in res.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
    return res.stderr


def example_arrays():
    # parsed by Python's float() (another reader than the package's, correctly rounded)
    df = pd.read_csv(EXAMPLE, comment="#", dtype=str)
    num = np.array([[float(x) for x in df[c]] for c in ["time"] + WRENCH]).T
    return num[:, 0].copy(), num[:, 1:].copy()


def write_mat73(path, columns: dict, struct=None):
    """A MATLAB v7.3 file (HDF5 with MATLAB's 512-byte header), column vectors of doubles."""
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w", userblock_size=512) as f:
        grp = f.create_group(struct) if struct else f
        if struct:
            grp.attrs["MATLAB_class"] = np.bytes_("struct")
        for name, v in columns.items():
            ds = grp.create_dataset(name, data=np.asarray(v, dtype=np.float64)[None, :])
            ds.attrs["MATLAB_class"] = np.bytes_("double")
    head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 00:00:00 2026 " \
           b"HDF5 schema 1.00 ."
    head = head.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(head.ljust(512, b"\0"))
    return path


@pytest.fixture(scope="module")
def csv_forces(tmp_path_factory):
    out = tmp_path_factory.mktemp("csv") / "forces.parquet"
    return simulate(EXAMPLE, out)


def assert_same_forces(got: pd.DataFrame, want: pd.DataFrame, *, exact_time=True):
    assert list(got.columns) == list(want.columns)
    for col in LABELS + ["peak_pressure_kPa", "contacts_in_touch"]:
        assert np.array_equal(got[col].to_numpy(), want[col].to_numpy()), col
    if exact_time:
        assert np.array_equal(got["time"].to_numpy(), want["time"].to_numpy())
    else:   # waveform timing: start + i * increment, not the CSV's decimal text
        np.testing.assert_allclose(got["time"], want["time"], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- same forces
def test_committed_examples_match_the_script(tmp_path):
    # the bundled files are what the script writes (regenerated here and compared by value)
    t, w = example_arrays()
    mk.write_tdms(tmp_path / "w.tdms", t, w)
    from nptdms import TdmsFile

    a, b = TdmsFile.read(REPO / "examples" / "wrench_log.tdms"), TdmsFile.read(tmp_path / "w.tdms")
    for name in WRENCH:
        assert np.array_equal(a["wrench"][name][:], b["wrench"][name][:])
        assert np.array_equal(a["wrench"][name][:], w[:, WRENCH.index(name)])


@pytest.mark.parametrize("name, extra, exact_time", [
    ("wrench_log.tdms", (), False),
    ("wrench_log.mat", ("--group", "log"), True),
])
def test_bundled_lab_logs_give_the_csv_forces(tmp_path, csv_forces, name, extra, exact_time):
    got = simulate(REPO / "examples" / name, tmp_path / "f.parquet", *extra)
    assert_same_forces(got, csv_forces, exact_time=exact_time)


def test_tdms_time_channel_and_mat_top_level_and_v73(tmp_path, csv_forces):
    t, w = example_arrays()
    mk.write_tdms(tmp_path / "t.tdms", t, w, group="Untitled", time_channel=True)
    mk.write_mat(tmp_path / "top.mat", t, w, struct=None)
    cols = {"time": t, **{n: w[:, j] for j, n in enumerate(WRENCH)}}
    write_mat73(tmp_path / "v73.mat", cols)
    write_mat73(tmp_path / "v73s.mat", cols, struct="rig")
    for log, extra in [("t.tdms", ()), ("top.mat", ()), ("v73.mat", ()),
                       ("v73s.mat", ("--group", "rig"))]:
        got = simulate(tmp_path / log, tmp_path / f"{log}.parquet", *extra)
        assert_same_forces(got, csv_forces, exact_time=True)


def test_column_map_and_config_group(tmp_path, csv_forces):
    t, w = example_arrays()
    # channels named by the rig, mapped with --column; several groups, chosen in the config
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    names = ["Kraft X", "Kraft Y", "Kraft Z", "Moment X", "Moment Y", "Moment Z"]
    with TdmsWriter(str(tmp_path / "rig.tdms")) as wr:
        objs = [GroupObject("other"), ChannelObject("other", "x", np.zeros(3)),
                GroupObject("loadcell"), ChannelObject("loadcell", "Zeit", t)]
        objs += [ChannelObject("loadcell", n, w[:, j]) for j, n in enumerate(names)]
        wr.write_segment(objs)
    cfg_path = tmp_path / "cfg.yaml"
    cfg_text = yaml.safe_load(HARMONY_CONFIG.read_text())
    cfg_text["load_cell"]["group"] = "loadcell"
    cfg_path.write_text(yaml.safe_dump(cfg_text))
    cols = ["--column", "time=Zeit"] + [a for j, n in enumerate(names)
                                         for a in ("--column", f"{WRENCH[j]}={n}")]
    res = invoke("simulate", cfg_path, tmp_path / "rig.tdms", "-o", tmp_path / "r.parquet", "-q",
                 *cols)
    assert res.exit_code == 0, res.stderr
    assert_same_forces(pd.read_parquet(tmp_path / "r.parquet"), csv_forces)
    # without the config's group the file is ambiguous: one line, naming both groups
    err = bad(tmp_path, tmp_path / "rig.tdms", *cols)
    assert "'other', 'loadcell'" in err and "--group" in err


def test_lab_log_reads_in_chunks_like_one_piece(tmp_path):
    from phri_spring.io.logs import iter_wrench_log

    t, w = example_arrays()
    chunks = list(iter_wrench_log(REPO / "examples" / "wrench_log.mat", {"@group": "log"},
                                  chunk_rows=1000))
    assert [c.start for c in chunks] == [0, 1000, 2000, 3000, 4000]
    assert np.array_equal(np.concatenate([c.wrench for c in chunks]), w)
    from phri_spring.io.logs import count_rows

    assert count_rows(REPO / "examples" / "wrench_log.tdms") == len(t)
    assert count_rows(REPO / "examples" / "wrench_log.mat") == len(t)


# --------------------------------------------------------------------------- bad files
def test_missing_channel(tmp_path):
    t, w = example_arrays()
    mk.write_tdms(tmp_path / "a.tdms", t, w)
    err = bad(tmp_path, tmp_path / "a.tdms", "--column", "Fy=Fyy", key="Fyy")
    assert "missing channel 'Fyy'" in err and "did you mean 'Fy'" in err


def test_channel_of_wrong_length(tmp_path):
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    t, w = example_arrays()
    with TdmsWriter(str(tmp_path / "a.tdms")) as wr:
        wr.write_segment([GroupObject("g"), ChannelObject("g", "time", t)] +
                         [ChannelObject("g", n, w[: (len(t) - 1 if n == "Mz" else None), j])
                          for j, n in enumerate(WRENCH)])
    err = bad(tmp_path, tmp_path / "a.tdms", key="Mz")
    assert f"{len(t) - 1} values; expected {len(t)}" in err
    mk.write_mat(tmp_path / "b.mat", t[:-2], w, struct=None)       # time too short
    err = bad(tmp_path, tmp_path / "b.mat", key="Fx")
    assert f"expected {len(t) - 2}" in err


def test_missing_group_and_struct(tmp_path):
    bad(tmp_path, REPO / "examples" / "wrench_log.tdms", "--group", "wrnch",
        key="group 'wrnch' not found")
    err = bad(tmp_path, REPO / "examples" / "wrench_log.mat", "--group", "nolog",
              key="struct 'nolog' not found")
    assert "'log'" in err
    err = bad(tmp_path, REPO / "examples" / "wrench_log.mat", key="Fx")
    assert "choose one with --group" in err


def test_no_time_and_no_waveform(tmp_path):
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    t, w = example_arrays()
    with TdmsWriter(str(tmp_path / "a.tdms")) as wr:
        wr.write_segment([GroupObject("g")] + [ChannelObject("g", n, w[:, j])
                                               for j, n in enumerate(WRENCH)])
    err = bad(tmp_path, tmp_path / "a.tdms", key="time")
    assert "wf_increment" in err


def test_text_nan_and_garbage(tmp_path):
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    t, w = example_arrays()
    with TdmsWriter(str(tmp_path / "a.tdms")) as wr:
        wr.write_segment([GroupObject("g"), ChannelObject("g", "time", t)] +
                         [ChannelObject("g", n, (np.array(["x"] * len(t)) if n == "Fz"
                                                 else w[:, j])) for j, n in enumerate(WRENCH)])
    bad(tmp_path, tmp_path / "a.tdms", key="Fz")
    w2 = w.copy()
    w2[17, 4] = np.nan
    mk.write_mat(tmp_path / "n.mat", t, w2, struct=None)
    err = bad(tmp_path, tmp_path / "n.mat", key="My")
    assert "row 18" in err
    (tmp_path / "g.tdms").write_bytes(b"not a tdms file at all" * 10)
    bad(tmp_path, tmp_path / "g.tdms", key="cannot read as TDMS")
    (tmp_path / "g.mat").write_bytes(b"not a mat file at all" * 10)
    bad(tmp_path, tmp_path / "g.mat", key="cannot read")
    bad(tmp_path, tmp_path / "absent.tdms", key="not found")


def test_missing_extra_names_it(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "nptdms", None)       # import fails
    err = bad(tmp_path, REPO / "examples" / "wrench_log.tdms")
    assert "npTDMS" in err and "pip install -e '.[lab]'" in err
    monkeypatch.setitem(sys.modules, "pymatreader", None)
    t, w = example_arrays()
    write_mat73(tmp_path / "v.mat", {"time": t, **{n: w[:, j] for j, n in enumerate(WRENCH)}})
    err = bad(tmp_path, tmp_path / "v.mat")
    assert "pymatreader" in err and "pip install -e '.[lab]'" in err


def test_group_on_a_csv_is_a_usage_error(tmp_path):
    res = invoke("simulate", HARMONY_CONFIG, EXAMPLE, "-o", tmp_path / "x.csv", "--group", "g")
    assert res.exit_code == 2 and one_line(res.stderr) and "--group" in res.stderr


def test_lab_output_is_refused(tmp_path):
    res = invoke("simulate", HARMONY_CONFIG, EXAMPLE, "-o", tmp_path / "x.tdms")
    assert res.exit_code == 2 and one_line(res.stderr) and "x.tdms" in res.stderr


# --------------------------------------------------------------------------- compare
def _experiment_copy(tmp_path, fmt):
    """The bundled experiment with every trial table as TDMS or MAT (struct 'trial')."""
    src = REPO / "examples" / "experiment"
    man = yaml.safe_load((src / "manifest.yaml").read_text())
    for entry in man["trials"]:
        df = pd.read_csv(src / entry["file"], keep_default_na=False, dtype=str)
        stem = Path(entry["file"]).stem
        if fmt == "tdms":
            from nptdms import ChannelObject, GroupObject, TdmsWriter

            with TdmsWriter(str(tmp_path / f"{stem}.tdms")) as wr:
                objs = [GroupObject("trial")]
                for c in df.columns:
                    v = df[c].to_numpy()
                    objs.append(ChannelObject("trial", c, v.astype(str) if c == "condition"
                                              else np.array([float(x) for x in v])))
                wr.write_segment(objs)
            entry["file"] = f"{stem}.tdms"
        else:
            import scipy.io

            data = {c: (np.array(df[c].tolist(), dtype=object) if c == "condition"
                        else np.array([float(x) for x in df[c]])) for c in df.columns}
            scipy.io.savemat(str(tmp_path / f"{stem}.mat"), {"trial": data}, oned_as="column")
            entry["file"] = f"{stem}.mat"
    (tmp_path / "manifest.yaml").write_text(yaml.safe_dump(man))
    return tmp_path / "manifest.yaml"


@pytest.mark.parametrize("fmt", ["tdms", "mat"])
def test_compare_lab_trials_give_the_csv_tables(tmp_path, fmt):
    from phri_spring.workflows.compare.run import compare

    want = compare(HARMONY_CONFIG, REPO / "examples" / "experiment" / "manifest.yaml")
    man = _experiment_copy(tmp_path, fmt)
    got = compare(HARMONY_CONFIG, man, columns={"@group": "trial"})
    for name in ("rmse", "summary", "loads", "conditions"):
        a, b = getattr(got, name), getattr(want, name)
        assert list(a.columns) == list(b.columns)
        for c in a.columns:
            assert (a[c].to_numpy() == b[c].to_numpy()).all(), (name, c)
    # through the command line, with a missing group: one line, exit 1
    res = invoke("compare", HARMONY_CONFIG, man, "-o", tmp_path / "out", "--no-figures",
                 "--group", "trials")
    assert res.exit_code == 1 and one_line(res.stderr) and "'trials'" in res.stderr
    assert not (tmp_path / "out").exists()
    res = invoke("compare", HARMONY_CONFIG, man, "-o", tmp_path / "out", "--no-figures", "-q",
                 "--group", "trial")
    assert res.exit_code == 0, res.stderr


def test_row_count_is_that_of_the_group_read(tmp_path):
    """The progress total of a lab file of several groups counts the group that is read
    (given as --group or in the column map, as the reader takes it), not the longest
    channel of any group: 100 rows here, with 460 in the other group."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    from phri_spring.io.config import LOG_GROUP_KEY
    from phri_spring.io.logs import count_rows

    path = tmp_path / "two.tdms"
    with TdmsWriter(str(path)) as wr:
        wr.write_segment([GroupObject("long"), ChannelObject("long", "x", np.zeros(460)),
                          GroupObject("rig"), ChannelObject("rig", "time", np.arange(100.0))]
                         + [ChannelObject("rig", n, np.zeros(100)) for n in WRENCH])
    assert count_rows(path, "rig") == 100
    assert count_rows(path, columns={LOG_GROUP_KEY: "rig"}) == 100
