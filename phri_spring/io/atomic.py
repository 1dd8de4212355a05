"""Writing outputs so that a failed run leaves nothing behind and never touches an input."""

from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..errors import UsageError

__all__ = ["atomic_file", "atomic_directory", "check_output_path"]


def _same(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def check_output_path(output, inputs=(), option: str = "-o/--output", directory: bool = False):
    """Refuse an output path that is an input (or contains/is contained by one, for folders).

    Raises
    ------
    UsageError
        Naming the option and the input it collides with.
    """
    out = Path(output)
    for inp in inputs:
        if inp is None:
            continue
        inp = Path(inp)
        if _same(out, inp):
            raise UsageError(f"output {str(out)!r} is the input {str(inp)!r}; "
                             "expected a different path (inputs are never written)", key=option)
        if directory and inp.exists():
            ri, ro = inp.resolve(), out.resolve()
            if ro == ri or ro in ri.parents:
                raise UsageError(f"output folder {str(out)!r} contains the input {str(inp)!r}; "
                                 "expected a new folder", key=option)
    if not directory and out.exists() and out.is_dir():
        raise UsageError(f"output {str(out)!r} is a folder; expected a file path", key=option)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.exists():
        raise UsageError(f"the folder of output {str(out)!r} does not exist", key=option)


@contextmanager
def atomic_file(dest, suffix: str | None = None):
    """Yield a temporary path beside ``dest``; rename it onto ``dest`` only on success."""
    dest = Path(dest)
    suffix = dest.suffix if suffix is None else suffix
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=f".tmp{suffix}",
                               dir=str(dest.parent) if str(dest.parent) else ".")
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        os.replace(tmp, dest)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextmanager
def atomic_directory(dest):
    """Yield a temporary folder beside ``dest``; on success its files land in ``dest``.

    ``dest`` is created if missing; files already in it with the same names are
    replaced; on failure nothing of the run remains (a folder created for it is removed).
    """
    dest = Path(dest)
    parent = dest.parent if str(dest.parent) else Path(".")
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", suffix=".tmp", dir=str(parent)))
    try:
        yield tmp
        if not dest.exists():
            os.replace(tmp, dest)
        else:
            for item in tmp.iterdir():
                target = dest / item.name
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target)
                os.replace(item, target)
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
