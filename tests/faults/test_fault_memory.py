"""Models too big for the machine (issue 19): refused from the estimate, before anything is
allocated or written, with one line naming the key; never an abort, a signal or a leftover
temporary file. ``PHRI_SPRING_MEMORY_LIMIT`` plays a small machine where the outcome must not
depend on the test machine's memory.
"""

from __future__ import annotations

import copy
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from phri_spring.io.config import config_from_dict, load_config
from phri_spring.io.memory import budget as mb
from phri_spring.io.memory.machine import ENV_LIMIT, available_memory

from .faultkit import CONFIG, Run, assert_fault, cli, command, snapshot

HUMAN = CONFIG.parent / "human_upper_arm.yaml"


def _config_text(count: int, *, step: float | None = None, base: Path = CONFIG) -> str:
    """The bundled config with ``count`` angular locations (a scalar cuff stiffness)."""
    text = base.read_text()
    step = 300.0 / count if step is None else step
    text = re.sub(r"count: 7\b.*", f"count: {count}", text)
    text = re.sub(r"step: 35.0\b.*", f"step: {step!r}", text)
    return re.sub(r"stiffness: \{per_angle: \[.*\]\}", "stiffness: 200000.0", text)


def _write_config(folder: Path, count: int, name: str = "cfg.yaml", **kw) -> Path:
    path = folder / name
    path.write_text(_config_text(count, **kw), encoding="utf-8")
    return path


#: Starts ``phri`` from a small, fresh Python process and reports the child's own peak RSS.
#: The peak a parent reads with wait4 includes the pages the child had before exec; forked
#: straight from pytest (hundreds of MB late in a full run) that would be pytest's size,
#: not phri's. Forked from this launcher it is the launcher's few MB at most.
_LAUNCHER = """
import os, resource, signal, sys
limit, report = int(sys.argv[1]), sys.argv[2]
pid = os.fork()
if pid == 0:
    if limit > 0:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    os.execvp(sys.argv[3], sys.argv[3:])
_, status, usage = os.wait4(pid, 0)
with open(report, "w") as f:
    f.write(str(usage.ru_maxrss * 1024))
if os.WIFSIGNALED(status):
    signal.signal(os.WTERMSIG(status), signal.SIG_DFL)
    os.kill(os.getpid(), os.WTERMSIG(status))
os._exit(os.waitstatus_to_exitcode(status))
"""


def _run(*args, env=None, address_space=None, timeout=300):
    """``phri ARGS`` as a real process: (Run, seconds, its own peak RSS [bytes])."""
    full_env = dict(os.environ)
    full_env.pop(ENV_LIMIT, None)
    full_env.update(env or {})
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err, \
            tempfile.TemporaryDirectory() as tmp:
        report = os.path.join(tmp, "peak")
        t0 = time.monotonic()
        proc = subprocess.run([sys.executable, "-c", _LAUNCHER, str(address_space or 0), report,
                               *command(*args)], stdout=out, stderr=err, env=full_env,
                              text=True, timeout=timeout)
        seconds = time.monotonic() - t0
        out.seek(0)
        err.seek(0)
        run = Run(proc.returncode, out.read(), err.read())
        peak = int(open(report).read())
    assert run.code >= 0, f"phri ended by signal {-run.code}: {run.stderr}"
    return run, seconds, peak


@pytest.fixture(autouse=True)
def _no_override(monkeypatch):
    """The machine's own figure unless a test sets one (the cache is keyed by the value)."""
    monkeypatch.delenv(ENV_LIMIT, raising=False)


@pytest.fixture(autouse=True)
def _own_fe_cache(tmp_path, monkeypatch):
    """No coupled FE result cached from other runs: the FE term is counted."""
    monkeypatch.setenv("PHRI_SPRING_CACHE", str(tmp_path / "fe-cache"))


# --------------------------------------------------------------------------- the case
@pytest.mark.parametrize("arm,name", [("rigid", "out.csv"), ("compliant", "out.csv"),
                                      ("coupled", "out.csv"), ("compliant", "out.parquet")])
def test_three_million_elements_refused_at_once(inputs, out, arm, name):
    cfg = _write_config(out, 1_000_000, step=0.00035)        # 3 rows x 1,000,000 angles
    target = out / name
    target.write_bytes(b"an existing output\n")
    before = snapshot(target)
    run, _, peak = _run("simulate", cfg, inputs["log_csv"], "-o", target, "--arm", arm)
    assert_fault(run, 1, r"geometry\.angles\.count", "3,000,000 elements", before=before,
                 folders=[out])
    assert sorted(p.name for p in out.iterdir()) == sorted(["cfg.yaml", name])
    # refused from the estimate, before the model (3 GB) is built
    assert peak < 1.5e9, peak


