"""The fenced code blocks of the README and docs/*.md, and a runner that executes them.

Used by tests/project/test_docs_examples.py. A block's language tag says what it is:

==============  ==========================================================================
``python``      run: the python blocks of a page share one namespace, in page order
``console``     run: every ``$ `` line in bash; the lines shown after it are its output,
                and each must appear in what the command prints (``...`` stands for lines
                left out)
``bash``        run in bash (``set -euo pipefail``)
``yaml``        parsed with the safe loader (config and study snippets, not programs)
``text``        output or messages shown on the page, not code
``{name}``      a MyST directive of the docs site (``{toctree}``, ``{eval-rst}``), not code
==============  ==========================================================================

A block that cannot run here (an installation, a lab's hardware, a benchmark of minutes,
placeholders such as CONFIG) has ``<!-- not-run: REASON -->`` on the line before it; the
test reports it as a skip with its reason, so that nothing is left out silently. A block
without a tag is an error (say what it is).

Run as a script (``python docs_blocks.py PAGE WORKDIR``), it executes the runnable blocks of
PAGE in WORKDIR, in page order, in this one fresh interpreter (so that a tissue law or an arm
model a page registers stays out of the test process), and prints one JSON line per block.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUN = {"python", "console", "bash"}
CHECKED = {"yaml"}
SHOWN = {"text"}
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", flags=re.S | re.M)
#: the prefix of the runner's result lines (the blocks print too)
MARK = "@@docs-block@@ "
NOT_RUN = re.compile(r"<!--\s*not-run:\s*(.+?)\s*-->\s*$")


@dataclass(frozen=True)
class Block:
    page: str          # path relative to the repository, e.g. docs/live.md
    line: int          # line of the opening fence (1-based)
    lang: str          # the tag: python, console, bash, yaml, text, {toctree}, ''
    code: str
    not_run: str | None    # the reason given in a not-run comment, or None

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"

    @property
    def runs(self) -> bool:
        return self.lang in RUN and self.not_run is None


def pages() -> list[Path]:
    return [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))


def blocks(page: Path) -> list[Block]:
    text = page.read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        before = text[:m.start()]
        line = before.count("\n") + 1
        prev = before.rstrip("\n").rsplit("\n", 1)[-1] if before.strip() else ""
        reason = NOT_RUN.search(prev)
        out.append(Block(str(page.relative_to(ROOT)), line, m.group(1).strip(), m.group(2),
                         reason.group(1) if reason else None))
    return out


def dangling_markers(page: Path) -> list[int]:
    """Lines of not-run comments that are not right before a fenced block."""
    lines = page.read_text(encoding="utf-8").splitlines()
    return [i + 1 for i, s in enumerate(lines)
            if NOT_RUN.search(s) and not (i + 1 < len(lines) and lines[i + 1].startswith("```"))]


def console_steps(code: str) -> list[tuple[str, list[str]]]:
    """``$ command`` lines and the output lines shown after each."""
    steps: list[tuple[str, list[str]]] = []
    for line in code.splitlines():
        if line.startswith("$ "):
            steps.append((line[2:], []))
        elif steps and line.strip():
            steps[-1][1].append(line)
        elif line.strip():
            raise ValueError(f"output before any '$ ' command: {line!r}")
    return steps


def _norm(s: str) -> str:
    return " ".join(s.split())


def _bash(script: str, timeout: float = 600.0) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", "set -euo pipefail\n" + script], capture_output=True,
                          text=True, timeout=timeout)


def run_block(block: Block, namespace: dict) -> str | None:
    """Run one block in the current folder; None when it did what it shows, else why not."""
    if block.lang == "python":
        try:
            exec(compile(block.code, block.where, "exec"), namespace)  # noqa: S102 - our docs
        except BaseException:  # noqa: BLE001 - reported, with its traceback
            return traceback.format_exc(limit=-3)
        return None
    if block.lang == "bash":
        res = _bash(block.code)
        return None if res.returncode == 0 else f"exit {res.returncode}:\n{res.stderr[-2000:]}"
    for command, shown in console_steps(block.code):
        res = _bash(command)
        printed = res.stdout + res.stderr
        if res.returncode != 0:
            return f"$ {command}\nexit {res.returncode}:\n{printed[-2000:]}"
        lines = {_norm(s) for s in printed.splitlines()}
        missing = [s for s in shown if _norm(s) != "..." and _norm(s) not in lines]
        if missing:
            return (f"$ {command}\nthe page shows lines it did not print: {missing[:3]}\n"
                    f"it printed:\n{printed[-2000:]}")
    return None


def main(page: str, workdir: str) -> int:
    os.chdir(workdir)
    namespace: dict = {"__name__": "__docs__"}
    for block in blocks(ROOT / page):
        if block.runs:
            result = {"where": block.where, "error": run_block(block, namespace)}
            print(MARK + json.dumps(result), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
