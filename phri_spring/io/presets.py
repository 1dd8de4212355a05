"""The bundled configs ("presets") and the starter configs ``phri init`` writes from them.

The presets are the YAML files of the repository's ``configs/`` folder, installed with the
package as ``phri_spring.presets`` (``pyproject.toml``), so that an installed wheel has them
too. A preset's name is its file name without ``.yaml``; :data:`DEFAULT_PRESET` is the
paper's Harmony upper-arm cuff. Every preset explains its keys, their units and where each
value comes from in its own comments, which a starter config keeps: it is the preset's text
under a short header.
"""

from __future__ import annotations

from contextlib import contextmanager
from importlib import resources
from pathlib import Path

from ..errors import UsageError
from .outputs.atomic import atomic_file, check_output_path

__all__ = ["DEFAULT_PRESET", "preset_names", "preset_text", "preset_title", "preset_file",
           "starter_text", "check_starter_path", "write_starter_config"]

#: the paper's cuff: what ``phri init`` writes without ``--preset``
DEFAULT_PRESET = "harmony_upper_arm"

_PACKAGE = "phri_spring.presets"


def _folder():
    try:
        return resources.files(_PACKAGE)
    except ModuleNotFoundError:
        # an editable install made before configs/ was mapped into the package
        raise UsageError("the bundled presets are not installed; expected the package "
                         f"{_PACKAGE} (reinstall phri-spring: pip install -e .)",
                         key="--preset") from None


def preset_names() -> list[str]:
    """Names of the bundled presets, sorted (the default among them)."""
    return sorted(p.name[:-5] for p in _folder().iterdir() if p.name.endswith(".yaml"))


def preset_text(name: str) -> str:
    """The YAML text of preset ``name``.

    Raises
    ------
    UsageError
        For a name that is not a bundled preset, listing the names there are.
    """
    if name not in preset_names():
        raise UsageError(f"unknown preset {name!r}; expected one of "
                         f"{', '.join(preset_names())}", key="--preset")
    return (_folder() / f"{name}.yaml").read_text(encoding="utf-8")


@contextmanager
def preset_file(name: str):
    """The path of preset ``name`` as a file, for as long as the ``with`` block lasts (a
    temporary copy where the package is not on a file system, e.g. a zip import)."""
    preset_text(name)                           # an unknown name: the UsageError
    with resources.as_file(_folder() / f"{name}.yaml") as path:
        yield Path(path)


def preset_title(name: str) -> str:
    """The preset's ``name:`` value (one line saying what it models), '' if it has none."""
    for line in preset_text(name).splitlines():
        if line.startswith("name:"):
            return line[len("name:"):].split(" #")[0].strip().strip("'\"")
    return ""


def starter_text(name: str = DEFAULT_PRESET, version: str | None = None) -> str:
    """A starter config: the preset's text (its comments included) under a header saying
    where it came from and what to do with it."""
    made_by = "phri init" if name == DEFAULT_PRESET else f"phri init --preset {name}"
    release = f" (phri-spring {version})" if version else ""
    header = (
        f"# Starter config written by '{made_by}'{release} from the bundled preset {name!r}.\n"
        "# Keys, units and the source of each value are explained in the comments below;\n"
        "# replace every [assumption] with your own device's and subject's values. Paths named\n"
        "# in the comments (configs/, docs/) are those of the phri-spring sources. Run it with\n"
        "#   phri simulate THIS_FILE YOUR_WRENCH_LOG.csv -o forces.csv\n"
        "#\n")
    return header + preset_text(name)


def check_starter_path(path, force: bool = False) -> Path:
    """``path`` as a Path if a starter config may be written there, else the UsageError
    (it exists and ``force`` is false, it is a folder, its folder does not exist)."""
    path = Path(path)
    check_output_path(path, option="FILE")
    if path.exists() and not force:
        raise UsageError(f"{str(path)!r} exists; expected a new file (or --force to replace "
                         "it)", key="FILE")
    return path


def write_starter_config(path, name: str = DEFAULT_PRESET, *, force: bool = False,
                         version: str | None = None) -> Path:
    """Write the starter config of preset ``name`` to ``path`` (atomically).

    Raises
    ------
    UsageError
        Unknown preset; ``path`` exists and ``force`` is false; ``path`` is a folder or its
        folder does not exist.
    """
    text = starter_text(name, version)          # an unknown preset fails before any check
    path = check_starter_path(path, force)
    with atomic_file(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
    return path
