"""A sweep of hostile inputs a user can give each command: every one ends in one
line and exit 1 (bad data) or 2 (bad usage), never "internal error", and leaves no
temporary file. The classes have their own modules; this one is their long tail.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from .faultkit import assert_fault, cli

HEAD = "time,Fx,Fy,Fz,Mx,My,Mz\n"


def _cfg(inputs, old=None, new=None, extra=""):
    text = inputs["cfg"].read_text()
    if old is not None:
        assert old in text, old
        text = text.replace(old, new)
    return text + extra


CONFIGS = {
    "empty": (lambda i: "", 1, "expected a mapping"),
    "only a byte-order mark": (lambda i: "\ufeff", 1, "expected a mapping"),
    "a list": (lambda i: "[1, 2]\n", 1, "expected a mapping"),
    "a tab": (lambda i: "geometry:\n\tradius: 1\n", 1, "invalid YAML"),
    "a python tag": (lambda i: "a: !!python/object/apply:os.system ['true']\n", 1,
                     "never run code"),
    "a bad timestamp": (lambda i: _cfg(i, "name: Harmony upper-arm cuff on the proxy arm",
                                       "name: !!timestamp 2024-13-45"), 1, "invalid YAML"),
    "a list as a key": (lambda i: "? [1, 2]\n: x\n", 1, "text keys"),
    "a duplicate key": (lambda i: _cfg(i, extra="solver: {max_iterations: 5}\n"), 1,
                        "duplicate key"),
    "count 7.5": (lambda i: _cfg(i, "count: 7", "count: 7.5"), 1, r"geometry\.angles\.count"),
    "count 10^11": (lambda i: _cfg(i, "count: 7", "count: 100000000000"), 1,
                    r"geometry\.angles"),
    "radius text": (lambda i: _cfg(i, "radius: 0.045", "radius: [a, b]"), 1,
                    r"geometry\.radius"),
    "position .inf": (lambda i: _cfg(i, "position: [0.0, -0.07, 0.0]", "position: [.inf, 0, 0]"),
                      1, r"load_cell\.position"),
    "tissue CSV is a folder": (lambda i: _cfg(i, "stiffness: 4242.0", "stiffness: /tmp"), 1,
                               r"tissue\.stiffness"),
    "larger than 1 MB": (lambda i: "a: 1\n" * 300_000, 1, "too large"),
}


@pytest.mark.parametrize("case", sorted(CONFIGS))
def test_hostile_config(inputs, out, case):
    make, code, pattern = CONFIGS[case]
    cfg = out / "cfg.yaml"
    cfg.write_text(make(inputs), encoding="utf-8")
    run = cli("simulate", cfg, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, code, pattern, folders=[out])
    assert not (out / "f.csv").exists()


LOGS = {
    "empty": ("", "empty"),
    "header only": (HEAD, "no data rows"),
    "a truncated row": (HEAD + "0,1,2,3\n", "Expected 7 columns"),
    "text in a number": (HEAD + "0,1,2,x,4,5,6\n", r"Fz: expected a number on line 2"),
    "a duplicate column": ("time,Fx,Fx,Fy,Fz,Mx,My,Mz\n0,1,1,2,3,4,5,6\n", "appears 2 times"),
    "an unterminated quote": (HEAD + '0,"1,2,3,4,5,6\n', "parse"),
    "a 10 MB line": (HEAD + "0," + "1" * 10_000_000 + ",2,3,4,5,6\n", "cannot parse as CSV"),
    "semicolons": (HEAD.replace(",", ";") + "0;1;2;3;4;5;6\n", "missing column 'time'"),
    "comments only": ("# a\n# b\n", "empty"),
    "NUL bytes after 10,000 rows": (HEAD + "0,1,2,3,4,5,6\n" * 10_000 + "\x00\x00,1\n",
                                    "parse"),
    "a broken UTF-16 body": (b"\xff\xfe" + b"\x00\xd8" * 10, "not valid UTF-16"),
}


@pytest.mark.parametrize("case", sorted(LOGS))
def test_hostile_log(inputs, out, case):
    data, pattern = LOGS[case]
    log = out / "log.csv"
    log.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
    existing = out / "f.csv"
    existing.write_bytes(b"old\n")
    run = cli("simulate", inputs["cfg"], log, "-o", existing)
    assert_fault(run, 1, r"log\.csv", pattern, folders=[out])
    assert existing.read_bytes() == b"old\n"


@pytest.mark.parametrize("output,code,pattern", [
    ("results.xlsx", 2, "unknown file type"),
    ("/proc/self/forces.csv", 1, "cannot write"),
    ("missing/forces.csv", 2, "does not exist"),
])
def test_hostile_simulate_output(inputs, out, output, code, pattern):
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o",
              output if output.startswith("/") else out / output)
    assert_fault(run, code, pattern, folders=[out])


TRIAL_FILES = {
    "empty": (b"", "empty file"),
    "header only": None,            # the trial's header line alone
    "no condition column": ("condition", "cond"),
    "a Parquet file that is not one": (b"junk", "Parquet"),
}


@pytest.mark.parametrize("case", sorted(TRIAL_FILES))
def test_hostile_trial_table(inputs, tmp_path, case):
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    trial = exp / "iact_horizontal_1.csv"
    spec = TRIAL_FILES[case]
    man = exp / "manifest.yaml"
    if case == "header only":
        trial.write_text(trial.read_text().splitlines()[0] + "\n")
        pattern = "no row has a condition"
    elif case == "a Parquet file that is not one":
        (exp / "t.parquet").write_bytes(spec[0])
        man.write_text(man.read_text().replace("iact_horizontal_1.csv", "t.parquet"))
        pattern = spec[1]
    elif isinstance(spec[0], bytes):
        trial.write_bytes(spec[0])
        pattern = spec[1]
    else:
        trial.write_text(trial.read_text().replace(*spec, 1))
        pattern = "missing column 'condition'"
    run = cli("compare", inputs["cfg"], man, "-o", tmp_path / "cmp", "--no-figures")
    assert_fault(run, 1, pattern, folders=[tmp_path])


MANIFESTS = {
    "empty": ("", "expected a mapping"),
    "trials is text": ("trials: x\n", "non-empty list"),
    "file is null": ("trials:\n - {file: ~, experiment: a, direction: b, trial: 1}\n",
                     r"trials\[0\]\.file"),
    "file is a folder": ("trials:\n - {file: ., experiment: a, direction: b, trial: 1}\n",
                         "trial file not found"),
    "trial 1.5": ("trials:\n - {file: iact_horizontal_1.csv, experiment: a, direction: b, "
                  "trial: 1.5}\n", r"trials\[0\]\.trial"),
    "description is a list": ("description: [1]\ntrials: []\n", "description"),
}


@pytest.mark.parametrize("case", sorted(MANIFESTS))
def test_hostile_manifest(inputs, tmp_path, case):
    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    text, pattern = MANIFESTS[case]
    (exp / "manifest.yaml").write_text(text)
    run = cli("compare", inputs["cfg"], exp / "manifest.yaml", "-o", tmp_path / "cmp",
              "--no-figures")
    assert_fault(run, 1, pattern, folders=[tmp_path])


INDENTER = {
    "an empty folder": ({}, "no trial files"),
    "an empty trial": ({"A0_1.csv": ""}, "empty file"),
    "a header only": ({"A0_1.csv": "time,displacement,force\n"}, "no data rows"),
    "a badly named file": ({"foo.csv": "time,displacement,force\n0,0,0\n"}, "file name"),
    "a MATLAB file that is not one": ({"A0_1.mat": b"MATLAB 5.0 junk"}, "MATLAB"),
    "a flat force": ({"A0_1.csv": "time,displacement,force\n"
                                  + "".join(f"{i / 100},0,0\n" for i in range(1000))},
                     "no indentation"),
}


@pytest.mark.parametrize("case", sorted(INDENTER))
def test_hostile_indenter_folder(tmp_path, out, case):
    files, pattern = INDENTER[case]
    folder = tmp_path / "trials"
    folder.mkdir()
    for name, data in files.items():
        (folder / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    run = cli("fit-stiffness", folder, "-o", out / "fit.csv")
    assert_fault(run, 1, pattern, folders=[out])


@pytest.mark.parametrize("row,pattern", [
    ("NA,1,0,0,0", "location"),
    ("A0,1e30,0,0,0", "integer trial number"),
    ("A0,1e999,0,0,0", "finite"),
])
def test_hostile_long_indenter_table(tmp_path, out, row, pattern):
    table = tmp_path / "long.csv"
    table.write_text(f"location,trial,time,displacement,force\n{row}\n")
    run = cli("fit-stiffness", table, "-o", out / "fit.csv")
    assert_fault(run, 1, r"long\.csv", pattern, folders=[out])


def test_hostile_tissue_stiffness_files(inputs, tmp_path):
    for name, data, pattern in (("missing.csv", None, "file not found"),
                                ("junk.csv", "a,b\n1,2\n", "missing column 'location'"),
                                ("empty.csv", "", "cannot read as CSV")):
        path = tmp_path / name
        if data is not None:
            path.write_text(data)
        run = cli("compare", inputs["cfg"], inputs["manifest"], "-o", tmp_path / "cmp",
                  "--no-figures", "--tissue-stiffness", path)
        assert_fault(run, 1, pattern, folders=[tmp_path])
    assert not Path(tmp_path / "cmp").exists()


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_device_given_as_config_or_manifest(inputs, out, device):
    """A device that never ends is refused after reading at most the YAML bound."""
    if not Path(device).exists():
        pytest.skip(f"no {device}")
    run = cli("simulate", device, inputs["log_csv"], "-o", out / "f.csv")
    assert_fault(run, 1, device, "binary|too large", folders=[out])
    run = cli("compare", inputs["cfg"], device, "-o", out / "cmp", "--no-figures")
    assert_fault(run, 1, device, "binary|too large", folders=[out])


def test_names_too_long_for_the_file_system(inputs, out):
    long_name = "a" * 300 + ".csv"
    run = cli("simulate", inputs["cfg"], inputs["log_csv"], "-o", out / long_name)
    assert_fault(run, 1, "File name too long", folders=[out])
    run = cli("simulate", inputs["cfg"], out / long_name, "-o", out / "f.csv")
    assert_fault(run, 1, "File name too long", folders=[out])
