"""``write_compare`` draws its figures on several processes: the same files, byte for byte,
as on one; an error in a worker leaves nothing behind."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from support.helpers import HARMONY_CONFIG, REPO
from phri_spring.workflows.compare.run import compare, write_compare

MANIFEST = REPO / "examples" / "experiment" / "manifest.yaml"


@pytest.fixture(scope="module")
def result():
    import dataclasses

    full = compare(HARMONY_CONFIG, MANIFEST)
    # four trials of both experiments (16 figures): enough to share the work, quick to draw
    return dataclasses.replace(full, trials=[full.trials[i] for i in (0, 1, 6, 7)])


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_parallel_figures_are_the_serial_ones(tmp_path, result):
    one = write_compare(result, tmp_path / "one", workers=1, dpi=40)
    two = write_compare(result, tmp_path / "two", workers=2, dpi=40)
    a, b = _files(tmp_path / "one"), _files(tmp_path / "two")
    # bars, wrench, heat maps, a section per arm
    assert len([n for n in a if n.endswith(".png")]) == 1 + 4 + 12 + 2
    assert a.keys() == b.keys()
    for name in a:
        assert a[name] == b[name], name
    assert [p.relative_to(tmp_path / "one") for p in one.files] == \
        [p.relative_to(tmp_path / "two") for p in two.files]


def test_worker_error_leaves_nothing(tmp_path, result, monkeypatch):
    import numpy as np

    # a trial whose heat map cannot be drawn (wrong number of values): the worker raises
    bad = result.trials[-1]
    monkeypatch.setattr(bad, "measured", np.zeros((len(bad.conditions), 5)))
    with pytest.raises(ValueError, match="expected 21 values"):
        write_compare(result, tmp_path / "out", workers=2, dpi=40)
    assert os.listdir(tmp_path) == []


def test_workers_are_forked_before_any_other_thread_runs(tmp_path, result):
    # the pool forks its workers on the first submission: that must come from this thread
    # before the feeder thread starts (a fork while another thread runs may copy a lock or a
    # font in mid-use into the child; Python 3.12 warns about it)
    import threading

    seen = []
    armed = [True]

    def before_fork():
        if armed[0]:
            seen.append((threading.current_thread() is threading.main_thread(),
                         [t.name for t in threading.enumerate()]))

    os.register_at_fork(before=before_fork)
    try:
        write_compare(result, tmp_path / "out", workers=2, dpi=40)
    finally:
        armed[0] = False
    assert seen, "no worker was forked"
    for in_main, threads in seen:
        assert in_main and "phri-figure-feeder" not in threads, threads
