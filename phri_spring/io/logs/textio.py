"""Text decoding shared by every reader of a text input (logs, trials, manifests, configs).

Lab software saves text in more than one encoding. The rule, the same for every
text file phri-spring reads:

- UTF-8, with or without a byte-order mark (BOM), is read as such;
- UTF-16 and UTF-32 with a BOM (little or big endian) are read as such;
- text that is not valid UTF-8 but holds no control characters is read as
  Latin-1 (ISO 8859-1, what Windows lab software writes for a degree sign);
- anything else (NUL bytes without a BOM, control characters: a binary file,
  a Parquet or MATLAB file under a ``.csv`` name, UTF-16 without a BOM) is
  rejected with one line naming the file and the encoding to save it in.

Only the start of the file is examined (:data:`SNIFF_BYTES`), so a long log
costs nothing more; a UTF-8 file with a stray Latin-1 byte further on is
reported by the reader that meets it.
"""

from __future__ import annotations

import codecs
import os
from dataclasses import dataclass
from pathlib import Path

from ...errors import DataError

__all__ = ["SNIFF_BYTES", "TextEncoding", "sniff_encoding", "read_text", "open_text",
           "NA_STRINGS", "is_missing"]

#: bytes examined to choose the encoding
SNIFF_BYTES = 1 << 16

_BOMS = (  # longest first: the UTF-32 LE BOM starts with the UTF-16 LE one
    (codecs.BOM_UTF32_LE, "utf-32-le", "UTF-32 LE"),
    (codecs.BOM_UTF32_BE, "utf-32-be", "UTF-32 BE"),
    (codecs.BOM_UTF8, "utf-8", "UTF-8 with BOM"),
    (codecs.BOM_UTF16_LE, "utf-16-le", "UTF-16 LE"),
    (codecs.BOM_UTF16_BE, "utf-16-be", "UTF-16 BE"),
)
# control characters that never occur in a text table or a YAML file (tab, LF, CR and
# form feed do); bytes 0x80-0x9f are printable in cp1252 and so allowed in Latin-1 text
_CONTROL = bytes(c for c in range(32) if c not in (9, 10, 12, 13)) + b"\x7f"

#: text that means "no value" in a text column: pandas' and pyarrow's default NA spellings
NA_STRINGS = frozenset({
    "", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND", "1.#QNAN",
    "<NA>", "N/A", "NA", "NULL", "NaN", "None", "n/a", "nan", "null", "NaT",
})


@dataclass(frozen=True)
class TextEncoding:
    """How to decode a text file.

    Attributes
    ----------
    codec : str
        Python codec name (``utf-8``, ``utf-16-le``, ``latin-1`` ...).
    bom : int
        Length of the byte-order mark to skip [bytes].
    name : str
        Human name (``UTF-16 LE``), for messages.
    """

    codec: str
    bom: int
    name: str

    @property
    def is_utf8(self) -> bool:
        return self.codec == "utf-8"


def _reject(path, what: str) -> DataError:
    return DataError(f"{what}; expected a text file in UTF-8 (or UTF-16 with a byte-order "
                     "mark): save it as UTF-8 text (a spreadsheet's 'CSV UTF-8')", file=path)


def sniff_encoding(head: bytes, path=None, *, what: str = "text",
                   complete: bool | None = None) -> TextEncoding:
    """Choose the encoding of a text file from its first bytes.

    Parameters
    ----------
    head : bytes
        The first bytes of the file (up to :data:`SNIFF_BYTES`; a cut
        multi-byte character at the end is allowed).
    path : str or path-like, optional
        The file, for messages.
    what : str
        What the file should be (``a CSV table``), for messages.
    complete : bool, optional
        True if ``head`` is the whole file (then a multi-byte character cut at its
        end is an error). Default: ``len(head) < SNIFF_BYTES``.

    Returns
    -------
    TextEncoding

    Raises
    ------
    DataError
        Binary data, or text in an encoding that cannot be told from its bytes.
    """
    final = len(head) < SNIFF_BYTES if complete is None else bool(complete)
    for bom, codec, name in _BOMS:
        if head.startswith(bom):
            body = head[len(bom):]
            try:
                codecs.getincrementaldecoder(codec)().decode(body, final=final)
            except UnicodeDecodeError:
                raise _reject(path, f"not valid {name} text although it starts with a "
                                    f"{name} byte-order mark") from None
            return TextEncoding(codec, len(bom), name)
    if head.startswith((b"PAR1", b"MATLAB", b"\x89HDF", b"PK\x03\x04", b"\x1f\x8b")):
        kind = {b"PAR1": "a Parquet file", b"MATL": "a MATLAB file", b"\x89HDF": "an HDF5 file",
                b"PK\x03": "a zip archive (e.g. .xlsx)", b"\x1f\x8b\x08": "a gzip file"}
        label = next((v for k, v in kind.items() if head.startswith(k)), "binary data")
        raise _reject(path, f"{label}, not {what}")
    if b"\x00" in head:
        # UTF-16 without a BOM has every other byte 0 on ASCII text
        odd, even = head[1::2], head[0::2]
        zeros = (odd.count(0) / max(len(odd), 1), even.count(0) / max(len(even), 1))
        if len(head) >= 4 and ((zeros[0] > 0.4 and zeros[1] < 0.1)
                               or (zeros[1] > 0.4 and zeros[0] < 0.1)):
            raise _reject(path, "UTF-16 text without a byte-order mark (cannot tell its byte "
                                "order)")
        raise _reject(path, f"binary data (NUL bytes), not {what}")
    if head.translate(None, _CONTROL) != head:
        raise _reject(path, f"binary data (control characters), not {what}")
    try:
        codecs.getincrementaldecoder("utf-8")().decode(head, final=final)
    except UnicodeDecodeError:
        return TextEncoding("latin-1", 0, "Latin-1")
    return TextEncoding("utf-8", 0, "UTF-8")


