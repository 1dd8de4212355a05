"""Entry point of the ``phri`` console script.

Sub-commands live in their own modules and are imported only when they run,
so that ``phri --help`` stays fast (no numpy, pandas or matplotlib at start-up).
"""

from __future__ import annotations

import importlib
import os

# Every matrix product phri-spring makes is 6 wide (or a 6x6 solve) over many samples: BLAS
# threads only add start-up and contention costs there (docs/performance.md, "Threads and
# memory"). One thread each, unless the user chose otherwise; set before numpy is first
# imported by a command.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def _tune_memory() -> None:
    """Let glibc reuse freed memory, and keep this process off transparent huge pages.

    Each chunk of a long log allocates arrays of the same sizes; by default
    glibc maps large ones fresh and unmaps them when freed, and every page is
    then faulted in again. Blocks up to 32 MB come from the heap instead, and
    the heap is trimmed only when more than 256 MB are free at its top, so the
    next chunk reuses the memory while the peak stays bounded.

    Transparent huge pages (which numpy and pyarrow's allocator ask for on
    large blocks) buy nothing here, as the chunk memory is reused, and a
    huge-page fault can be slow and erratic on virtual machines. What both
    settings were measured to save is in docs/performance.md ("Threads and
    memory").
    """
    import sys

    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3
        libc.mallopt(m_mmap_threshold, 32 << 20)
        libc.mallopt(m_trim_threshold, 256 << 20)
        pr_set_thp_disable = 41
        libc.prctl(pr_set_thp_disable, 1, 0, 0, 0)  # fails harmlessly on old kernels
    except (OSError, AttributeError):  # not glibc: nothing to tune
        pass

import click

from ._common import PhriGroup

_COMMANDS = {
    "init": ("phri_cli.init", "init"),
    "simulate": ("phri_cli.simulate", "simulate"),
    "fit-stiffness": ("phri_cli.fit_stiffness", "fit_stiffness"),
    "compare": ("phri_cli.compare", "compare"),
    "stiffness": ("phri_cli.stiffness", "stiffness"),
    "design": ("phri_cli.design", "design"),
    "live": ("phri_cli.live", "live"),
}

_SHORT_HELP = {
    "init": "Write a commented starter config from a bundled preset (and an example log).",
    "simulate": "Wrench log -> contact force of every cuff element [N].",
    "fit-stiffness": "Indenter recordings -> tissue stiffness map [N/m].",
    "compare": "RMSE of the arm models' predictions (rigid, compliant, coupled) against a sensorized cuff.",
    "stiffness": "Interface stiffness of the cuff on the arm at the load cell [N/mm, N*m/deg].",
    "design": "Parameter study of a cuff over a load set -> Pareto designs, best config.",
    "live": "Live wrench stream (stdin, Net F/T, LSL) -> element forces as it runs.",
}


class LazyGroup(PhriGroup):
    def list_commands(self, ctx):
        return list(_COMMANDS)

    def get_command(self, ctx, name):
        if name not in _COMMANDS:
            return None
        module, attr = _COMMANDS[name]
        try:
            return getattr(importlib.import_module(module), attr)
        except ModuleNotFoundError as exc:
            if exc.name == module:
                return None
            raise

    def format_commands(self, ctx, formatter):
        rows = [(name, _SHORT_HELP[name]) for name in _COMMANDS]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="phri-spring", prog_name="phri")
def phri():
    """phri-spring: distributed cuff-arm loads from a six-axis load cell.

    Models an exoskeleton cuff on a limb as a network of springs (bone -
    tissue - skin - cuff - robot) with strap preload and contacts that can
    lift off, and predicts the normal force [N] on every cuff element.

    \b
    Examples:
      phri init cuff.yaml --example .
      phri simulate configs/harmony_upper_arm.yaml examples/wrench_log.csv -o forces.csv
      phri fit-stiffness examples/indenter -o stiffness.csv --plots figs/
      phri compare configs/harmony_upper_arm.yaml examples/experiment/manifest.yaml -o cmp/

    Add --traceback to any command to see the Python traceback of an error.
    Exit status: 0 success, 1 bad data or failed run, 2 bad usage, 128 + N when
    stopped by signal N (Ctrl-C 130, SIGTERM 143, SIGHUP 129).
    """


def main(argv=None):
    """Console entry point: run the command, then leave without the interpreter's teardown.

    Every output file is closed and renamed before the command returns, so the
    process can end with ``os._exit``: tearing down numpy, pyarrow and pydantic
    takes time and does nothing for the user (what it costs is in
    benchmarks/STARTUP.md). Tests call the click group, not this function.
    """
    import sys

    from ._common import handle_signals, own_process

    _tune_memory()
    own_process()
    handle_signals()   # SIGTERM and SIGHUP like Ctrl-C; SIGXFSZ ignored (EFBIG instead)
    code = 0
    try:
        phri.main(args=argv, prog_name="phri")
    except SystemExit as exc:
        code = exc.code
    if not isinstance(code, int):
        code = 0 if code is None else 1
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # closed pipe: nothing more to say
            pass
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    main()
