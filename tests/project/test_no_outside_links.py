"""Nothing in the repository links or points outside it (the model is documented in
docs/model.md, inside the repository, for anyone who clones or installs the package)."""

from __future__ import annotations
from support.helpers import REPO  # noqa: E402

import re
import subprocess
from pathlib import Path

import pytest

ROOT = REPO
#: text that points outside: the team's folder beside the repository, and its contract
#: (spelt in parts, so that this file itself passes the check)
_OUTSIDE, _CONTRACT = "sha" + "red", "SP" + "EC.md"
FORBIDDEN = [
    (re.compile(r"\.\./" + _OUTSIDE), f"a path to the {_OUTSIDE} folder beside the repository"),
    (re.compile(re.escape(_CONTRACT)), f"a reference to {_CONTRACT}"),
]
#: a markdown link's target: checked to stay inside the repository
LINK = re.compile(r"\]\(\s*([^)\s]+)")
TEXT = {".py", ".md", ".txt", ".yaml", ".yml", ".toml", ".cfg", ".ini", ".sh", ".csv", ".rst"}


def tracked_text_files():
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout (an installed package has no repository to check)")
    return [ROOT / f for f in out if Path(f).suffix.lower() in TEXT and (ROOT / f).is_file()]


def offending_lines(path: Path, root: Path = ROOT):
    text = path.read_text(encoding="utf-8", errors="replace")
    for lineno, line in enumerate(text.splitlines(), 1):
        where = f"{path.relative_to(root)}:{lineno}"
        for pattern, what in FORBIDDEN:
            if pattern.search(line):
                yield f"{where}: {what}: {line.strip()[:80]}"
        if path.suffix.lower() != ".md":
            continue
        for target in LINK.findall(line):
            if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                continue                      # a URL or an anchor of the same page
            dest = (path.parent / target.split("#")[0]).resolve()
            if dest != root and root not in dest.parents:
                yield f"{where}: a markdown link leaving the repository: {target}"


def test_no_file_links_outside_the_repository():
    files = tracked_text_files()
    assert any(f.name == "README.md" for f in files)
    bad = [msg for f in files for msg in offending_lines(f)]
    assert bad == [], "\n".join(bad)


def test_the_check_finds_what_it_looks_for(tmp_path):
    (tmp_path / "docs").mkdir()
    sample = tmp_path / "docs" / "x.md"
    sample.write_text(f"see [the spec](../../{_OUTSIDE}/{_CONTRACT})\n"
                      "[a](../../x.md) [b](/etc/passwd)\n"
                      "[fine](../README.md) [web](https://example.org) [here](#top)\n")
    found = list(offending_lines(sample, tmp_path))
    assert len(found) == 5, found          # the folder, the contract and three links leaving


def test_model_document_is_linked_and_numbered():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "](docs/model.md)" in readme
    model = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    heads = re.findall(r"^## (\d+)\. (.+)$", model, flags=re.M)
    assert [int(n) for n, _ in heads] == list(range(1, len(heads) + 1)) and len(heads) >= 11
    assert [t for _, t in heads][:9] == ["Geometry and frames", "Springs", "Strap preload",
                                         "Equilibrium", "Load cell", "Config", "Files",
                                         "Command line", "Solver"]