def read_text(path, *, what: str = "text", max_bytes: int | None = None) -> str:
    """The whole text of a (small) file, decoded by the rule of this module.

    Parameters
    ----------
    path : str or path-like
    what : str
        What the file should be, for messages (``a YAML file``).
    max_bytes : int, optional
        Refuse larger files (checked before reading) [bytes].

    Raises
    ------
    DataError
        Missing file, a folder, unreadable, too large, binary, or not decodable.
        (Callers that report config errors convert it.)
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            if max_bytes is None:
                data = fh.read()
            else:  # read no more than the bound (a device such as /dev/zero never ends)
                data = fh.read(max_bytes + 1)
                if len(data) > max_bytes:
                    sniff_encoding(data[:SNIFF_BYTES], path, what=what)  # binary: say so
                    size = os.fstat(fh.fileno()).st_size
                    size = (f"{size:,} bytes" if size > max_bytes
                            else f"more than {max_bytes:,} bytes")
                    raise DataError(f"{size}: too large for {what} (at most {max_bytes:,} "
                                    "bytes)", file=path)
    except FileNotFoundError:
        raise DataError(f"file not found; expected {what}", file=path) from None
    except IsADirectoryError:
        raise DataError(f"is a folder; expected {what}", file=path) from None
    except OSError as exc:
        raise DataError(f"cannot read ({exc.strerror or exc})", file=path) from None
    enc = sniff_encoding(data[:SNIFF_BYTES], path, what=what,
                         complete=len(data) <= SNIFF_BYTES)
    if enc.codec == "utf-8" and not enc.bom and len(data) > SNIFF_BYTES:
        # the whole file is at hand: a Latin-1 byte after the sniffed start still makes it
        # Latin-1 text (if it holds no control characters)
        enc = sniff_encoding(data, path, what=what, complete=True)
    try:
        text = data[enc.bom:].decode(enc.codec)
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1 if enc.bom == 0 else None
        where = f" on line {line}" if line else ""
        raise _reject(path, f"not valid {enc.name} text{where} (byte {exc.start + enc.bom})") \
            from None
    if "\x00" in text:
        raise _reject(path, f"binary data (NUL characters), not {what}")
    return text


def open_text(path, *, what: str = "text"):
    """A text stream of the file (``newline=''``) and its :class:`TextEncoding`.

    For large files read line by line; the encoding is chosen from the first
    :data:`SNIFF_BYTES`.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(SNIFF_BYTES)
            complete = not fh.read(1)
    except OSError as exc:
        raise DataError(f"cannot read ({exc.strerror or exc})", file=path) from None
    enc = sniff_encoding(head, path, what=what, complete=complete)
    codec = {"utf-16-le": "utf-16", "utf-16-be": "utf-16", "utf-32-le": "utf-32",
             "utf-32-be": "utf-32"}.get(enc.codec, "utf-8-sig" if enc.codec == "utf-8"
                                        else enc.codec)
    return open(path, encoding=codec, newline="", errors="strict"), enc


def is_missing(value) -> bool:
    """True for a missing value in any spelling: None, NaN, pandas NA/NaT, 'NA', 'null', ..."""
    if value is None:
        return True
    if isinstance(value, str):
        return value.strip() in NA_STRINGS
    if isinstance(value, float):
        return value != value
    try:
        import pandas as pd

        return bool(pd.isna(value))
    except (TypeError, ValueError):
        return False
