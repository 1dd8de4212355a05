"""Text encodings: every text input in UTF-8 (with or without BOM), UTF-16 LE/BE
with BOM and Latin-1 is read as the same data; binary junk and BOM-less UTF-16 are refused
with one line naming the file.

The expected result of each encoded run is the run on the same text saved as plain
UTF-8: decoding must not change one byte of any output.
"""

from __future__ import annotations

import pytest

from .faultkit import (ENCODINGS, assert_fault, assert_one_line, cli, phri, snapshot,
                      write_encoded)

DEGREE = "# recorded at 23 \N{DEGREE SIGN}C by the lab PC\n"


def _with_column(text: str, name: str, value: str) -> str:
    """Add a column the readers ignore (its name holds a degree sign) to a CSV text."""
    lines = text.splitlines()
    head = [i for i, ln in enumerate(lines) if not ln.startswith("#")][0]
    out = lines[:head] + [lines[head] + f",{name}"]
    out += [ln + f",{value}" if ln else ln for ln in lines[head + 1:]]
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_simulate_reads_config_and_log_in_every_encoding(inputs, tmp_path, encoding):
    cfg = write_encoded(tmp_path / "cfg.yaml", DEGREE + inputs["cfg"].read_text(), encoding)
    log = write_encoded(tmp_path / "log.csv", DEGREE + inputs["log_csv"].read_text(), encoding)
    out = tmp_path / "forces.csv"
    run = cli("simulate", cfg, log, "-o", out, "-q")
    assert run.code == 0 and run.stderr == "", run.stderr
    assert out.read_bytes() == inputs["ref_forces"]


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_compare_reads_every_text_input_in_every_encoding(inputs, tmp_path, encoding):
    exp = inputs["exp"]
    cfg = write_encoded(tmp_path / "cfg.yaml", DEGREE + inputs["cfg"].read_text(), encoding)
    for name in ("iact_horizontal_1.csv", "iipass_horizontal_1.csv"):
        text = _with_column((exp / name).read_text(), "room \N{DEGREE SIGN}C", "23")
        write_encoded(tmp_path / name, text, encoding)
    write_encoded(tmp_path / "manifest.yaml", DEGREE + (exp / "manifest.yaml").read_text(),
                  encoding)
    stiff = write_encoded(tmp_path / "k.csv", DEGREE + (exp / "stiffness.csv").read_text(),
                          encoding)
    run = cli("compare", cfg, tmp_path / "manifest.yaml", "-o", tmp_path / "cmp",
               "--no-figures", "-q", "--tissue-stiffness", stiff)
    assert run.code == 0 and run.stderr == "", run.stderr
    for name, data in inputs["ref_cmp"].items():
        assert (tmp_path / "cmp" / name).read_bytes() == data, name


@pytest.mark.parametrize("encoding", ENCODINGS)
def test_fit_stiffness_reads_trials_in_every_encoding(inputs, tmp_path, encoding):
    folder = tmp_path / "trials"
    folder.mkdir()
    for src in sorted(inputs["indenter"].glob("*_*.csv")):
        write_encoded(folder / src.name,
                      _with_column(src.read_text(), "probe \N{DEGREE SIGN}C", "31"), encoding)
    out = tmp_path / "fit.csv"
    run = cli("fit-stiffness", folder, "-o", out, "-q")
    assert run.code == 0 and run.stderr == "", run.stderr
    assert out.read_bytes() == inputs["ref_fit"]


JUNK = {
    "random bytes": bytes(range(256)) * 16,
    "a Parquet file": b"PAR1" + bytes(range(200)) + b"PAR1",
    "UTF-16 without a byte-order mark": "time,Fx,Fy,Fz,Mx,My,Mz\n0,1,2,3,4,5,6\n".encode(
        "utf-16-le"),
}


@pytest.mark.parametrize("kind", sorted(JUNK))
def test_simulate_refuses_a_binary_log(inputs, out, kind):
    log = out / "junk.csv"
    log.write_bytes(JUNK[kind])
    existing = out / "forces.csv"
    existing.write_bytes(b"old forces\n")
    before = snapshot(existing, log)
    run = phri("simulate", inputs["cfg"], log, "-o", existing)
    assert_fault(run, 1, r"junk\.csv", "UTF-8", before=before, folders=[out])


def test_simulate_refuses_a_binary_config(inputs, out):
    cfg = out / "cfg.yaml"
    cfg.write_bytes(bytes(range(256)) * 4)
    existing = out / "forces.csv"
    existing.write_bytes(b"old forces\n")
    before = snapshot(existing)
    run = cli("simulate", cfg, inputs["log_csv"], "-o", existing)
    assert_fault(run, 1, r"cfg\.yaml", "binary", before=before, folders=[out])


