"""Shared plumbing of the ``phri`` commands: error handling and progress."""

from __future__ import annotations

import os
import sys
import traceback

import click

EXIT_DATA = 1
EXIT_USAGE = 2


def _want_traceback() -> bool:
    return os.environ.get("PHRI_TRACEBACK", "") not in ("", "0")


class PhriGroup(click.Group):
    """A click group whose errors are one line each, with exit 1 (data) or 2 (usage).

    ``--traceback`` (or ``PHRI_TRACEBACK=1``) shows the Python traceback.
    """

    def main(self, args=None, prog_name=None, complete_var=None,
             standalone_mode=True, **extra):
        if args is None:
            args = sys.argv[1:]
        args = list(args)
        if "--traceback" in args:
            args.remove("--traceback")
            os.environ["PHRI_TRACEBACK"] = "1"
        prog = prog_name or "phri"
        try:
            rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var,
                              standalone_mode=False, **extra)
        except click.exceptions.NoArgsIsHelpError as exc:  # pragma: no cover - click>=8.2
            click.echo(exc.ctx.get_help() if exc.ctx else str(exc), err=True)
            sys.exit(EXIT_USAGE)
        except click.UsageError as exc:
            cmd = exc.ctx.command_path if exc.ctx is not None else prog
            click.echo(f"{cmd}: error: {exc.format_message()} (see '{cmd} --help')", err=True)
            sys.exit(EXIT_USAGE)
        except click.ClickException as exc:
            click.echo(f"{prog}: error: {exc.format_message()}", err=True)
            sys.exit(exc.exit_code)
        except click.Abort:
            click.echo(f"{prog}: aborted", err=True)
            sys.exit(EXIT_DATA)
        except Exception as exc:  # noqa: BLE001 - the one place errors become exit codes
            from phri_spring.errors import PhriError

            if _want_traceback():
                traceback.print_exc()
            if isinstance(exc, PhriError):
                click.echo(f"{prog}: error: {exc}", err=True)
                sys.exit(exc.exit_code)
            if isinstance(exc, MemoryError):
                click.echo(f"{prog}: error: out of memory", err=True)
                sys.exit(EXIT_DATA)
            msg = str(exc).replace("\n", " ")
            click.echo(f"{prog}: internal error: {type(exc).__name__}: {msg} "
                       "(rerun with --traceback and report it)", err=True)
            sys.exit(EXIT_DATA)
        if isinstance(rv, int) and not isinstance(rv, bool):
            sys.exit(rv)
        sys.exit(0)


def progress_enabled(flag: bool | None) -> bool:
    """Progress goes to stderr, and only when stderr is a terminal (unless forced)."""
    if flag is not None:
        return flag
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class StderrProgress:
    """A minimal progress line on stderr: ``label: 42% (151,200 / 360,000 samples)``."""

    def __init__(self, label: str, enabled: bool):
        self.label = label
        self.enabled = enabled
        self._last = -1

    def __call__(self, done: int, total: int | None) -> None:
        if not self.enabled:
            return
        if total:
            pct = int(100 * done / total)
            if pct == self._last:
                return
            self._last = pct
            sys.stderr.write(f"\r{self.label}: {pct:3d}% ({done:,} / {total:,} samples)")
        else:
            sys.stderr.write(f"\r{self.label}: {done:,} samples")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled and self._last != -2:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self._last = -2


def info(message: str, quiet: bool = False) -> None:
    """A line for the user, on stderr so stdout stays clean for data."""
    if not quiet:
        click.echo(message, err=True)


def warn(message: str) -> None:
    click.echo(f"warning: {message}", err=True)
