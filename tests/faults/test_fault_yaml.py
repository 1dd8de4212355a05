"""Hostile YAML: configs and manifests whose aliases expand exponentially, that
nest deeply, refer to themselves or hold numbers no double or int64 can: refused with one
line naming the key, within 1 s and 200 MB; ordinary anchors, aliases and merge keys work.

``phri fit-stiffness`` reads no YAML; its text inputs are covered by the encoding cases.
"""

from __future__ import annotations

import time
import tracemalloc

import pytest

from .faultkit import assert_fault, cli, phri, snapshot


def laughs(key_root: str, width: int = 10, levels: int = 12) -> str:
    """Aliases of lists of aliases: ``width ** levels`` values once expanded."""
    lines = [f"{key_root}l0: &l0 [" + ", ".join(["1"] * width) + "]"]
    for i in range(1, levels):
        lines.append(f"{key_root}l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


def deep(n: int = 50_000) -> str:
    return "x: " + "[" * n + "]" * n + "\n"


def deep_block(n: int = 200) -> str:
    return "".join("  " * i + f"k{i}:\n" for i in range(n)) + "  " * n + "v: 1\n"


def config_with(inputs, extra: str, replace=None) -> str:
    text = inputs["cfg"].read_text()
    if replace:
        old, new = replace
        assert old in text
        text = text.replace(old, new)
    return text + extra


HOSTILE_CONFIGS = {
    # name: (text maker, patterns the one line must hold)
    "alias bomb at the top": (lambda i: laughs("") + i["cfg"].read_text(),
                              [r"aliases expand to more than", r"cfg\.yaml: l\d+"]),
    "alias bomb under a key": (lambda i: config_with(
        i, "", ("geometry:", "geometry:\n" + "".join("  " + ln + "\n" for ln in
                                                     laughs("bomb_").splitlines()))),
        [r"geometry\.bomb_l\d+", "aliases"]),
    "deep flow nesting": (lambda i: deep(), ["nested deeper than"]),
    "deep block nesting": (lambda i: deep_block(), ["nested deeper than"]),
    "self-referring alias": (lambda i: "loop: &a [1, *a]\n" + i["cfg"].read_text(),
                             ["recursive", r"loop\[1\]"]),
    "integer of 400 digits": (lambda i: config_with(i, "", ("count: 7", "count: " + "9" * 400)),
                              [r"geometry\.angles\.count", "400 digits"]),
    "integer of 5000 digits": (lambda i: config_with(i, "", ("max_iterations: 100",
                                                             "max_iterations: " + "1" * 5000))
                               if "max_iterations: 100" in i["cfg"].read_text() else
                               i["cfg"].read_text() + "solver:\n  max_iterations: " + "1" * 5000
                               + "\n", [r"solver\.max_iterations", "5000 digits"]),
    "float beyond a double": (lambda i: config_with(i, "", ("tension: 15.0", "tension: 1e999")),
                              [r"strap\.tension", "too large"]),
}


def _refused(path) -> None:
    from phri_spring.errors import ConfigError
    from phri_spring.io.config import load_yaml

    with pytest.raises(ConfigError):
        load_yaml(path)


def _time_and_memory(path):
    """Wall time [s] of refusing ``path``, and the peak memory traced meanwhile [bytes]."""
    t0 = time.perf_counter()
    _refused(path)
    elapsed = time.perf_counter() - t0
    tracemalloc.start()
    try:
        _refused(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return elapsed, peak


@pytest.mark.parametrize("case", sorted(HOSTILE_CONFIGS))
def test_simulate_refuses_a_hostile_config(inputs, out, case):
    make, patterns = HOSTILE_CONFIGS[case]
    cfg = out / "cfg.yaml"
    cfg.write_text(make(inputs), encoding="utf-8")
    existing = out / "forces.csv"
    existing.write_bytes(b"old\n")
    before = snapshot(existing)
    run = cli("simulate", cfg, inputs["log_csv"], "-o", existing)
    assert_fault(run, 1, r"cfg\.yaml", *patterns, before=before, folders=[out])
    # the bound holds whatever the structure: well under 1 s and 200 MB (a generous bound:
    # the loader takes milliseconds; an unbounded one runs out of memory or recursion)
    elapsed, peak = _time_and_memory(cfg)
    assert elapsed < 1.0 and peak < 200e6, (elapsed, peak)


def test_a_hostile_config_is_refused_by_the_real_process_quickly(inputs, out):
    cfg = out / "cfg.yaml"
    cfg.write_text(laughs("", width=20, levels=30) + inputs["cfg"].read_text())
    run = phri("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, "aliases expand", folders=[out])
    assert not (out / "f.csv").exists()


def _manifest(inputs, body: str):
    return body + inputs["manifest"].read_text()


HOSTILE_MANIFESTS = {
    "alias bomb": (lambda i: _manifest(i, "") .replace(
        "trials:", laughs("").replace("l0:", "description: &l0 x\nl0:")
        .replace("description: &l0 x\n", "") + "trials:"), ["aliases expand"]),
    "alias bomb in a trial entry": (lambda i: i["manifest"].read_text().replace(
        "trial: 1}", "trial: 1, experiment_notes: *l9}", 1).replace(
        "trials:", laughs("") + "trials:"), ["aliases expand"]),
    "deep nesting": (lambda i: "description: " + "[" * 40_000 + "]" * 40_000 + "\n"
                     + i["manifest"].read_text(), ["nested deeper than"]),
    "trial number of 300 digits": (lambda i: i["manifest"].read_text().replace(
        "trial: 1}", "trial: " + "7" * 300 + "}", 1), [r"trials\[0\]\.trial", "300 digits"]),
    "self-referring alias": (lambda i: "description: &d [*d]\n" + i["manifest"].read_text(),
                             ["recursive"]),
}


@pytest.mark.parametrize("case", sorted(HOSTILE_MANIFESTS))
def test_compare_refuses_a_hostile_manifest(inputs, tmp_path, case):
    import shutil

    make, patterns = HOSTILE_MANIFESTS[case]
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    man = exp / "manifest.yaml"
    man.write_text(make(inputs), encoding="utf-8")
    outdir = tmp_path / "cmp"
    outdir.mkdir()
    (outdir / "summary.csv").write_text("old\n")
    before = snapshot(outdir)
    run = cli("compare", inputs["cfg"], man, "-o", outdir, "--no-figures")
    assert_fault(run, 1, r"manifest\.yaml", *patterns, before=before, folders=[tmp_path])
    elapsed, peak = _time_and_memory(man)
    assert elapsed < 1.0 and peak < 200e6, (elapsed, peak)


def test_ordinary_anchors_aliases_and_merge_keys_still_work(inputs, tmp_path):
    """Values shared with anchors, aliases and merge keys give the same results as written out."""
    text = inputs["cfg"].read_text()
    for old, new in (("row_width: 0.025", "row_width: &width 0.025"),
                     ("C: 0.025}", "C: *width}"),
                     ("rows: {A: -0.025", "rows: {A: &minus -0.025"),
                     ("position: [0.0, -0.07, 0.0]", "position: [&zero 0.0, -0.07, *zero]")):
        assert old in text
        text = text.replace(old, new)
    # an alias must follow its anchor: move rows below row_width
    lines = text.splitlines()
    i_rows = next(i for i, ln in enumerate(lines) if ln.strip().startswith("rows:"))
    rows = lines.pop(i_rows)
    i_width = next(i for i, ln in enumerate(lines) if ln.strip().startswith("row_width:"))
    lines.insert(i_width + 1, rows)
    exp = tmp_path / "exp"
    import shutil

    shutil.copytree(inputs["exp"], exp)
    cfg = exp / "cfg.yaml"
    cfg.write_text("\n".join(lines) + "\n")
    out = tmp_path / "forces.csv"
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out, "-q")
    assert run.code == 0, run.stderr
    assert out.read_bytes() == inputs["ref_forces"]
    # a manifest whose second trial merges the first one's keys (a YAML merge key)
    man = exp / "manifest.yaml"
    man.write_text(
        "baseline: no_load\n"
        "trials:\n"
        "  - &first {file: iact_horizontal_1.csv, experiment: I-Act, direction: horizontal,"
        " trial: 1}\n"
        "  - {<<: *first, file: iipass_horizontal_1.csv, experiment: II-Pass, baseline: start}\n")
    run = cli("compare", cfg, man, "-o", tmp_path / "cmp", "--no-figures", "-q",
              "--tissue-stiffness", exp / "stiffness.csv")
    assert run.code == 0, run.stderr
    for name, data in inputs["ref_cmp"].items():
        assert (tmp_path / "cmp" / name).read_bytes() == data, name
