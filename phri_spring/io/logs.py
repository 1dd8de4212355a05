"""Wrench logs in, contact forces out (docs/model.md section 7), CSV or Parquet.

Reading and writing go through pyarrow: multi-threaded C++ CSV parsing and
writing, Parquet, and streaming in chunks so hour-long logs fit in bounded
memory. Every problem is a one-line :class:`DataError` naming the file and the
column (and the line, for bad values).
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ..errors import DataError, UsageError
from .config import LOG_COLUMNS

__all__ = ["prefetch", "table_format", "resolve_columns", "iter_wrench_log", "read_wrench_log",
           "count_rows", "ForcesWriter", "WrenchChunk", "parse_column_map"]

_FORMATS = {".csv": "csv", ".txt": "csv", ".parquet": "parquet", ".pq": "parquet"}


def table_format(path, *, role: str = "input", option: Optional[str] = None) -> str:
    """``'csv'`` or ``'parquet'`` from a file's extension (inputs also ``'tdms'``, ``'mat'``)."""
    ext = Path(path).suffix.lower()
    fmt = _FORMATS.get(ext)
    if fmt is None and role == "input":
        from .labfiles import LAB_FORMATS

        fmt = LAB_FORMATS.get(ext)
    if fmt is None:
        msg = f"unknown file type {ext or '(none)'!r}; expected .csv or .parquet" + \
            (", .tdms or .mat" if role == "input" else "")
        if role == "output":
            raise UsageError(msg, file=path, key=option)
        raise DataError(msg, file=path)
    return fmt


