"""CSV and Parquet logs through pyarrow: the :data:`CSV` and :data:`PARQUET` recipes.

pyarrow parses CSV in C++ and reads both formats in chunks, so hour-long logs
fit in bounded memory; it also writes the forces table (the sinks below, used
by :class:`phri_spring.io.outputs.forces.ForcesWriter`). Every problem is a
one-line :class:`DataError` naming the file and the column (and the line, for
bad values). The recipes are registered in
:data:`phri_spring.io.logs.formats.LOG_FORMATS`.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Iterator, Optional

import numpy as np

from ...errors import DataError
from .columns import LOG_COLUMNS
from .base import LogFormat, WrenchChunk, check_chunk, resolve_columns

__all__ = ["CSV", "PARQUET"]

_ARROW_ROW = re.compile(r"[Rr]ow #(\d+)")
_ARROW_COL = re.compile(r"column #(\d+)")
_ARROW_VAL = re.compile(r"invalid value '([^']*)'")


# --------------------------------------------------------------------------- reading
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


def _batch_matrix(batch, names) -> np.ndarray:
    """(rows, len(names)) float64 matrix of the named columns of a batch; nulls become NaN.

    Reads the value buffers directly: ``Array.to_numpy(zero_copy_only=False)``
    imports pandas on first use, which would add to every run's start-up.
    """
    import pyarrow as pa

    out = np.empty((batch.num_rows, len(names)))
    for i, name in enumerate(names):
        col = batch.column(name)
        if not pa.types.is_float64(col.type) or col.null_count:
            import pyarrow.compute as pc  # only when needed: slow to import

            col = pc.fill_null(pc.cast(col, pa.float64()), float("nan"))
        out[:, i] = np.frombuffer(col.buffers()[1], dtype=np.float64, count=len(col),
                                  offset=col.offset * 8)
    return out


def _csv_header(path: Path):
    """``(header names, comment lines skipped, encoding)`` of a CSV log."""
    import pyarrow as pa
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
    return header, skip, enc


def _read_csv(path: Path, columns: Optional[dict] = None, *, chunk_rows: int = 131072,
              wanted=LOG_COLUMNS) -> Iterator[WrenchChunk]:
    """Stream a CSV log in pyarrow's blocks of about ``chunk_rows`` rows (see LogFormat.read)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    header, skip, enc = _csv_header(path)
    names = resolve_columns(header, columns, file=path, wanted=wanted)
    # blocks of about chunk_rows rows at ~8 bytes a cell, at most 2 MB: larger blocks
    # cost more in page faults than they save
    block = int(min(max(1 << 16, int(chunk_rows) * 8 * len(header)), 1 << 21))
    total = 0
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
            # line numbers count the comment lines and the header
            check_chunk(arr, names, path, first=total + skip + 2, unit="line")
            yield WrenchChunk(total, arr[:, 0].copy(), arr[:, 1:])
            total += arr.shape[0]
    except pa.ArrowInvalid as exc:
        raise _arrow_error(exc, path, header, skip) from None
    except pa.ArrowException as exc:
        raise DataError(f"cannot read as CSV ({exc})".replace("\n", " "), file=path) from None
    except UnicodeDecodeError as exc:
        raise DataError(f"not valid {enc.name} text at byte {exc.start:,} of a block "
                        f"({exc.reason}); expected a text file in UTF-8", file=path) from None
    if total == 0:
        raise DataError("no data rows; expected at least one sample", file=path)


def _read_parquet(path: Path, columns: Optional[dict] = None, *, chunk_rows: int = 131072,
                  wanted=LOG_COLUMNS) -> Iterator[WrenchChunk]:
    """Stream a Parquet log in batches of ``chunk_rows`` rows (see LogFormat.read)."""
    import pyarrow as pa
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
    total = 0
    for batch in pf.iter_batches(batch_size=int(chunk_rows), columns=names,
                                 use_threads=False):
        arr = _batch_matrix(batch, names)
        if arr.shape[0] == 0:
            continue
        check_chunk(arr, names, path, first=total + 1)
        yield WrenchChunk(total, arr[:, 0].copy(), arr[:, 1:])
        total += arr.shape[0]
    if total == 0:
        raise DataError("no data rows; expected at least one sample", file=path)


