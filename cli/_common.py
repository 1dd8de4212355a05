"""Shared plumbing of the ``phri`` commands: error handling and progress."""

from __future__ import annotations

import os
import signal
import sys
import traceback
import warnings

import click

EXIT_DATA = 1
EXIT_USAGE = 2


class Interrupted(BaseException):
    """Raised in the main thread by SIGINT, SIGTERM or SIGHUP (see :func:`handle_signals`).

    A ``BaseException`` like ``KeyboardInterrupt``: nothing catches it but the
    clean-up code (``finally``, temporary outputs removed) and :class:`PhriGroup`,
    which exits with status 128 + the signal number.
    """

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = int(signum)

    @property
    def name(self) -> str:
        try:
            return signal.Signals(self.signum).name
        except ValueError:  # pragma: no cover
            return f"signal {self.signum}"


#: signals received (their Interrupted may have been swallowed: see raise_if_interrupted)
_received: list = []


def _on_signal(signum, frame):
    # once only: the clean-up that follows (removing temporary files) must not be cut short
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        try:
            signal.signal(sig, signal.SIG_IGN)
        except (OSError, ValueError):  # pragma: no cover
            pass
    _received.append(signum)
    raise Interrupted(signum)


def raise_if_interrupted() -> None:
    """Raise :class:`Interrupted` again if a signal arrived.

    A signal handler's exception raised while Python runs a weakref callback or
    a ``__del__`` (matplotlib's transforms have such callbacks) is printed as
    "Exception ignored" and lost: the run would go on and write its outputs.
    This check runs before any output lands and when the command returns.
    """
    if _received:
        raise Interrupted(_received[0])


def _unraisable(args) -> None:
    if isinstance(args.exc_value, Interrupted):
        return      # recorded in _received; raised again by raise_if_interrupted
    sys.__unraisablehook__(args)


def handle_signals() -> None:
    """Make SIGTERM and SIGHUP behave like Ctrl-C: clean up, then exit 128 + signal number.

    Also ignores SIGXFSZ, so that a file-size limit (``ulimit -f``) makes a write
    fail with EFBIG, reported as one line, instead of killing the process and
    leaving a temporary file behind. A SIGHUP already ignored (``nohup``) stays
    ignored. Call from the main thread, before the command runs.
    """
    from phri_spring.io.outputs.atomic import add_commit_check

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        if sig != signal.SIGINT and signal.getsignal(sig) == signal.SIG_IGN:
            continue
        signal.signal(sig, _on_signal)
    sys.unraisablehook = _unraisable
    add_commit_check(raise_if_interrupted)
    if hasattr(signal, "SIGXFSZ"):
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


#: non-empty once the console entry point runs (cli/main.py): this process is the command's
_own_process: list = []


def own_process() -> None:
    """Mark this process as the console command's own (called by the entry point only)."""
    _own_process.append(True)


def freeze_setup() -> None:
    """Keep the objects made so far out of the garbage collector's scans, in the console
    command's own process only.

    What start-up made (modules, the config, the model) lives until the process ends, so
    the collections of a long run need not scan it again. Not when the commands are
    called from Python (the tests): there it would keep the caller's garbage of the
    moment forever.
    """
    if _own_process:
        import gc

        gc.freeze()


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
        from phri_spring.workflows.hyper_arm import identification_progress

        try:
            with warnings.catch_warnings(), identification_progress(_IdentificationProgress()):
                if not _want_traceback():
                    # no Python warning line for the user (numpy RuntimeWarnings on absurd
                    # values, library deprecations): what matters is in the data and the
                    # one-line messages; --traceback shows them
                    warnings.simplefilter("ignore")
                rv = super().main(args=args, prog_name=prog_name, complete_var=complete_var,
                                  standalone_mode=False, **extra)
                raise_if_interrupted()     # a signal whose exception Python swallowed
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
        except click.Abort as exc:
            if isinstance(exc.__context__, KeyboardInterrupt):  # Ctrl-C without handle_signals
                click.echo(f"{prog}: interrupted (SIGINT)", err=True)
                sys.exit(128 + signal.SIGINT)
            click.echo(f"{prog}: aborted", err=True)
            sys.exit(EXIT_DATA)
        except Interrupted as exc:
            if _want_traceback():
                traceback.print_exc()
            click.echo(f"{prog}: interrupted ({exc.name}); no output written", err=True)
            sys.exit(128 + exc.signum)
        except Exception as exc:  # noqa: BLE001 - the one place errors become exit codes
            from phri_spring.errors import PhriError

            if _want_traceback():
                traceback.print_exc()
            if isinstance(exc, PhriError):
                click.echo(f"{prog}: error: {exc}", err=True)
                sys.exit(exc.exit_code)
            if isinstance(exc, OSError):
                # an input or output the system refuses (outputs are named by OutputError)
                name = exc.filename
                reason = os.strerror(exc.errno) if exc.errno else str(exc).replace("\n", " ")
                where = f"{os.fsdecode(name)}: " if name is not None else ""
                click.echo(f"{prog}: error: {where}{reason}", err=True)
                sys.exit(EXIT_DATA)
            if isinstance(exc, RuntimeError) and "can't start new thread" in str(exc):
                # a thread's stack is refused by the same limits (ulimit -v, -u)
                exc = MemoryError("can't start new thread")
            if isinstance(exc, MemoryError):
                # the last line of defence: runs are estimated before they allocate
                # (io/memory_budget.py), but an estimate can be short, and memory
                # others take meanwhile is not ours (numpy, pyarrow: ArrowMemoryError)
                detail = " ".join(str(exc).split())
                click.echo(f"{prog}: error: out of memory{f' ({detail})' if detail else ''}; "
                           "expected a run that fits in this machine's memory (fewer "
                           "elements, draws or designs)", err=True)
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

    def __init__(self, label: str, enabled: bool, unit: str = "samples"):
        self.label = label
        self.enabled = enabled
        self.unit = unit
        self._last = -1

    def __call__(self, done: int, total: int | None) -> None:
        if not self.enabled:
            return
        if total:
            pct = int(100 * done / total)
            if pct == self._last:
                return
            self._last = pct
            sys.stderr.write(f"\r{self.label}: {pct:3d}% ({done:,} / {total:,} {self.unit})")
        else:
            sys.stderr.write(f"\r{self.label}: {done:,} {self.unit}")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled and self._last != -2:
            sys.stderr.write("\n")
            sys.stderr.flush()
            self._last = -2


class _IdentificationProgress(StderrProgress):
    """The hyperelastic model's identification (minutes, once per config): its rays."""

    def __init__(self):
        super().__init__("identifying the hyperelastic tissue model (once per config, then "
                         "cached)", progress_enabled(None), unit="rays")

    def __call__(self, done: int, total: int | None) -> None:
        super().__call__(done, total)
        if total and done >= total:
            self.close()


def info(message: str, quiet: bool = False) -> None:
    """A line for the user, on stderr so stdout stays clean for data."""
    if not quiet:
        click.echo(message, err=True)


def warn(message: str) -> None:
    click.echo(f"warning: {message}", err=True)


class ArmChoice(click.Choice):
    """The arm models of ``phri_spring.workflows.common.ARMS`` (the arm registry), looked up when first needed.

    The list is not repeated here (new arm models appear by themselves), and
    numpy is not imported until the command runs or shows its help.
    """

    def __init__(self):
        super().__init__((), case_sensitive=True)

    @property
    def choices(self):
        from phri_spring.workflows.common import ARMS

        return tuple(ARMS)

    @choices.setter
    def choices(self, value):  # click assigns in __init__; the list lives in ARMS
        pass
