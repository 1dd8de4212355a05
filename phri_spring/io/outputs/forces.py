"""Contact forces out (docs/model.md section 7): the chunked, threaded forces-table writer.

The format's own part (CSV text or Parquet) is its recipe's sink
(:data:`phri_spring.io.logs.formats.LOG_FORMATS`); this module builds each
chunk's table and keeps the chunks in order across the writer threads.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Optional

import numpy as np

from ..logs.formats import format_named

__all__ = ["ForcesWriter"]


def _arrow_array(values, typ=None):
    """A pyarrow array from a numpy array without ``pa.array``.

    ``pa.array`` imports pandas on first use, which would add to every run's
    start-up; building the array from its buffers does not, and is zero-copy
    for numbers.
    """
    import pyarrow as pa

    arr = np.asarray(values)
    if arr.dtype == np.bool_:
        bits = np.packbits(arr, bitorder="little")
        return pa.Array.from_buffers(pa.bool_(), len(arr), [None, pa.py_buffer(bits)])
    if typ is None:
        typ = pa.from_numpy_dtype(arr.dtype)
    arr = np.ascontiguousarray(arr, dtype=typ.to_pandas_dtype())
    return pa.Array.from_buffers(typ, len(arr), [None, pa.py_buffer(arr)])


#: rows of the forces transposed at a time: a block of the chunk and its transpose stay in
#: the processor's cache, where one strided pass over the whole chunk would miss it on
#: every value; 512 rows take a third less time than 64 on 21 and on 400 elements (and
#: an eighth of the writer thread's Python steps, which hold the interpreter lock)
_TRANSPOSE_ROWS = 512


def transpose_into(forces: np.ndarray, out: np.ndarray) -> np.ndarray:
    """``forces.T`` (k, n) -> (n, k) written into the C-contiguous ``out``, block by block
    (the same values as ``np.ascontiguousarray(forces.T)``)."""
    k = forces.shape[0]
    for lo in range(0, k, _TRANSPOSE_ROWS):
        hi = min(lo + _TRANSPOSE_ROWS, k)
        out[:, lo:hi] = forces[lo:hi].T
    return out


def _arrow_strings(names):
    """A pyarrow string array from Python strings, from its buffers (see _arrow_array)."""
    import pyarrow as pa

    data = [str(n).encode("utf-8") for n in names]
    offsets = np.zeros(len(data) + 1, dtype=np.int32)
    offsets[1:] = np.cumsum([len(d) for d in data])
    return pa.Array.from_buffers(pa.string(), len(data),
                                 [None, pa.py_buffer(offsets), pa.py_buffer(b"".join(data))])


class ForcesWriter:
    """Write the forces table (docs/model.md section 7) in chunks, CSV or Parquet by ``fmt``.

    Columns: ``time`` [s], one per element label [N], then extra columns.

    Chunks are converted and written on background threads, so writing
    overlaps the solving of the next chunk (pyarrow formats numbers without
    holding the GIL). CSV chunks are encoded to bytes by ``workers`` threads at
    once and written in order, because formatting numbers as text is the
    costliest step of a CSV run; Parquet chunks are written by one thread, in
    order. At most ``max(2, workers) + 1`` chunks are in flight, which bounds
    memory. Use as a context manager around an already-atomic temporary path;
    an error on a background thread is raised in the caller.

    Parameters
    ----------
    path : path-like
        The file to write (replaced).
    fmt : str
        A format with a writer (``'csv'`` or ``'parquet'``), e.g. from
        :func:`phri_spring.io.logs.formats.table_format` with ``role='output'``.
    labels : sequence of str
        Element labels: one force column [N] each.
    extra_types : dict
        Extra column name -> pyarrow type, after the forces.
    threaded : bool
        Convert and write on background threads.
    decimals : int or None
        CSV only: forces and other floats (not time) rounded to this many
        decimals (6 = 1 uN); None or negative keeps every digit.
    workers : int
        CSV only: threads encoding chunks at once.
    """

    def __init__(self, path, fmt: str, labels, extra_types: dict, *, threaded: bool = True,
                 decimals: Optional[int] = 6, workers: int = 2):
        import pyarrow as pa

        self.path = Path(path)
        self.fmt = fmt
        self._sink_type = format_named(fmt).writer
        if self._sink_type is None:
            raise ValueError(f"{fmt!r} logs are read only; the forces table is written as "
                             "CSV or Parquet")
        self.labels = list(labels)
        fields = [pa.field("time", pa.float64())]
        fields += [pa.field(lab, pa.float64()) for lab in self.labels]
        fields += [pa.field(name, typ) for name, typ in extra_types.items()]
        self.schema = pa.schema(fields)
        self.threaded = threaded
        # a sink that encodes on several threads gets `workers` of them; the others one
        self.workers = max(1, int(workers)) if self._sink_type.parallel else 1
        # rounding halves a CSV file and its formatting time; None keeps every digit
        self.decimals = None if decimals is None or decimals < 0 else int(decimals)
        self._sink = None
        self._pool = None
        self._pending = None
        # each converting thread transposes its chunks into one array of its own, kept from
        # chunk to chunk: a fresh chunk-sized array would be faulted in anew every chunk
        self._scratch = threading.local()

    @property
    def in_flight(self) -> int:
        """Most chunks the writer may still be reading after :meth:`write` returns: an
        array handed to it may be reused once ``in_flight`` later chunks were written."""
        return max(2, self.workers) if self.threaded else 0

    def __enter__(self):
        self._sink = self._sink_type(self.path, self.schema, self.labels)
        if self.threaded:
            import collections
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="phri-writer")
            self._pending = collections.deque()
        return self

    def _table(self, time, forces, extras):
        import pyarrow as pa

        if callable(extras):  # computed here, on a background thread
            extras = extras()
        rnd = self.decimals if self._sink_type.rounds else None
        cols = [_arrow_array(np.asarray(time, dtype=float))]
        forces = np.asarray(forces, dtype=float)
        forces_t = transpose_into(forces, self._transposed(*forces.shape[::-1]))
        if rnd is not None:   # element by element: the same values as rounding before
            np.round(forces_t, rnd, out=forces_t)
        cols += [_arrow_array(forces_t[j]) for j in range(forces_t.shape[0])]
        for name in self.schema.names[1 + len(self.labels):]:
            typ = self.schema.field(name).type
            val = extras[name]
            if rnd is not None and pa.types.is_floating(typ):
                val = np.round(np.asarray(val, dtype=float), rnd)
            if pa.types.is_dictionary(typ):
                idx, names = val
                cols.append(pa.DictionaryArray.from_arrays(
                    _arrow_array(np.asarray(idx, dtype=np.int32)), _arrow_strings(names)))
            else:
                cols.append(_arrow_array(val, None if pa.types.is_boolean(typ) else typ))
        return pa.Table.from_arrays(cols, schema=self.schema)

    @property
    def backlog(self) -> int:
        """Chunks handed to the writer threads and not finished yet (0 when not threaded)."""
        return 0 if self._pending is None else sum(not f.done() for f in self._pending)

    def _transposed(self, n: int, k: int) -> np.ndarray:
        """This thread's (n, k) array for a chunk's transposed forces (its own memory, reused
        by the thread's next chunk: a sink's ``encode`` must not keep the table it is given)."""
        flat = getattr(self._scratch, "flat", None)
        if flat is None or flat.size < n * k:
            flat = self._scratch.flat = np.empty(n * k)
        return flat[:n * k].reshape(n, k)

    def _convert(self, time, forces, extras):
        """One chunk encoded by the sink: bytes to write later, in order, or None if written."""
        return self._sink.encode(self._table(time, forces, extras))

    def _flush_pending(self, keep: int) -> None:
        # finish chunks in order until at most `keep` are in flight
        while len(self._pending) > keep:
            data = self._pending.popleft().result()
            if data is not None:
                self._sink.write(data)

    def write(self, time, forces, extras: dict) -> None:
        """Queue (or write) one chunk: time (k,) [s], forces (k, n) [N], extras by column name.

        ``extras`` may be a callable returning that mapping: it is then called on
        a background thread. A dictionary-typed extra column takes ``(indices, names)``.
        """
        if self._pool is None:
            data = self._convert(time, forces, extras)
            if data is not None:
                self._sink.write(data)
            return
        self._pending.append(self._pool.submit(self._convert, time, forces, extras))
        self._flush_pending(keep=max(2, self.workers))

    def __exit__(self, *exc):
        try:
            if self._pool is not None:
                try:
                    if exc[0] is None:
                        self._flush_pending(keep=0)
                finally:
                    for fut in self._pending:
                        fut.cancel()
                    self._pool.shutdown(wait=True)
        finally:
            if self._sink is not None:
                self._sink.close()
        return False
