"""``phri simulate --plot`` and the max-pooling accumulator behind it."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from support.helpers import HARMONY_CONFIG, REPO, one_line
from phri_cli.main import phri
from phri_spring.workflows.plots.maxpool import MaxPool

EXAMPLE = REPO / "examples" / "wrench_log.csv"


def feed(pool, t, f, p, cuts):
    edges = [0, *sorted(set(cuts)), len(t)]
    for a, b in zip(edges[:-1], edges[1:]):
        pool(t[a:b], f[a:b], p[a:b])
    return pool.result()


@settings(max_examples=60, deadline=None)
@given(m=st.integers(1, 700), n=st.integers(1, 4), bins=st.integers(1, 40),
       total=st.one_of(st.none(), st.integers(1, 1500)), seed=st.integers(0, 2**31 - 1),
       cuts=st.lists(st.integers(1, 699), max_size=8))
def test_maxpool_keeps_every_peak(m, n, bins, total, seed, cuts):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 0.02, m))
    f = rng.exponential(size=(m, n))
    f[rng.random((m, n)) < 0.05] = np.nan           # samples that did not converge
    p = rng.exponential(size=m) * 100
    res = feed(MaxPool(n, total=total, bins=bins), t, f, p, [c for c in cuts if c < m])
    w = res.samples_per_group
    k = math.ceil(m / w)
    # bounded: never more than 2 * bins groups, whatever the length
    assert len(res.time_start) == k <= 2 * bins
    assert res.samples == m
    # each group is the maximum over its own samples (computed here group by group)
    for g in range(k):
        sl = slice(g * w, min(m, (g + 1) * w))
        assert res.time_start[g] == t[sl][0] and res.time_end[g] == t[sl][-1]
        col = f[sl]
        want = np.array([np.nanmax(col[:, j]) if np.isfinite(col[:, j]).any() else np.nan
                         for j in range(n)])
        np.testing.assert_array_equal(res.forces[g], want)
        assert res.peak_pressure[g] == np.max(p[sl])
    # no peak lost
    if np.isfinite(f).any():
        assert np.nanmax(res.forces) == np.nanmax(f)
    else:
        assert np.isnan(res.forces).all()
    j = int(np.argmax(p))
    assert res.peak_kpa == p[j] and res.peak_time == t[j]


def test_maxpool_group_size_from_the_total():
    pool = MaxPool(2, total=10_000, bins=100)
    t = np.arange(10_000.0)
    res = feed(pool, t, np.zeros((10_000, 2)), np.zeros(10_000), [3333, 6000])
    assert res.samples_per_group == 100 and len(res.time_start) == 100


def invoke(*args):
    return CliRunner().invoke(phri, ["simulate", *map(str, args)], catch_exceptions=False)


@pytest.mark.parametrize("ext, magic", [(".png", b"\x89PNG"), (".svg", b"<?xml"),
                                        (".pdf", b"%PDF")])
def test_plot_is_written(tmp_path, ext, magic):
    out, plot = tmp_path / "f.parquet", tmp_path / f"plot{ext}"
    res = invoke(HARMONY_CONFIG, EXAMPLE, "-o", out, "--plot", plot)
    assert res.exit_code == 0, res.stderr
    assert plot.read_bytes().startswith(magic)
    assert f"plot {plot}" in res.stderr
    section = tmp_path / f"plot_section{ext}"            # the pressure around the limb
    assert section.read_bytes().startswith(magic)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["f.parquet", plot.name,
                                                                 section.name])


def test_plot_peak_is_the_forces_files_peak(tmp_path):
    from phri_spring.io.config import load_config
    from phri_spring.workflows.simulate import simulate_file

    cfg = load_config(HARMONY_CONFIG)
    pool = MaxPool(21, bins=50)
    simulate_file(cfg, EXAMPLE, tmp_path / "f.parquet", on_chunk=pool, chunk_rows=1000)
    df = pd.read_parquet(tmp_path / "f.parquet")
    res = pool.result()
    i = int(np.argmax(df["peak_pressure_kPa"].to_numpy()))
    assert res.peak_kpa == df["peak_pressure_kPa"].iloc[i]
    assert res.peak_time == df["time"].iloc[i]
    labels = [c for c in df.columns if len(c) == 2 and c[1].isdigit()]
    assert labels[res.peak_element] == df["peak_pressure_element"].iloc[i]
    # the heat map's columns hold the largest force of each element (absolute forces)
    np.testing.assert_array_equal(np.nanmax(res.forces, axis=0), df[labels].max().to_numpy())


def test_bad_plot_paths(tmp_path):
    out = tmp_path / "f.csv"
    res = invoke(HARMONY_CONFIG, EXAMPLE, "-o", out, "--plot", tmp_path / "p.jpg")
    assert res.exit_code == 2 and one_line(res.stderr) and "--plot" in res.stderr
    res = invoke(HARMONY_CONFIG, EXAMPLE, "-o", out, "--plot", tmp_path / "nodir" / "p.png")
    assert res.exit_code == 2 and one_line(res.stderr)
    res = invoke(HARMONY_CONFIG, EXAMPLE, "-o", out, "--plot", out.with_suffix(".png").
                 with_name("f.csv"))
    assert res.exit_code == 2 and one_line(res.stderr)
    assert list(tmp_path.iterdir()) == []


def test_failed_run_leaves_no_plot(tmp_path):
    log = tmp_path / "bad.csv"
    log.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,1,2,3,4,5,6\n0.01,1,x,3,4,5,6\n")
    res = invoke(HARMONY_CONFIG, log, "-o", tmp_path / "f.csv", "--plot", tmp_path / "p.png")
    assert res.exit_code == 1 and one_line(res.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]
