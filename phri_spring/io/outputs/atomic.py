"""Writing outputs so that a failed run leaves nothing behind and never touches an input.

Every output is written to a hidden temporary file (or folder) beside it and
renamed onto it only when complete. On any failure, including an interrupt
(Ctrl-C, SIGTERM, SIGHUP: the command line turns them into exceptions), the
temporary file is removed and an existing output is left as it was. New files
get the permissions any tool gives them (``0666`` and folders ``0777``, less
the umask: ``0644``/``0755`` under umask 022); a replaced file keeps its mode.
An ``OSError`` while writing (full disk, file-size limit, read-only place)
becomes an :class:`~phri_spring.errors.OutputError` naming the output.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
from contextlib import contextmanager
from pathlib import Path

from ...errors import OutputError, UsageError

__all__ = ["atomic_file", "atomic_directory", "check_output_path", "output_error", "naming",
           "umask", "add_commit_check"]

#: callables run just before any output lands (see :func:`add_commit_check`)
_COMMIT_CHECKS: list = []


def add_commit_check(check) -> None:
    """Run ``check()`` just before any output of :func:`atomic_file` or :func:`atomic_directory`
    lands; an exception it raises stops the output, which is then cleaned up like any failure.

    The command line registers one that raises when a signal arrived whose
    exception Python could not deliver (raised inside a weakref callback or a
    ``__del__``, it is only reported as "ignored"): a run stopped by a signal
    must never replace an output.
    """
    if check not in _COMMIT_CHECKS:
        _COMMIT_CHECKS.append(check)


def _before_commit() -> None:
    for check in _COMMIT_CHECKS:
        check()


def umask() -> int:
    """The process's file-mode creation mask (read without changing it where possible)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # pragma: no cover - not Linux
    os.umask(mask)
    return mask


def _reason(exc: OSError) -> str:
    if exc.errno:
        return os.strerror(exc.errno)
    return str(exc).replace("\n", " ") or type(exc).__name__


def output_error(exc: OSError, dest, tmp=None) -> OutputError:
    """An :class:`OutputError` naming ``dest`` (and the file inside it) for an OSError.

    ``tmp`` is the temporary path standing for ``dest``: a file name inside it
    is shown as the same name inside ``dest``. Writers that do not name the file
    in their error (pandas, matplotlib, pyarrow) are named by ``dest`` itself,
    unless the caller set ``exc.filename`` (see :func:`naming`).
    """
    dest = Path(dest)
    where = dest
    name = getattr(exc, "filename", None)
    if tmp is not None and name is not None:
        try:
            rel = Path(os.fsdecode(name)).relative_to(Path(tmp))
            where = dest / rel if str(rel) != "." else dest
        except ValueError:
            pass
    return OutputError(f"cannot write ({_reason(exc)})", file=where)


@contextmanager
def naming(path):
    """Give an ``OSError`` raised inside without a file name the name ``path``.

    For writers that do not say which file failed (``DataFrame.to_csv`` on a
    full disk, ``Figure.savefig``), so that the error names the file.
    """
    try:
        yield
    except OSError as exc:
        if exc.filename is None:
            exc.filename = os.fspath(path)
        raise


def _is_ours(exc: OSError, tmp) -> bool:
    """True if an OSError came from writing the temporary output (not from an input)."""
    name = getattr(exc, "filename", None)
    if name is None:
        return True  # pyarrow, matplotlib and close() do not name the file
    try:
        Path(os.fsdecode(name)).relative_to(Path(tmp))
        return True
    except (ValueError, TypeError):
        return False


