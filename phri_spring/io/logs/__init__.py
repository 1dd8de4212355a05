"""Wrench logs in, contact forces out (docs/model.md section 7): one import for all three jobs.

The work is split by job, and this module re-exports the public names so that
``from phri_spring.io.logs import ...`` keeps working:

- reading: :mod:`phri_spring.io.logs.formats` (the registry of log formats, one
  recipe each, and the chunked reader), with the recipes in
  :mod:`phri_spring.io.logs.arrow` (CSV, Parquet) and
  :mod:`phri_spring.io.logs.lab` (TDMS, MAT), on
  :mod:`phri_spring.io.logs.base` (the recipe, the chunk, the column map and group);
- writing: :mod:`phri_spring.io.outputs.forces`;
- reading ahead on a thread: :mod:`phri_spring.io.logs.readahead`.
"""

from __future__ import annotations

from ..outputs.forces import ForcesWriter
from .base import (LogFormat, WrenchChunk, parse_column_map, reader_options,
                       resolve_columns, take_group)
from .formats import (LOG_FORMATS, count_rows, format_named, iter_wrench_log, log_format,
                          read_wrench_log, table_format)
from .readahead import Prefetch, prefetch

__all__ = ["prefetch", "table_format", "resolve_columns", "iter_wrench_log", "read_wrench_log",
           "count_rows", "ForcesWriter", "WrenchChunk", "parse_column_map", "Prefetch",
           "LogFormat", "LOG_FORMATS", "log_format", "format_named", "reader_options",
           "take_group"]
