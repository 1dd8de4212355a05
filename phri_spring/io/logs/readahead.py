"""Iterate on a background thread, a few items ahead, so that reading a log overlaps solving it.

Any iterable works; the wrench-log readers of :mod:`phri_spring.io.logs.formats`
are the intended one.
"""

from __future__ import annotations

__all__ = ["prefetch", "Prefetch"]


def prefetch(iterable, depth: int = 2) -> "Prefetch":
    """Iterate on a background thread, ``depth`` items ahead (reading overlaps computing).

    The thread starts at once, so the first items are being produced while the
    caller still sets up. Exceptions raised by the iterable are re-raised in the
    caller, in order. Close the returned iterator (or use it as a context
    manager) when leaving before the end; that stops the thread.
    """
    return Prefetch(iterable, depth)


class Prefetch:
    """Iterator returned by :func:`prefetch`."""

    _DONE = object()

    def __init__(self, iterable, depth: int = 2):
        import queue
        import threading

        self._q: "queue.Queue" = queue.Queue(maxsize=max(1, int(depth)))
        self._stop = threading.Event()
        self._finished = False
        self._thread = threading.Thread(target=self._run, args=(iterable,),
                                        name="phri-reader", daemon=True)
        self._thread.start()

    def _put(self, item) -> bool:
        import queue

        while not self._stop.is_set():
            try:
                self._q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def _run(self, iterable):
        try:
            for item in iterable:
                if not self._put((item, None)):
                    return
            self._put((self._DONE, None))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller
            self._put((self._DONE, exc))

    def __iter__(self):
        return self

    def __next__(self):
        if self._finished:
            raise StopIteration
        item, exc = self._q.get()
        if item is self._DONE:
            self.close()
            if exc is not None:
                raise exc
            raise StopIteration
        return item

    def close(self) -> None:
        """Stop the background thread (it ends after its current item)."""
        self._finished = True
        self._stop.set()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __del__(self):
        self.close()
