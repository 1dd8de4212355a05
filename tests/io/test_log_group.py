"""The TDMS group / MAT struct is a parameter of its own, from the config to the reader.

``load_cell.group`` becomes ``Config.log_group`` (not an entry of the column
map), ``--group`` overrides it, and both reach the lab-file reader as its
``group`` argument, for ``simulate`` and ``simulate --uncertainty`` alike: the
column map the reader gets holds spec names only, and of a TDMS file with two
groups of the same channels the chosen one is read.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from support.helpers import HARMONY_CONFIG, REPO
from phri_cli.main import phri

pytest.importorskip("nptdms")

WRENCH = ["Fx", "Fy", "Fz", "Mx", "My", "Mz"]


def _two_group_tdms(path):
    """Group ``rig``: the bundled example log; group ``other``: the same at half the load."""
    from nptdms import ChannelObject, GroupObject, TdmsWriter

    df = pd.read_csv(REPO / "examples" / "wrench_log.csv", comment="#")
    t, w = df["time"].to_numpy(float), df[WRENCH].to_numpy(float)
    objs = []
    for group, scale in (("other", 0.5), ("rig", 1.0)):
        objs += [GroupObject(group), ChannelObject(group, "time", t)]
        objs += [ChannelObject(group, n, w[:, j] * scale) for j, n in enumerate(WRENCH)]
    with TdmsWriter(str(path)) as wr:
        wr.write_segment(objs)
    return len(t)


@pytest.fixture
def reads(monkeypatch):
    """Every (column map, group) the TDMS reader is called with."""
    from phri_spring.io.logs import lab as labfiles
    from phri_spring.io.logs import formats as log_formats

    seen = []

    def spy(path, columns=None, *, group=None, **kw):
        seen.append((dict(columns or {}), group))
        return labfiles.iter_lab_log(path, columns, group=group, **kw)

    monkeypatch.setitem(log_formats.LOG_FORMATS, ".tdms",
                        dataclasses.replace(log_formats.LOG_FORMATS[".tdms"], read=spy))
    return seen


@pytest.mark.parametrize("extra", [(), ("--uncertainty", "2")])
def test_config_group_and_option_reach_the_reader(tmp_path, reads, extra):
    from phri_spring.io.config import LOG_GROUP_KEY, load_config

    n = _two_group_tdms(tmp_path / "two.tdms")
    d = yaml.safe_load(HARMONY_CONFIG.read_text())
    d["load_cell"]["group"] = "rig"
    cfg_path = tmp_path / "cfg.yaml"
    cfg_path.write_text(yaml.safe_dump(d))
    cfg = load_config(cfg_path)
    assert cfg.log_group == "rig" and LOG_GROUP_KEY not in cfg.log_columns

    def run(config, name, *opts):
        out = tmp_path / f"{name}.parquet"
        res = CliRunner().invoke(phri, ["simulate", str(config), str(tmp_path / "two.tdms"),
                                        "-o", str(out), "-q", *extra, *opts])
        assert res.exit_code == 0, res.stderr
        return pd.read_parquet(out)

    def forces(df):
        return df.drop(columns=["time"]).select_dtypes("number").to_numpy(float)

    from_config = run(cfg_path, "config")                   # load_cell.group: 'rig'
    chosen = run(cfg_path, "option", "--group", "other")    # --group wins over the config
    plain = run(HARMONY_CONFIG, "plain", "--group", "rig")  # --group without a config group
    assert [g for _, g in reads] == ["rig", "other", "rig"]
    assert all(LOG_GROUP_KEY not in cols for cols, _ in reads)
    assert len(from_config) == len(chosen) == n
    np.testing.assert_array_equal(forces(from_config), forces(plain))
    assert not np.array_equal(forces(from_config), forces(chosen))