def parse_column_map(items) -> dict:
    """``["Fx=Fx (N)", ...]`` -> ``{"Fx": "Fx (N)", ...}`` (the ``--column`` option)."""
    out = {}
    for item in items or ():
        if "=" not in item:
            raise UsageError(f"expected SPEC_NAME=LOG_NAME (e.g. 'Fx=Fx (N)'), got {item!r}",
                             key="--column")
        name, col = item.split("=", 1)
        name = name.strip()
        if name not in LOG_COLUMNS:
            close = difflib.get_close_matches(name, LOG_COLUMNS, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise UsageError(f"unknown column name {name!r}{hint} (expected one of "
                             f"{', '.join(LOG_COLUMNS)})", key="--column")
        out[name] = col
    return out


def resolve_columns(available, mapping: Optional[dict] = None, *, file=None,
                    wanted=LOG_COLUMNS) -> list:
    """The log's column name for each wanted spec column, in order."""
    mapping = dict(mapping or {})
    available = list(available)
    out = []
    for name in wanted:
        col = mapping.get(name, name)
        if available.count(col) > 1:
            raise DataError(f"column {col!r} appears {available.count(col)} times; expected "
                            "one column of that name", file=file, key=col)
        if col not in available:
            close = difflib.get_close_matches(col, available, n=1, cutoff=0.6)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            how = (f" (mapped from {name!r})" if name in mapping else
                   f"; map another name with --column {name}=NAME or load_cell.columns")
            raise DataError(f"missing column {col!r}{how}{hint}; the file has "
                            f"{', '.join(map(repr, available[:12]))}"
                            f"{' ...' if len(available) > 12 else ''}", file=file, key=col)
        out.append(col)
    return out


@dataclass
class WrenchChunk:
    """Rows ``start .. start + len`` of a log."""

    start: int
    time: np.ndarray          # (k,) [s]
    wrench: np.ndarray        # (k, 6) in the log's units


_ARROW_ROW = re.compile(r"[Rr]ow #(\d+)")
_ARROW_COL = re.compile(r"column #(\d+)")
_ARROW_VAL = re.compile(r"invalid value '([^']*)'")


def _find_line(path, col: int, value: str):
    """Line number (1-based) of the first row whose column ``col`` holds ``value``."""
    import csv

    try:
        with open(path, newline="", encoding="utf-8", errors="replace") as fh:
            for lineno, row in enumerate(csv.reader(fh), start=1):
                if len(row) > col and row[col] == value and not row[0].lstrip().startswith("#"):
                    return lineno
    except OSError:
        return None
    return None


def _arrow_error(exc, path, cols, skip: int = 0) -> DataError:
    text = str(exc).replace("\n", " ")
    mcol, mrow, mval = _ARROW_COL.search(text), _ARROW_ROW.search(text), _ARROW_VAL.search(text)
    col = cols[int(mcol.group(1))] if mcol and int(mcol.group(1)) < len(cols) else None
    where = f" on line {int(mrow.group(1)) + skip}" if mrow else ""
    if not mrow and mcol and mval:
        line = _find_line(path, int(mcol.group(1)), mval.group(1))
        where = f" on line {line}" if line else ""
    if mval:
        return DataError(f"expected a number{where}, got {mval.group(1)!r}", file=path, key=col)
    return DataError(f"cannot parse as CSV: {text}", file=path, key=col)


def _check_chunk(arr: np.ndarray, start: int, names, path, fmt) -> None:
    bad = ~np.isfinite(arr)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        val = arr[i, j]
        what = "an empty cell or NaN" if np.isnan(val) else \
            f"{float(val)!r} (beyond the range of a double, e.g. 1e999)"
        loc = f"line {start + i + 2}" if fmt == "csv" else f"row {start + i + 1}"
        raise DataError(f"expected a finite number on {loc}, got {what}", file=path,
                        key=names[j])


def iter_wrench_log(path, columns: Optional[dict] = None, *, chunk_rows: int = 131072,
                    wanted=LOG_COLUMNS) -> Iterator[WrenchChunk]:
    """Stream a wrench log in chunks of about ``chunk_rows`` rows.

    Parameters
    ----------
    path : str or path-like
        CSV (``.csv``, ``.txt``) or Parquet (``.parquet``, ``.pq``) file, or a
        lab file (``.tdms``, ``.mat``: see :mod:`phri_spring.io.labfiles`).
    columns : dict, optional
        Map from spec names (``time``, ``Fx`` ... ``Mz``) to the log's names
        (lab files: also the group, under ``LOG_GROUP_KEY``).
    chunk_rows : int
        Rows per chunk (CSV chunks follow pyarrow's blocks and are approximate).

    Yields
    ------
    WrenchChunk
        time [s] and wrench in the log's units (docs/model.md section 5 converts).

    Raises
    ------
    DataError
        Missing file or column, text or NaN in a number, no data rows.
    """
    import pyarrow as pa

    path = Path(path)
    fmt = table_format(path)
    if not path.exists():
        raise DataError("file not found; expected a wrench log (.csv or .parquet)", file=path)
    if path.is_dir():
        raise DataError("is a folder; expected a wrench log file", file=path)
    total = 0
    if fmt in ("tdms", "mat"):
        from .labfiles import iter_lab_log

        yield from iter_lab_log(path, columns, chunk_rows=chunk_rows, wanted=wanted)
        return
    if fmt == "csv":
        import pyarrow.csv as pacsv

        from .textio import SNIFF_BYTES, open_text, sniff_encoding

        skip = 0  # leading comment lines ('# ...') are allowed
        try:
            with open(path, "rb") as fh:
                head = fh.read(SNIFF_BYTES)
                enc = sniff_encoding(head, path, what="a CSV wrench log",
                                     complete=len(head) < SNIFF_BYTES or not fh.read(1))
                fh.seek(enc.bom)
                if enc.is_utf8:
                    head = fh.readline()
                    while head.lstrip().startswith(b"#"):
                        skip += 1
                        head = fh.readline()
            if not enc.is_utf8:  # UTF-16/32 or Latin-1: pyarrow transcodes, lines read here
                text, _ = open_text(path, what="a CSV wrench log")
                with text:
                    line = text.readline()
                    while line.lstrip().startswith("#"):
                        skip += 1
                        line = text.readline()
                head = line.encode("utf-8")
            header = pacsv.read_csv(pa.py_buffer(head),
                                    read_options=pacsv.ReadOptions(autogenerate_column_names=False)
                                    ).column_names if head.strip() else []
        except OSError as exc:
            raise DataError(f"cannot read ({exc.strerror or exc})", file=path) from None
        except UnicodeDecodeError as exc:
            raise DataError(f"not valid {enc.name} text in its first lines ({exc.reason}); "
                            "expected a text file in UTF-8", file=path) from None
        except pa.ArrowInvalid:
            header = []
        if not header:
            raise DataError("the file is empty; expected a header line with time, Fx, Fy, Fz, "
                            "Mx, My, Mz", file=path)
        names = resolve_columns(header, columns, file=path, wanted=wanted)
        # blocks of about chunk_rows rows at ~8 bytes a cell, at most 2 MB: larger blocks
        # cost more in page faults than they save (measured)
        block = int(min(max(1 << 16, int(chunk_rows) * 8 * len(header)), 1 << 21))
        try:
            codec = {"utf-16-le": "utf-16", "utf-16-be": "utf-16", "utf-32-le": "utf-32",
                     "utf-32-be": "utf-32"}.get(enc.codec, enc.codec)
            ropts = pacsv.ReadOptions(block_size=block, use_threads=False, skip_rows=skip)
            if not enc.is_utf8:
                ropts.encoding = codec
            reader = pacsv.open_csv(
                path, read_options=ropts,
                convert_options=pacsv.ConvertOptions(
                    include_columns=names, column_types={c: pa.float64() for c in names}))
            it = iter(reader)
            while True:
                try:
                    batch = next(it)
                except StopIteration:
                    break
                arr = _batch_matrix(batch, names)
                if arr.shape[0] == 0:
                    continue
                _check_chunk(arr, total + skip, names, path, fmt)
                yield WrenchChunk(total, arr[:, 0].copy(), arr[:, 1:])
                total += arr.shape[0]
        except pa.ArrowInvalid as exc:
            raise _arrow_error(exc, path, header, skip) from None
        except pa.ArrowException as exc:
            raise DataError(f"cannot read as CSV ({exc})".replace("\n", " "), file=path) from None
        except UnicodeDecodeError as exc:
            raise DataError(f"not valid {enc.name} text at byte {exc.start:,} of a block "
                            f"({exc.reason}); expected a text file in UTF-8", file=path) from None
    else:
        import pyarrow.parquet as pq

        try:
            pf = pq.ParquetFile(path)
        except (pa.ArrowException, OSError) as exc:
            raise DataError(f"cannot read as Parquet ({exc})".replace("\n", " "),
                            file=path) from None
        names = resolve_columns(pf.schema_arrow.names, columns, file=path, wanted=wanted)
        for name in names:
            typ = pf.schema_arrow.field(name).type
            if not (pa.types.is_floating(typ) or pa.types.is_integer(typ)):
                raise DataError(f"expected numbers, the column holds {typ}", file=path, key=name)
        for batch in pf.iter_batches(batch_size=int(chunk_rows), columns=names,
                                     use_threads=False):
            arr = _batch_matrix(batch, names)
            if arr.shape[0] == 0:
                continue
            _check_chunk(arr, total, names, path, fmt)
            yield WrenchChunk(total, arr[:, 0].copy(), arr[:, 1:])
            total += arr.shape[0]
    if total == 0:
        raise DataError("no data rows; expected at least one sample", file=path)


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


def read_wrench_log(path, columns: Optional[dict] = None):
    """Read a whole wrench log: ``(time (m,) [s], wrench (m, 6) [log units])``."""
    chunks = list(iter_wrench_log(path, columns))
    return (np.concatenate([c.time for c in chunks]),
            np.concatenate([c.wrench for c in chunks]))


def count_rows(path, group: Optional[str] = None) -> Optional[int]:
    """Number of data rows (fast newline count for CSV, metadata for Parquet and TDMS)."""
    path = Path(path)
    try:
        if table_format(path) in ("tdms", "mat"):
            from .labfiles import lab_row_count

            return lab_row_count(path, group)
        if table_format(path) == "parquet":
            import pyarrow.parquet as pq

            return pq.ParquetFile(path).metadata.num_rows
        n = 0
        last = b"\n"
        with open(path, "rb") as fh:
            while True:
                buf = fh.read(1 << 24)
                if not buf:
                    break
                n += buf.count(b"\n")
                last = buf[-1:]
        return max(0, n - 1 + (last != b"\n"))
    except Exception:  # noqa: BLE001 - best effort (progress only); reading reports errors
        return None


def _batch_matrix(batch, names) -> np.ndarray:
    """(rows, len(names)) float64 matrix of the named columns of a batch; nulls become NaN.

    Reads the value buffers directly: ``Array.to_numpy(zero_copy_only=False)``
    imports pandas on first use (0.2 s of start-up).
    """
    import pyarrow as pa

    out = np.empty((batch.num_rows, len(names)))
    for i, name in enumerate(names):
        col = batch.column(name)
        if not pa.types.is_float64(col.type) or col.null_count:
            import pyarrow.compute as pc  # only when needed: 30 ms to import

            col = pc.fill_null(pc.cast(col, pa.float64()), float("nan"))
        out[:, i] = np.frombuffer(col.buffers()[1], dtype=np.float64, count=len(col),
                                  offset=col.offset * 8)
    return out


def _arrow_array(values, typ=None):
    """A pyarrow array from a numpy array without ``pa.array``.

    ``pa.array`` imports pandas on first use (0.2 s of start-up); building the
    array from its buffers does not, and is zero-copy for numbers.
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


def _arrow_strings(names):
    """A pyarrow string array from Python strings, from its buffers (see _arrow_array)."""
    import pyarrow as pa

    data = [str(n).encode("utf-8") for n in names]
    offsets = np.zeros(len(data) + 1, dtype=np.int32)
    offsets[1:] = np.cumsum([len(d) for d in data])
    return pa.Array.from_buffers(pa.string(), len(data),
                                 [None, pa.py_buffer(offsets), pa.py_buffer(b"".join(data))])


class ForcesWriter:
    """Write the forces table (docs/model.md section 7) in chunks, CSV or Parquet by extension.

    Columns: ``time``, one per element label [N], then extra columns.

    Chunks are converted and written on background threads, so writing
    overlaps the solving of the next chunk (pyarrow formats numbers without
    holding the GIL). CSV chunks are encoded to bytes by ``workers`` threads at
    once and written in order (formatting numbers as text is the costliest
    step of a CSV run: measured 0.9 s of CPU for a one-hour log); Parquet
    chunks are written by one thread, in order. At most ``max(2, workers) + 1``
    chunks are in flight, which bounds memory. Use as a context manager around
    an already-atomic temporary path; an error on a background thread is raised
    in the caller.
    """

    def __init__(self, path, fmt: str, labels, extra_types: dict, *, threaded: bool = True,
                 decimals: Optional[int] = 6, workers: int = 2):
        import pyarrow as pa

        self.path = Path(path)
        self.fmt = fmt
        self.labels = list(labels)
        fields = [pa.field("time", pa.float64())]
        fields += [pa.field(lab, pa.float64()) for lab in self.labels]
        fields += [pa.field(name, typ) for name, typ in extra_types.items()]
        self.schema = pa.schema(fields)
        self.threaded = threaded
        # Parquet has one writer, so one thread; CSV encodes on `workers` threads
        self.workers = max(1, int(workers)) if fmt == "csv" else 1
        # CSV only: forces and other floats (not time) rounded to this many decimals
        # (6 = 1 uN): halves the file and the formatting time; None keeps every digit
        self.decimals = None if decimals is None or decimals < 0 else int(decimals)
        self._writer = None      # Parquet: pyarrow's writer
        self._file = None        # CSV: the open output file
        self._csv_options = None
        self._pool = None
        self._pending = None

    def __enter__(self):
        import pyarrow as pa

        if self.fmt == "csv":
            import pyarrow.csv as pacsv

            # no quotes when no name or label needs them (a plain header people can read)
            plain = all(re.fullmatch(r"[\w.+-]+", str(x)) for x in
                        list(self.schema.names) + list(self.labels))
            style = "none" if plain else "needed"
            self._csv_options = _csv_write_options(style, header=False)
            self._file = open(self.path, "wb")
            try:
                header = pa.BufferOutputStream()
                with pacsv.CSVWriter(header, self.schema,
                                     write_options=_csv_write_options(style, header=True)):
                    pass
                self._file.write(header.getvalue())
            except BaseException:
                self._file.close()
                raise
        else:
            import pyarrow.parquet as pq

            # dictionary encoding only for the label column: on float columns it costs
            # more than it saves
            dict_cols = [f.name for f in self.schema if pa.types.is_dictionary(f.type)]
            self._writer = pq.ParquetWriter(str(self.path), self.schema, compression="snappy",
                                            use_dictionary=dict_cols or False)
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
        rnd = self.decimals if self.fmt == "csv" else None
        cols = [_arrow_array(np.asarray(time, dtype=float))]
        forces = np.asarray(forces, dtype=float)
        if rnd is not None:
            forces = np.round(forces, rnd)
        forces_t = np.ascontiguousarray(forces.T)
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

    def _convert(self, time, forces, extras):
        """One chunk as CSV bytes (written later, in order), or written to the Parquet file."""
        table = self._table(time, forces, extras)
        if self.fmt != "csv":
            self._writer.write_table(table)
            return None
        import pyarrow as pa
        import pyarrow.csv as pacsv

        sink = pa.BufferOutputStream()
        pacsv.write_csv(table, sink, write_options=self._csv_options)
        return sink.getvalue()

    def _flush_pending(self, keep: int) -> None:
        # finish chunks in order until at most `keep` are in flight
        while len(self._pending) > keep:
            data = self._pending.popleft().result()
            if data is not None:
                self._file.write(data)

    def write(self, time, forces, extras: dict) -> None:
        """Queue (or write) one chunk: time (k,), forces (k, n) [N], extras by column name.

        ``extras`` may be a callable returning that mapping: it is then called on
        a background thread. A dictionary-typed extra column takes ``(indices, names)``.
        """
        if self._pool is None:
            data = self._convert(time, forces, extras)
            if data is not None:
                self._file.write(data)
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
            if self._writer is not None:
                self._writer.close()
            if self._file is not None:
                self._file.close()
        return False


def _csv_write_options(style: str, *, header: bool):
    """pyarrow CSV write options: quoting ``style`` for names and values, header line or not."""
    import pyarrow.csv as pacsv

    try:
        return pacsv.WriteOptions(include_header=header, batch_size=16384,
                                  quoting_style=style, quoting_header=style)
    except TypeError:  # pragma: no cover - pyarrow without quoting_style
        return pacsv.WriteOptions(include_header=header, batch_size=16384)