def _count_csv_rows(path: Path, columns: Optional[dict] = None) -> int:
    """Lines after the header, from a newline count (no parsing; the group does not apply)."""
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


def _count_parquet_rows(path: Path, columns: Optional[dict] = None) -> int:
    """Rows in the file's metadata (the group does not apply)."""
    import pyarrow.parquet as pq

    return pq.ParquetFile(path).metadata.num_rows


# --------------------------------------------------------------------------- writing
def _csv_write_options(style: str, *, header: bool):
    """pyarrow CSV write options: quoting ``style`` for names and values, header line or not."""
    import pyarrow.csv as pacsv

    try:
        return pacsv.WriteOptions(include_header=header, batch_size=16384,
                                  quoting_style=style, quoting_header=style)
    except TypeError:  # pragma: no cover - pyarrow without quoting_style
        return pacsv.WriteOptions(include_header=header, batch_size=16384)


class _CsvSink:
    """A CSV forces table: the header at once, then chunks encoded to bytes on any thread."""

    # formatting numbers as text is the costliest step of a CSV run, and pyarrow
    # does it without the GIL: chunks are encoded on several threads at once
    parallel = True
    # rounded floats (6 decimals = 1 uN) halve the file and the formatting time
    rounds = True

    def __init__(self, path: Path, schema, labels):
        import pyarrow as pa
        import pyarrow.csv as pacsv

        # no quotes when no name or label needs them (a plain header people can read)
        plain = all(re.fullmatch(r"[\w.+-]+", str(x)) for x in
                    list(schema.names) + list(labels))
        style = "none" if plain else "needed"
        self._options = _csv_write_options(style, header=False)
        self._file = open(path, "wb")
        try:
            header = pa.BufferOutputStream()
            with pacsv.CSVWriter(header, schema,
                                 write_options=_csv_write_options(style, header=True)):
                pass
            self._file.write(header.getvalue())
        except BaseException:
            self._file.close()
            raise

    def encode(self, table) -> bytes:
        """One chunk as CSV bytes (no header), for :meth:`write` in order."""
        import pyarrow as pa
        import pyarrow.csv as pacsv

        sink = pa.BufferOutputStream()
        pacsv.write_csv(table, sink, write_options=self._options)
        return sink.getvalue()

    def write(self, data) -> None:
        self._file.write(data)

    def close(self) -> None:
        self._file.close()


class _ParquetSink:
    """A Parquet forces table (snappy): pyarrow's one writer, so chunks go in one at a time."""

    parallel = False
    rounds = False      # Parquet always stores full double precision

    def __init__(self, path: Path, schema, labels):
        import pyarrow as pa
        import pyarrow.parquet as pq

        # dictionary encoding only for the label column: on float columns it costs
        # more than it saves
        dict_cols = [f.name for f in schema if pa.types.is_dictionary(f.type)]
        # a chunk's column is encoded in batches of this many values (pyarrow's default
        # 1,024 costs a round of bookkeeping per batch); pages still close at pyarrow's
        # page size, so a chunk of up to 65,536 rows gives the same file as before
        self._writer = pq.ParquetWriter(str(path), schema, compression="snappy",
                                        use_dictionary=dict_cols or False,
                                        write_batch_size=1 << 16)

    def encode(self, table) -> None:
        """Write one chunk at once (nothing is left for :meth:`write`)."""
        self._writer.write_table(table)

    def close(self) -> None:
        self._writer.close()


# --------------------------------------------------------------------------- recipes
#: comma-separated text, optionally after '# ...' comment lines; any of the
#: encodings :mod:`phri_spring.io.logs.textio` recognises
CSV = LogFormat("csv", (".csv", ".txt"), read=_read_csv, count_rows=_count_csv_rows,
                writer=_CsvSink)
#: Apache Parquet; integer or float columns
PARQUET = LogFormat("parquet", (".parquet", ".pq"), read=_read_parquet,
                    count_rows=_count_parquet_rows, writer=_ParquetSink)