def _same(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _file_in_the_way(path: Path):
    """The nearest existing ancestor of ``path`` if it is not a folder, else None."""
    for anc in path.parents:
        try:
            st = os.stat(anc)
        except (FileNotFoundError, NotADirectoryError):  # not there (yet): look further up
            continue
        except OSError:
            return None
        return None if stat.S_ISDIR(st.st_mode) else anc
    return None


def check_output_path(output, inputs=(), option: str = "-o/--output", directory: bool = False):
    """Refuse an output path that is an input (or contains/is contained by one, for folders).

    Raises
    ------
    UsageError
        Naming the option and the input it collides with, or a missing folder.
    OutputError
        If a file stands where a folder of the path should be.
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
    blocker = _file_in_the_way(out)
    if blocker is not None:
        raise OutputError(f"cannot write ({str(blocker)!r} is a file, not a folder)", file=out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.exists():
        raise UsageError(f"the folder of output {str(out)!r} does not exist", key=option)


def _new_mode(dest: Path, default: int) -> int:
    """Mode of what replaces ``dest``: its own if it exists, else ``default`` less the umask."""
    try:
        st = os.stat(dest)
        if stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode):
            return stat.S_IMODE(st.st_mode)
    except OSError:
        pass
    return default & ~umask()


def _special(dest: Path) -> bool:
    """True for an existing output that is not a regular file (a device, /dev/null, a FIFO)."""
    try:
        st = os.stat(dest)
    except OSError:
        return False
    return not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode))


def _temporary_names(parent, prefix: str, suffix: str):
    """Fresh hidden names for a temporary file or folder in ``parent``.

    The command line turns Ctrl-C, SIGTERM and SIGHUP into exceptions (``cli/_common.py``)
    that can be raised between any two steps. ``mkstemp``/``mkdtemp`` return the name only
    after making the path, so one arriving in between left it behind; the writers below
    hold the name first and then make the path exclusively, so their clean-up always knows
    it (removing a path not made yet does nothing).
    """
    for _ in range(100):
        yield Path(parent) / f"{prefix}{os.getpid()}-{os.urandom(6).hex()}{suffix}"
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(parent))


@contextmanager
def atomic_file(dest, suffix: str | None = None):
    """Yield a temporary path beside ``dest``; rename it onto ``dest`` only on success.

    The temporary file has its final permissions from the start (``dest``'s own
    mode if it exists, else ``0666`` less the umask). An existing ``dest`` that
    is not a regular file (``/dev/null``, a FIFO) is written in place: it cannot
    be replaced. Any exception removes the temporary file; an ``OSError`` from
    writing it becomes an :class:`OutputError` naming ``dest``.
    """
    dest = Path(dest)
    if _special(dest):
        try:
            yield dest
        except OSError as exc:
            if not _is_ours(exc, dest):
                raise
            raise output_error(exc, dest) from None
        return
    suffix = dest.suffix if suffix is None else suffix
    tmp = None
    try:
        for tmp in _temporary_names(dest.parent if str(dest.parent) else Path("."),
                                    f".{dest.name}.", f".tmp{suffix}"):
            try:
                fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o600)
                break
            except FileExistsError:   # someone else's: not ours to remove
                tmp = None
        try:
            os.fchmod(fd, _new_mode(dest, 0o666))
        finally:
            os.close(fd)
        yield tmp
        _before_commit()
        os.replace(tmp, dest)
        tmp = None
    except OSError as exc:
        if tmp is not None:
            _unlink(tmp)
        if tmp is not None and not _is_ours(exc, tmp):
            raise
        raise output_error(exc, dest, tmp) from None
    except BaseException:
        if tmp is not None:
            _unlink(tmp)
        raise


def _unlink(path: Path) -> None:
    try:
        path.unlink(missing_ok=True)
    except OSError:  # pragma: no cover - the folder vanished or turned read-only
        pass


@contextmanager
def atomic_directory(dest):
    """Yield a temporary folder beside ``dest``; on success its files land in ``dest``.

    ``dest`` is created if missing (``0777`` less the umask); files already in
    it with the same names are replaced and keep their mode; on failure nothing
    of the run remains (a folder created for it is removed). An ``OSError``
    from writing becomes an :class:`OutputError` naming the file in ``dest``.
    """
    dest = Path(dest)
    parent = dest.parent if str(dest.parent) else Path(".")
    tmp = None
    try:
        for tmp in _temporary_names(parent, f".{dest.name}.", ".tmp"):
            try:
                os.mkdir(tmp, 0o700)
                break
            except FileExistsError:   # someone else's: not ours to remove
                tmp = None
        os.chmod(tmp, 0o777 & ~umask())
        yield tmp
        _before_commit()
        if not dest.exists():
            os.replace(tmp, dest)
        else:
            for item in tmp.iterdir():
                target = dest / item.name
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target)
                elif item.is_file() and target.is_file():
                    os.chmod(item, _new_mode(target, 0o666))
                os.replace(item, target)
            shutil.rmtree(tmp, ignore_errors=True)
        tmp = None
    except OSError as exc:
        if tmp is not None and not _is_ours(exc, tmp):
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        if exc.errno == errno.ENOTEMPTY or exc.errno == errno.EEXIST:
            err = OutputError(f"cannot write ({_reason(exc)})", file=dest)
        else:
            err = output_error(exc, dest, tmp)  # before the clean-up: it looks inside tmp
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise err from None
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
