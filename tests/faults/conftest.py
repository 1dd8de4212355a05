"""Fixtures of the fault-injection tests: small real inputs, made once."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from .faultkit import CONFIG, EXPERIMENT, INDENTER, cli

TRIALS = ("iact_horizontal_1.csv", "iipass_horizontal_1.csv")


def _write_log(path: Path, n: int, seed: int = 3) -> Path:
    import pyarrow as pa
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    from phri_spring.synthetic.wrench import smooth_random_log

    t, w = smooth_random_log(n, seed=seed)
    data = {"time": np.round(np.arange(n) / 100.0, 2)}
    data.update({c: np.round(w[:, j], 4) for j, c in enumerate(("Fx", "Fy", "Fz", "Mx", "My",
                                                                 "Mz"))})
    table = pa.table(data)
    if path.suffix == ".csv":
        pacsv.write_csv(table, path, pacsv.WriteOptions(quoting_style="none",
                                                         quoting_header="none"))
    else:
        pq.write_table(table, path)
    return path


@pytest.fixture(scope="session")
def inputs(tmp_path_factory):
    """Small inputs of every command, UTF-8, with a reference run of each command."""
    base = tmp_path_factory.mktemp("fault_inputs")
    cfg = base / "cfg.yaml"
    shutil.copy(CONFIG, cfg)
    log_csv = _write_log(base / "log.csv", 300)
    log_pq = _write_log(base / "log.parquet", 300)
    exp = base / "experiment"
    exp.mkdir()
    for name in TRIALS:
        shutil.copy(EXPERIMENT / name, exp / name)
    shutil.copy(EXPERIMENT / "truth_tissue_stiffness.csv", exp / "stiffness.csv")
    (exp / "manifest.yaml").write_text(
        "baseline: no_load\n"
        "trials:\n"
        f"  - {{file: {TRIALS[0]}, experiment: I-Act, direction: horizontal, trial: 1}}\n"
        f"  - {{file: {TRIALS[1]}, experiment: II-Pass, direction: horizontal, trial: 1, "
        "baseline: start}\n", encoding="utf-8")
    ind = base / "indenter"
    shutil.copytree(INDENTER, ind, ignore=shutil.ignore_patterns("*.md", "README*"))
    ind_small = base / "indenter_small"     # two locations: quick plots
    ind_small.mkdir()
    for src in sorted(ind.glob("A[01]_*.csv")):
        shutil.copy(src, ind_small / src.name)
    man1 = exp / "manifest_one.yaml"         # one trial: quick figures
    man1.write_text("trials:\n"
                    f"  - {{file: {TRIALS[0]}, experiment: I-Act, direction: horizontal, "
                    "trial: 1}\n", encoding="utf-8")
    refs = base / "reference"
    refs.mkdir()
    ref = {"base": base, "cfg": cfg, "log_csv": log_csv, "log_parquet": log_pq, "exp": exp,
           "manifest": exp / "manifest.yaml", "stiffness": exp / "stiffness.csv",
           "indenter": ind, "indenter_small": ind_small, "manifest_one": man1}
    run = cli("simulate", cfg, log_csv, "-o", refs / "forces.csv", "-q")
    assert run.code == 0, run.stderr
    run = cli("compare", cfg, exp / "manifest.yaml", "-o", refs / "cmp", "--no-figures", "-q",
               "--tissue-stiffness", exp / "stiffness.csv")
    assert run.code == 0, run.stderr
    run = cli("fit-stiffness", ind, "-o", refs / "fit.csv", "-q")
    assert run.code == 0, run.stderr
    ref["ref_forces"] = (refs / "forces.csv").read_bytes()
    ref["ref_cmp"] = {n: (refs / "cmp" / n).read_bytes()
                      for n in ("rmse.csv", "summary.csv", "loads.csv", "conditions.csv")}
    ref["ref_fit"] = (refs / "fit.csv").read_bytes()
    return ref


@pytest.fixture(scope="session")
def long_logs(tmp_path_factory):
    """Two-hour logs (CSV and Parquet): a run takes long enough to be stopped mid-write."""
    base = tmp_path_factory.mktemp("fault_long_logs")
    n = 2 * 360_000
    return {"csv": _write_log(base / "long.csv", n, seed=5),
            "parquet": _write_log(base / "long.parquet", n, seed=5)}


@pytest.fixture
def out(tmp_path):
    """A folder for outputs, and an existing output in it (to prove it is left alone)."""
    folder = tmp_path / "out"
    folder.mkdir()
    return folder
