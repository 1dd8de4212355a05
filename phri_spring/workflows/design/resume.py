"""Resuming ``phri design``: the finished batches of a study kept in ``OUTDIR/.phri-design/``.

The designs are evaluated in batches; each finished batch is written
atomically to ``OUTDIR/.phri-design/batch_NNNNNN.npz``, next to a
``state.json`` holding the study's fingerprint. Running the same study into the
same folder again computes only the missing batches. The fingerprint covers
only what the batches depend on (base config, arm, batch size, parameters and
their values, stiffness files, load set): objectives, constraints, ``best``
and the ``uncertainty:`` section can change and the finished batches still
count. A folder holding another study is refused and left as it was.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from ...errors import UsageError
from ...io.outputs.atomic import atomic_file
from ...io.config import Config
from ...io.config.study import Study
from .objectives import LoadSet

__all__ = ["STATE_DIR", "BatchState", "batch_size", "fingerprint", "split_batches"]

#: the folder inside OUTDIR that holds the finished batches of a study (for resuming)
STATE_DIR = ".phri-design"


def batch_size(study: Study, n_designs: int) -> int:
    """The study's ``batch_size``, else designs / 100 (1 to 50)."""
    if study.batch_size:
        return study.batch_size
    return int(min(50, max(1, math.ceil(n_designs / 100))))


def fingerprint(study: Study, base: Config, values: np.ndarray, loads: LoadSet, bs: int) -> str:
    """SHA-256 of what the batches depend on (see the module docstring)."""
    h = hashlib.sha256()
    h.update(json.dumps({"config": base.raw, "arm": study.arm, "batch": bs,
                         "parameters": [p.path + ":" + p.kind for p in study.parameters]},
                        sort_keys=True, default=str).encode())
    h.update(np.ascontiguousarray(values).tobytes())
    for f in base.stiffness_files:
        try:
            h.update(Path(f).read_bytes())
        except OSError:
            pass
    h.update(loads.digest().encode())
    if base.tolerance is not None and loads.seconds is not None:
        h.update(np.ascontiguousarray(loads.seconds).tobytes())   # the dose depends on them
    return h.hexdigest()


def split_batches(configs: list, bs: int) -> list:
    """``[(batch id, [(design id, Config), ...]), ...]``, ``bs`` designs a batch."""
    return [(b, [(i, configs[i]) for i in range(s, min(s + bs, len(configs)))])
            for b, s in enumerate(range(0, len(configs), bs))]


def _save_npz(path: Path, data: dict) -> None:
    with atomic_file(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **data)


def _load_npz(path: Path) -> Optional[dict]:
    try:
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    except Exception:  # noqa: BLE001 - a damaged batch file is simply recomputed
        return None


class BatchState:
    """The finished batches of one study in ``outdir`` (identified by its fingerprint)."""

    def __init__(self, outdir: Path, fingerprint: str):
        self.outdir = Path(outdir)
        self.fingerprint = fingerprint
        self.folder = self.outdir / STATE_DIR
        self.state_file = self.folder / "state.json"

    def finished(self, batches: list) -> dict:
        """The batches already computed, ``{batch id: result}`` (nothing written).

        A batch file that is damaged, or does not hold the designs of its
        batch, is left out (recomputed).

        Raises
        ------
        UsageError
            ``outdir`` holds another study, or is not empty and holds no study.
        """
        done: dict = {}
        if self.state_file.exists():
            try:
                old = json.loads(self.state_file.read_text())
            except (OSError, ValueError):
                old = {}
            if old.get("fingerprint") != self.fingerprint:
                raise UsageError(f"{str(self.outdir)!r} holds the results of another study "
                                 "(other designs, arm, config or loads); expected a new folder, "
                                 "or the same study to resume", key="-o/--output")
            for f in sorted(self.folder.glob("batch_*.npz")):
                data = _load_npz(f)
                if data is not None:
                    done[int(f.stem.split("_")[1])] = data
        elif self.outdir.exists() and any(self.outdir.iterdir()):
            raise UsageError(f"{str(self.outdir)!r} is not empty and holds no study; expected a "
                             "new or empty folder", key="-o/--output")
        for b, payload in batches:
            if b in done and not np.array_equal(done[b].get("design"), [i for i, _ in payload]):
                del done[b]
        return {b: d for b, d in done.items() if b < len(batches)}

    def start(self, n_designs: int, n_batches: int) -> None:
        """Create the state folder and its ``state.json`` (kept if already there)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        if not self.state_file.exists():
            with atomic_file(self.state_file) as tmp:
                tmp.write_text(json.dumps({"fingerprint": self.fingerprint,
                                           "designs": n_designs, "batches": n_batches}))

    def save(self, b: int, result: dict) -> None:
        """Write one finished batch (atomically)."""
        _save_npz(self.folder / f"batch_{b:06d}.npz", result)