def test_three_million_elements_name_the_memory_limit(inputs, out):
    cfg = _write_config(out, 1_000_000, step=0.00035)
    run, _, _ = _run("simulate", cfg, inputs["log_csv"], "-o", out / "f.parquet",
                     env={ENV_LIMIT: "16G"})
    line = assert_fault(run, 1, r"geometry\.angles\.count", r"need about [\d.]+ [GT]B of memory",
                        rf"{ENV_LIMIT}=16G", folders=[out])
    assert "expected fewer elements" in line
    assert not (out / "f.parquet").exists()


@pytest.mark.parametrize("command_args", [
    ("stiffness", "{cfg}"),
    ("stiffness", "{cfg}", "--arm", "coupled"),
    ("compare", "{cfg}", "{manifest}", "-o", "{out}/cmp"),
    ("simulate", "{cfg}", "{log}", "-o", "{out}/f.csv", "--uncertainty", "5"),
    ("simulate", "{cfg}", "{log}", "-o", "{out}/f.csv", "--plot", "{out}/f.png"),
    ("simulate", "{cfg}", "{log}", "-o", "{out}/f.csv", "--shear", "--chunk-rows",
     "1000000000000"),
], ids=["stiffness", "stiffness-coupled", "compare", "uncertainty", "plot", "shear"])
def test_every_command_refuses_a_model_too_big(inputs, out, command_args):
    cfg = _write_config(out, 1_000_000, step=0.00035)
    args = [a.format(cfg=cfg, log=inputs["log_csv"], out=out, manifest=inputs["manifest"])
            for a in command_args]
    run, _, peak = _run(*args, env={ENV_LIMIT: "2G"})
    assert_fault(run, 1, r"geometry\.angles\.count", folders=[out])
    assert sorted(p.name for p in out.iterdir()) == ["cfg.yaml"]
    assert peak < 1.5e9, peak          # refused before the model was built


def test_a_count_beyond_any_machine_is_refused_before_the_labels(out, inputs):
    # 3 x 10^12 elements: building the labels alone would end in the out-of-memory killer
    cfg = _write_config(out, 10**12, step=1e-10)
    run, seconds, peak = _run("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, r"geometry\.angles\.count", "3,000,000,000,000 elements", "PB",
                 folders=[out])
    assert peak < 5e8, peak


def test_many_rows_name_the_rows(out, inputs, monkeypatch):
    rows = ", ".join(f"R{i}: {i * 1e-6:.6f}" for i in range(30_000))
    text = re.sub(r"rows: \{A: -0.025, B: 0.0, C: 0.025\}.*", "rows: {" + rows + "}",
                  CONFIG.read_text())
    text = re.sub(r"row_width: 0.025 .*", "row_width: 0.000001", text)
    cfg = out / "cfg.yaml"
    cfg.write_text(text, encoding="utf-8")
    monkeypatch.setenv(ENV_LIMIT, "64M")
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, r"geometry\.rows", "30,000 rows x 7 angles", folders=[out])


# --------------------------------------------------------------------------- chunks
@pytest.mark.parametrize("log", ["log_csv", "log_parquet"])
@pytest.mark.parametrize("rows", ["1000000000000", "99999999999999999999999"])
def test_huge_chunk_rows_is_a_hint(inputs, out, log, rows):
    run = cli("simulate", inputs["cfg"], inputs[log], "-o", out / "f.csv", "--chunk-rows", rows,
              "-q")
    assert run.code == 0, run.stderr
    assert (out / "f.csv").read_bytes() == inputs["ref_forces"]
    run = cli("simulate", inputs["cfg"], inputs[log], "-o", out / "g.csv", "--chunk-rows", rows,
              "--baseline", "first:1", "-q")
    assert run.code == 0, run.stderr


def test_chunk_is_reduced_when_memory_is_short(inputs, out, monkeypatch):
    cfg = load_config(inputs["cfg"])
    limit = mb.estimate(cfg, "compliant", 100, output_format="csv").total
    monkeypatch.setenv(ENV_LIMIT, str(limit))
    rows = mb.plan_stream(cfg, "compliant", 65536, output_format="csv")
    assert rows == 100
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv", "-q")
    assert run.code == 0, run.stderr
    assert (out / "f.csv").read_bytes() == inputs["ref_forces"]     # 3 chunks, same table


