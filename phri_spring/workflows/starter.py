"""``phri init``: a starter config from a bundled preset, and the bundled example wrench log.

The example log is the quick start's ``examples/wrench_log.csv``, made again here from its
fixed seed rather than stored twice: an installed package writes the very same samples
(``examples/make_wrench_log.py`` writes the repository's copy with :func:`example_log_text`).
"""

from __future__ import annotations

from pathlib import Path

from ..errors import UsageError
from ..io.outputs.atomic import atomic_file, check_output_path, output_error
from ..io.config import load_config
from ..io.presets import DEFAULT_PRESET, preset_file
from ..synthetic.wrench import iact_like_log

__all__ = ["EXAMPLE_LOG", "EXAMPLE_SEED", "example_log_text", "check_example_folder",
           "write_example_log"]

#: file name of the example log in the folder given to ``phri init --example``
EXAMPLE_LOG = "wrench_log.csv"
#: the example log's seed (as examples/wrench_log.csv was made)
EXAMPLE_SEED = 2024


def example_log_text() -> str:
    """The example wrench log as CSV text: a SYNTHETIC I-Act-like log of horizontal loading
    (0, 11.1, 33.4 and 55.6 N steps held 8 s each, then unloaded) at 100 Hz with Gaussian
    sensor noise, as the load cell of the default preset would read it."""
    import numpy as np
    import pandas as pd

    with preset_file(DEFAULT_PRESET) as path:
        cfg = load_config(path)
    time, w = iact_like_log(seed=EXAMPLE_SEED, loadcell_position=cfg.loadcell_position,
                            rotation=cfg.loadcell_rotation)
    df = pd.DataFrame(np.round(w, 4), columns=["Fx", "Fy", "Fz", "Mx", "My", "Mz"])
    df.insert(0, "time", np.round(time, 3))
    header = ("# SYNTHETIC I-Act-like log made by examples/make_wrench_log.py (seed "
              f"{EXAMPLE_SEED}): horizontal loading 0, 11.1, 33.4, 55.6 N; units s, N, N*m\n")
    return header + df.to_csv(index=False, lineterminator="\n")


def check_example_folder(folder, force: bool = False) -> Path:
    """The path the example log would have in ``folder``, or the UsageError: ``folder`` is
    a file, or the log exists there and ``force`` is false."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{str(folder)!r} is a file; expected a folder", key="--example")
    dest = folder / EXAMPLE_LOG
    if dest.exists() and not force:
        raise UsageError(f"{str(dest)!r} exists; expected a folder without {EXAMPLE_LOG} (or "
                         "--force to replace it)", key="--example")
    if dest.is_dir():
        raise UsageError(f"{str(dest)!r} is a folder; expected a file path", key="--example")
    return dest


def write_example_log(folder, *, force: bool = False) -> Path:
    """Write the example log into ``folder`` (made if missing) as :data:`EXAMPLE_LOG`.

    Raises
    ------
    UsageError
        See :func:`check_example_folder`.
    """
    dest = check_example_folder(folder, force)
    folder = dest.parent
    text = example_log_text()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise output_error(exc, folder) from None
    check_output_path(dest, option="--example")
    with atomic_file(dest) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return dest
