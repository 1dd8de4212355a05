"""Where the batches of a study run: a local process pool, or a dask.distributed cluster.

One entry point, :func:`batch_executor`, opens the chosen executor (so that a
scheduler that cannot be reached is reported before anything is written) and
yields a ``run`` function that maps ``func(batch, shared)`` over batches:

- ``scheduler=None``: a local process pool (``workers`` processes, default one
  per core the process may run on). The shared data (the load set) goes to each
  worker once, as the pool's initialiser argument.
- ``scheduler='local:N'``: a dask ``LocalCluster`` with N single-threaded worker
  processes, started here and closed at the end.
- ``scheduler='tcp://host:port'`` (any address dask accepts): a running
  dask.distributed scheduler.

With dask the shared data is scattered to every worker once
(``client.scatter(..., broadcast=True)``) and each task receives it as a
future. Results are returned by batch index whatever ran them and in whatever
order they finished, so a study's table does not depend on the executor.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Callable, Iterator, Optional, Sequence

from ...errors import UsageError

__all__ = ["batch_executor", "default_workers", "parse_scheduler"]

_SHARED = None  # the shared data, in a pool worker


def default_workers() -> int:
    """CPU cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def parse_scheduler(text: Optional[str]) -> tuple:
    """``None`` -> ('pool', None); ``local:N`` -> ('local', N); else ('address', text).

    Raises
    ------
    UsageError
        For ``local:`` without a positive worker count, or an empty address.
    """
    if text is None:
        return ("pool", None)
    s = str(text).strip()
    if s.startswith("local:"):
        try:
            n = int(s[6:])
        except ValueError:
            n = 0
        if n < 1:
            raise UsageError(f"expected local:N with N >= 1 workers, got {s!r}",
                             key="--scheduler")
        return ("local", n)
    if not s:
        raise UsageError("expected a scheduler address such as tcp://10.0.0.5:8786 or local:N",
                         key="--scheduler")
    return ("address", s)


def _pool_init(shared, env):
    global _SHARED
    os.environ.update(env)
    _SHARED = shared


def _pool_call(func, batch):
    return func(batch, _SHARED)


def _import_distributed():
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError("running on dask needs the dask extra: pip install -e .[dask]  "
                         "(or pip install 'dask[distributed]')", key="--scheduler") from None
    return distributed


@contextmanager
def batch_executor(scheduler: Optional[str] = None, workers: Optional[int] = None,
                   connect_timeout: float = 5.0) -> Iterator[Callable]:
    """Open an executor; yield ``run(func, batches, shared, on_result=None) -> dict``.

    Parameters
    ----------
    scheduler : str, optional
        None (local process pool), ``local:N`` or a dask scheduler address.
    workers : int, optional
        Processes of the local pool (default :func:`default_workers`); ignored with dask.
    connect_timeout : float
        Seconds to wait for a dask scheduler [s].

    Yields
    ------
    run : callable
        ``run(func, batches, shared, on_result=None)`` calls ``func(batch, shared)``
        for every ``(index, batch)`` of ``batches`` and returns ``{index: result}``;
        ``on_result(index, result)`` is called in this process as each result
        arrives (e.g. to save it). ``func`` must be a module-level function.

    Raises
    ------
    UsageError
        The scheduler cannot be reached, or dask is not installed.
    """
    kind, arg = parse_scheduler(scheduler)
    if kind == "pool":
        n = default_workers() if workers is None else int(workers)
        if n < 1:
            raise UsageError(f"expected at least 1 worker, got {n}", key="--workers")
        with _pool_runner(n) as run:
            yield run
        return
    _import_distributed()
    from distributed import Client, LocalCluster

    logging.getLogger("distributed").setLevel(logging.ERROR)
    cluster = None
    try:
        if kind == "local":
            cluster = LocalCluster(n_workers=arg, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            try:
                client = Client(arg, timeout=connect_timeout)
            except (OSError, TimeoutError, ValueError) as exc:
                msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                raise UsageError(f"cannot reach the dask scheduler at {arg!r} ({msg}); expected "
                                 "the address of a running scheduler, e.g. tcp://host:8786",
                                 key="--scheduler") from None
        try:
            yield _dask_runner(client)
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


@contextmanager
def _pool_runner(n: int):
    state = {}

    def run(func, batches: Sequence, shared, on_result=None) -> dict:
        out = {}
        batches = list(batches)
        if not batches:
            return out
        if "pool" not in state:
            env = {v: os.environ.get(v, "1") for v in
                   ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
            ctx = multiprocessing.get_context("forkserver" if os.name == "posix" else "spawn")
            state["pool"] = ProcessPoolExecutor(max_workers=min(n, len(batches)), mp_context=ctx,
                                                initializer=_pool_init, initargs=(shared, env))
        pool = state["pool"]
        pending = {pool.submit(_pool_call, func, b): i for i, b in batches}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    i = pending.pop(fut)
                    res = fut.result()
                    out[i] = res
                    if on_result is not None:
                        on_result(i, res)
        except BaseException:
            for fut in pending:
                fut.cancel()
            raise
        return out

    try:
        yield run
    finally:
        pool = state.get("pool")
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


def _dask_runner(client):
    from distributed import as_completed

    def run(func, batches: Sequence, shared, on_result=None) -> dict:
        out = {}
        batches = list(batches)
        if not batches:
            return out
        shared_future = client.scatter(shared, broadcast=True, hash=False)
        futures = [client.submit(func, b, shared_future, pure=False, key=f"phri-batch-{i}-"
                                 f"{time.time_ns()}") for i, b in batches]
        index = {f.key: i for f, (i, _) in zip(futures, batches)}
        try:
            for fut, res in as_completed(futures, with_results=True):
                i = index[fut.key]
                out[i] = res
                if on_result is not None:
                    on_result(i, res)
        except BaseException:
            client.cancel(futures)
            raise
        return out

    return run