def test_just_within_the_limit_runs_just_over_is_refused(inputs, out, monkeypatch):
    cfg = load_config(inputs["cfg"])
    need = mb.estimate(cfg, "compliant", mb.MIN_CHUNK_ROWS, output_format="csv").total
    monkeypatch.setenv(ENV_LIMIT, str(need))
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv", "-q")
    assert run.code == 0, run.stderr
    assert (out / "f.csv").read_bytes() == inputs["ref_forces"]
    monkeypatch.setenv(ENV_LIMIT, str(need - 1))
    before = snapshot(out / "f.csv")
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv", "-q")
    assert_fault(run, 1, r"geometry\.angles\.count", f"{mb.MIN_CHUNK_ROWS} samples at a time",
                 before=before, folders=[out])


def test_csv_wider_than_pyarrow_writes_is_refused(out, inputs, monkeypatch):
    monkeypatch.setenv(ENV_LIMIT, "1T")            # memory is not the limit here
    cfg = _write_config(out, 43_700, step=0.0001)  # 131,100 elements + 7 columns
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, r"geometry\.angles\.count", "131,107 columns", r"\.parquet",
                 folders=[out])
    assert not (out / "f.csv").exists()


def test_plot_counts_in_the_estimate(inputs, out, monkeypatch):
    cfg = _write_config(out, 700)                  # 2,100 elements
    c = load_config(cfg)
    plain = mb.estimate(c, "compliant", mb.MIN_CHUNK_ROWS, output_format="csv").total
    monkeypatch.setenv(ENV_LIMIT, str(plain + mb.PLOT_BYTES_PER_ELEMENT * 2100 // 2))
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv", "--plot", out / "f.png")
    assert_fault(run, 1, r"geometry\.angles\.count", r"plot [\d.]+ MB", folders=[out])
    assert not (out / "f.png").exists() and not (out / "f.csv").exists()


# --------------------------------------------------------------------------- draws, designs
@pytest.mark.parametrize("args", [("--uncertainty", "99999999999999999999"),
                                  ("--uncertainty", "1000000", "--uncertainty-sd", "tissue=0.1")])
def test_too_many_draws(inputs, out, args):
    run, _, peak = _run("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv",
                        *args, env={ENV_LIMIT: "4G"})
    assert_fault(run, 1, r"--uncertainty: [\d,]+ Monte Carlo draws", "expected fewer draws",
                 folders=[out])
    assert not (out / "f.csv").exists() and peak < 5e8, peak


def test_compare_bands_too_many_draws(inputs, out, monkeypatch):
    monkeypatch.setenv(ENV_LIMIT, "256M")
    run = cli("compare", inputs["cfg"], inputs["manifest"], "-o", out / "cmp", "--no-figures",
              "--uncertainty", "10000000")
    assert_fault(run, 1, "--uncertainty", folders=[out])
    assert not (out / "cmp").exists()


def _study(inputs, out, rest: str) -> Path:
    """A study of the fixtures' config over a copy of their log (task.csv): ``vary:`` and
    what follows it, in YAML."""
    (out / "task.csv").write_bytes(Path(inputs["log_csv"]).read_bytes())
    study = out / "study.yaml"
    study.write_text(f"config: {inputs['cfg']}\nloads: [task.csv]\narm: compliant\nvary:\n"
                     + rest, encoding="utf-8")
    return study


def test_design_grid_too_large(inputs, out):
    study = _study(inputs, out,
                   "  strap.tension: {range: [5, 40], count: 100000}\n"
                   "  cuff.stiffness.per_angle[5]: {range: [1.0e5, 2.0e6], count: 100000}\n"
                   "plan: grid\nminimise: [peak_pressure_to_pain_threshold]\n")
    run, _, peak = _run("design", study, "-o", out / "d")
    assert_fault(run, 1, r"vary: 10,000,000,000 designs", "expected fewer designs",
                 folders=[out])
    assert not (out / "d").exists() and peak < 5e8, peak


def test_study_draws_too_many(inputs, out):
    study = _study(inputs, out,
                   "  strap.tension: {values: [5, 10]}\nplan: grid\n"
                   "minimise: [peak_pressure_to_pain_threshold]\n"
                   "uncertainty: {draws: 10000000, tissue_stiffness_sd: 0.06}\n")
    run, _, peak = _run("design", study, "-o", out / "d", env={ENV_LIMIT: "4G"})
    assert_fault(run, 1, r"uncertainty\.draws: 10,000,000 Monte Carlo draws", folders=[out])
    assert not (out / "d").exists() and peak < 5e8, peak


@pytest.mark.parametrize("plan", ["grid", "lhs:37", "sobol:16"])
def test_design_count_is_the_plans(inputs, out, plan):
    from phri_spring.io.config.study import load_study
    from phri_spring.workflows.design.study import design_values

    study = out / "study.yaml"
    study.write_text(f"config: {inputs['cfg']}\nloads: [{inputs['log_csv']}]\nvary:\n"
                     "  strap.tension: {values: [5, 10, 20]}\n"
                     "  cuff.stiffness.per_angle: {scale: [0.5, 1]}\n"
                     "  cuff.stiffness.per_angle[5]: {range: [1.0e5, 2.0e6], count: 4}\n"
                     f"plan: {plan}\nminimise: [peak_pressure_to_pain_threshold]\n",
                     encoding="utf-8")
    st = load_study(study)
    assert mb.design_count(st) == len(design_values(st))


def test_coupled_fe_too_large(inputs, out, monkeypatch):
    monkeypatch.setenv(ENV_LIMIT, "8G")
    cfg = _write_config(out, 40, base=HUMAN)                   # 120 patches
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv", "--arm", "coupled")
    assert_fault(run, 1, r"geometry\.angles\.count", r"tissue FE \([\d,]+ hexahedra",
                 "--arm compliant", folders=[out])


def test_address_space_limit(out, inputs):
    cfg = _write_config(out, 1_000_000, step=0.00035)
    run, _, _ = _run("simulate", cfg, inputs["log_csv"], "-o", out / "f.parquet",
                     address_space=3 << 30)
    assert_fault(run, 1, r"geometry\.angles\.count", r"ulimit -v", folders=[out])


def test_tight_address_space_is_refused_not_aborted(inputs, out):
    # pyarrow's CSV encoder ends in std::bad_alloc and an abort under ulimit -v of ~0.5 GB:
    # the streamed run's libraries and arenas are counted against the address space
    run, _, _ = _run("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv",
                     address_space=600 << 20)
    assert_fault(run, 1, "of address space", r"ulimit -v", "expected a larger ulimit -v",
                 folders=[out])
    assert not (out / "f.csv").exists()
    run, _, _ = _run("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv", "-q",
                     address_space=3 << 30)
    assert run.code == 0, run.stderr
    assert (out / "f.csv").read_bytes() == inputs["ref_forces"]


@pytest.mark.parametrize("value", ["lots", "-1", "2X"])
def test_bad_override_is_bad_usage(inputs, out, monkeypatch, value):
    monkeypatch.setenv(ENV_LIMIT, value)
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 2, ENV_LIMIT, "expected a number of bytes", folders=[out])


def test_memory_error_is_one_line(inputs, out, monkeypatch):
    # the last line of defence: an allocation the estimate did not foresee
    from phri_spring.workflows import simulate as sim

    def fail(*args, **kwargs):
        raise MemoryError("Unable to allocate 24.0 GiB for an array with shape (1024, 3000000)")

    monkeypatch.setattr(sim, "solve_chunk", fail)
    (out / "f.csv").write_bytes(b"old\n")
    before = snapshot(out / "f.csv")
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, r"out of memory \(Unable to allocate 24.0 GiB", before=before,
                 folders=[out])