@pytest.mark.parametrize("which", ["manifest", "trial", "stiffness"])
def test_compare_refuses_binary_inputs(inputs, tmp_path, which):
    import shutil

    exp = tmp_path / "exp"
    shutil.copytree(inputs["exp"], exp)
    target = {"manifest": exp / "manifest.yaml", "trial": exp / "iact_horizontal_1.csv",
              "stiffness": exp / "stiffness.csv"}[which]
    target.write_bytes(b"\x00\x01\x02\xff\xfe binary \x00" * 64)
    outdir = tmp_path / "cmp"
    outdir.mkdir()
    (outdir / "rmse.csv").write_text("old\n")
    before = snapshot(outdir)
    run = cli("compare", inputs["cfg"], exp / "manifest.yaml", "-o", outdir, "--no-figures",
               "--tissue-stiffness", exp / "stiffness.csv")
    assert_fault(run, 1, target.name.replace(".", r"\."), "binary", before=before,
                 folders=[tmp_path, outdir])


def test_fit_stiffness_refuses_a_binary_trial(inputs, tmp_path, out):
    import shutil

    folder = tmp_path / "trials"
    shutil.copytree(inputs["indenter"], folder)
    (folder / "B3_1.csv").write_bytes(bytes(range(256)) * 8)
    existing = out / "fit.csv"
    existing.write_text("old\n")
    before = snapshot(existing)
    run = cli("fit-stiffness", folder, "-o", existing)
    assert_fault(run, 1, r"B3_1\.csv", "binary", before=before, folders=[out])


def test_latin1_column_name_is_decoded_not_mangled(inputs, tmp_path):
    """A Latin-1 column name is found by its real name (mapped with --column)."""
    text = inputs["log_csv"].read_text().replace("Fx", "Fx [N] \N{DEGREE SIGN}", 1)
    log = write_encoded(tmp_path / "log.csv", text, "latin-1")
    out = tmp_path / "f.csv"
    run = cli("simulate", inputs["cfg"], log, "-o", out, "-q", "--column",
               "Fx=Fx [N] \N{DEGREE SIGN}")
    assert run.code == 0, run.stderr
    assert out.read_bytes() == inputs["ref_forces"]
    run = cli("simulate", inputs["cfg"], log, "-o", tmp_path / "g.csv")
    assert_one_line(run, 1, r"missing column 'Fx'", "\N{DEGREE SIGN}")


# --------------------------------------------------------------------------- the decoding rule
from hypothesis import HealthCheck, assume, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_TEXT = st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="\ufeff")
                | st.sampled_from("\t\n\r,;#\N{DEGREE SIGN}\N{MICRO SIGN}"), max_size=300)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=_TEXT, encoding=st.sampled_from(["utf-8", "utf-8-bom", "utf-16-le-bom",
                                             "utf-16-be-bom"]))
def test_read_text_returns_the_text_written_in_any_unicode_encoding(tmp_path, text, encoding):
    """UTF-8 with or without BOM and UTF-16 with BOM give back exactly the text written."""
    from phri_spring.io.logs.textio import read_text

    path = write_encoded(tmp_path / "t.txt", text, encoding)
    assert read_text(path) == text


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(st.characters(min_codepoint=0x20, max_codepoint=0xFF,
                                  blacklist_characters="\x7f")
                    .filter(lambda c: not 0x80 <= ord(c) <= 0x9F), min_size=1, max_size=200))
def test_read_text_reads_latin1_that_is_not_utf8(tmp_path, text):
    """Latin-1 text (printable, not also valid UTF-8) is read as Latin-1."""
    from phri_spring.io.logs.textio import read_text

    data = text.encode("latin-1")
    try:
        data.decode("utf-8")
        assume(False)   # also valid UTF-8: read as UTF-8, as every editor would
    except UnicodeDecodeError:
        pass
    path = tmp_path / "t.txt"
    path.write_bytes(data)
    assert read_text(path) == text


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(junk=st.binary(min_size=8, max_size=400).filter(lambda b: b"\x00" in b or any(
    c < 9 or 13 < c < 32 for c in b)))
def test_binary_data_is_refused_naming_the_file(tmp_path, junk):
    """Bytes with NUL or control characters (and no byte-order mark) are not text."""
    from phri_spring.errors import DataError
    from phri_spring.io.logs.textio import read_text

    assume(not junk.startswith((b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff", b"\x00\x00\xfe\xff")))
    path = tmp_path / "junk.csv"
    path.write_bytes(junk)
    with pytest.raises(DataError, match=r"junk\.csv: .*(binary|UTF-16|not)"):
        read_text(path)