def test_no_thread_is_one_line(inputs, out, monkeypatch):
    from phri_spring.workflows import simulate as sim

    def fail(*args, **kwargs):
        raise RuntimeError("can't start new thread")

    monkeypatch.setattr(sim, "_stream", fail)
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, r"out of memory \(can't start new thread\)", folders=[out])


# --------------------------------------------------------------------------- the estimate itself
def test_budget_reads_the_machine(monkeypatch):
    budget = available_memory()
    assert 0 < budget.memory and budget.source
    monkeypatch.setenv(ENV_LIMIT, "3G")
    assert available_memory().memory == 3 << 30
    assert available_memory().source == f"{ENV_LIMIT}=3G"


def test_terms_match_measured_allocations(inputs, out):
    """Each term against what its part allocates for a moderate model (2,100 elements), so
    that the estimate cannot drift silently: never below, and not far above."""
    cfg_path = _write_config(out, 700)
    tracemalloc.start()
    try:
        b = tracemalloc.get_traced_memory()[0]
        cfg = load_config(cfg_path)
        config_bytes = tracemalloc.get_traced_memory()[0] - b
        from phri_spring.workflows.common import cuff_wrench, model_from_config

        tracemalloc.reset_peak()
        b = tracemalloc.get_traced_memory()[0]
        model = model_from_config(cfg, "compliant")
        model_peak = tracemalloc.get_traced_memory()[1] - b
        arrays = sum(getattr(model, f).nbytes for f in ("k", "k_shear", "delta0", "f0", "bT",
                                                        "bb", "delta0_b", "inv_area_kpa"))
        arrays += sum(getattr(model.geometry, f).nbytes for f in
                      ("x", "radius", "row_width", "theta", "span", "points", "normals",
                       "areas", "b"))
        from phri_spring.physics.contact.solver import FactorCache
        from phri_spring.workflows.pipeline import solve_chunk

        rows = 1000
        w = np.tile(np.array([0.5, 20.0, 1.0, 0.01, 0.0, 0.0]), (rows, 1))
        w[:, 1] += np.linspace(0, 30, rows)
        tracemalloc.reset_peak()
        b = tracemalloc.get_traced_memory()[0]
        ch = solve_chunk(model, cuff_wrench(cfg, w), None, 100, FactorCache(), True)
        ch.extras()
        chunk_peak = tracemalloc.get_traced_memory()[1] - b
    finally:
        tracemalloc.stop()
    est = mb.estimate(cfg, "compliant", rows, output_format="parquet", shear=True)
    n = 2100
    assert config_bytes <= est.terms["config"] <= 3 * config_bytes
    assert arrays <= mb.MODEL_BYTES_PER_ELEMENT * n     # the arrays the model keeps
    assert model_peak <= est.terms["model"] <= 2 * model_peak
    assert chunk_peak <= est.terms["chunk"] <= 3 * chunk_peak


def test_whole_run_within_the_estimate(tmp_path, out):
    """Peak RSS of a real streamed run (2,100 elements, 3 chunks, CSV) against the estimate."""
    from .conftest import _write_log

    cfg = _write_config(out, 700)
    log = _write_log(tmp_path / "log.csv", 5000)
    rows = mb.preferred_chunk_rows(2100, 65536)
    est = mb.estimate(load_config(cfg), "compliant", rows, output_format="csv")
    tiny = _write_log(tmp_path / "tiny.csv", 10)
    idle, _, base_peak = _run("simulate", CONFIG, tiny, "-o", out / "t.csv", "-q")
    assert idle.code == 0                                    # interpreter and libraries
    run, _, peak = _run("simulate", cfg, log, "-o", out / "f.csv", "-q")
    assert run.code == 0, run.stderr
    used = peak - base_peak
    assert used <= est.total <= 3 * used, (used, est.terms)


def test_fe_mesh_size_and_term_match_the_fe(tmp_path):
    pytest.importorskip("skfem")
    code = f"""
import copy, json, sys
sys.path.insert(0, {str(Path(__file__).resolve().parents[2])!r})
from phri_spring.io.config import load_config, config_from_dict
from phri_spring.physics.continuum import tissue as fe_tissue
import skfem, scipy.sparse.linalg
from phri_spring.workflows.common import geometry_from_config
def rss(name):
    for line in open("/proc/self/status"):
        if line.startswith(name + ":"):
            return int(line.split()[1]) * 1024
base = load_config({str(HUMAN)!r})
raw = copy.deepcopy(base.raw)
raw["geometry"]["rows"] = {{"A": 0.0}}
raw["geometry"]["angles"].update(count=3, step=120.0)
raw["cuff"]["stiffness"] = 2e5
cfg = config_from_dict(raw, path=None, base_dir={str(HUMAN.parent)!r})
b = rss("VmRSS")
K, N, parts, owner, info = fe_tissue._build_unit_operators(geometry_from_config(cfg), cfg.continuum_thickness,
                                             0.45, 3, 6.0, "fixed")
print(json.dumps({{"added": rss("VmHWM") - b, "hex": info["n_elements"],
                  "dofs": info["n_dofs"], "raw": raw}}))
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    got = json.loads(res.stdout)
    cfg = config_from_dict(copy.deepcopy(got["raw"]), path=None, base_dir=HUMAN.parent)
    fe = mb.fe_mesh_size(cfg)
    assert fe == (got["hex"], got["dofs"])
    term = mb.estimate(cfg, "coupled", fe=fe).terms["tissue FE"]
    assert got["added"] <= term <= 2 * got["added"], (got["added"], term)


def test_normal_runs_are_far_from_any_limit():
    # the bundled configs' runs need well under 1 GB: the check never refuses them
    for path in (CONFIG, HUMAN):
        cfg = load_config(path)
        for arm in ("rigid", "compliant"):
            est = mb.estimate(cfg, arm, mb.preferred_chunk_rows(21, 65536), output_format="csv",
                              shear=True, plot=True)
            assert est.total < 1e9, est.terms
