"""The memory a run needs, estimated from its config before anything is allocated.

Why estimate first: numpy reports a failed allocation as ``MemoryError``, but
pyarrow's writers, scikit-fem and LAPACK allocate in C++ and C, where a failed
allocation can end the process (``std::bad_alloc``, abort, exit -6) before any
clean-up runs, leaving a temporary file beside the output; and on Linux a
large allocation usually succeeds and the kernel's out-of-memory killer ends
the process later (SIGKILL). Neither can be caught, so every command that
builds a model asks here first, before any output or temporary file exists,
and a run that cannot fit is refused with one line naming the key to change.

One estimator, :func:`estimate`: the size of a config (rows x angles, and for
the coupled arm the built-in FE's mesh), the arm, the chunk size and the
command's options give a :class:`MemoryEstimate`, a sum of named terms in bytes
(below). :func:`available_memory` reads what the machine can give: the
smallest of ``MemAvailable`` (``/proc/meminfo``; physical memory where there is
none), the cgroup's ``memory.max`` (containers) and, for address space, the
``RLIMIT_AS`` soft limit (``ulimit -v``) less what the process has mapped.
``PHRI_SPRING_MEMORY_LIMIT`` (bytes, or with a K, M, G or T suffix, powers of
1024) replaces the first two, e.g. to test the refusal on a small "machine".

Terms (each constant below is what real runs were seen to need, peak RSS and
tracemalloc, with a margin; the figures behind them are in
``benchmarks/MEMORY_BUDGET.md``):

==================  ==========================================================
``config``          element labels (text) and stiffness arrays of the config
``model``           geometry and model arrays, one per model held (Monte Carlo
                    draws hold one per draw), with the build's temporaries
``coupled``         the coupled arm's dense (6n x 6n) matrices, about 16 live
``tissue FE``       the built-in FE of the coupled arm: per hexahedron
                    (assembly, sparse LU) and dense (dofs x 6n) blocks; not
                    counted when its cached result is on disk
``chunk``           solving one chunk (rows x n values) with the chunks that
                    wait for the writer, the ``--shear`` columns
``writer``          CSV or Parquet: per column, and per cell of the chunks in
                    flight
``row groups``      Parquet: footer metadata per column of every row group,
                    held until the file closes (grows with the log's length)
``plot``            ``--plot``: the max-pooled forces and the heat map
``draws``           Monte Carlo: the drawn inputs and the (draws x block x n)
                    forces with their percentiles
``designs``         ``phri design``: every design's config, and each worker
                    evaluating one design over the whole load set
==================  ==========================================================

Address space that a run reserves but does not touch (pyarrow's CSV encoder
reserves 128 KiB per column and chunk) is counted only against ``RLIMIT_AS``.

Chunks: ``--chunk-rows`` is a performance hint (larger chunks amortise
per-chunk costs), so when the chunk is the only thing that does not fit, the
run takes fewer rows per chunk (:func:`plan_stream`, down to
:data:`MIN_CHUNK_ROWS`) instead of refusing; the output is the same. Only a
model too large to stream even :data:`MIN_CHUNK_ROWS` samples at a time is
refused, naming the element count.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from ...errors import ConfigError, DataError
from ...plugins import arm_record
from .machine import ENV_LIMIT, MemoryBudget, available_memory

__all__ = ["ENV_LIMIT", "MemoryEstimate", "MemoryBudget", "estimate", "available_memory",
           "check", "check_elements", "check_model", "plan_stream", "preferred_chunk_rows",
           "fe_mesh_size", "fe_to_build", "dense_coupling_terms", "element_key",
           "CSV_MAX_COLUMNS", "MIN_CHUNK_ROWS", "format_bytes"]


# --------------------------------------------------------------------------- constants
#: label text + tuple slot, tissue and cuff stiffness
CONFIG_BYTES_PER_ELEMENT = 128
#: geometry (18 doubles), SpringModel (53 doubles) and the build's temporaries
MODEL_BYTES_PER_ELEMENT = 1024
#: array headers and dataclasses of one model
MODEL_FIXED_BYTES = 32 << 10
#: dense (6n x 6n) float64 matrices alive at once while the coupled model is built
#: (K, its factor, R, C_t, C, their products, the reduced problem; counted 13 to 16)
COUPLED_DENSE_COPIES = 16
#: dense (6n x 6n) matrices a built coupled model keeps (K_t, C, C_t, the output map, the
#: safeguard's reduced problem): what each further Monte Carlo draw's model adds
COUPLED_HELD_COPIES = 6
#: coupled per-set cache entries (69 n doubles each) counted; a log that meets more
#: distinct contact sets holds more (the cache keeps at most 16,384)
COUPLED_CACHED_SETS = 512
#: what the coupled patches read (physics/continuum/reading.py): skin-node rows of 6n
#: doubles, (2 level + 1)^2 nodes per patch at the FE's default level 3, alive as the
#: cached rows, their local-axes product and the reading's own map while the model is
#: built (the map held per further model), plus one 1,024-row chunk of node values
READING_NODES_PER_PATCH = 49
READING_BUILD_COPIES = 3
READING_CHUNK_ROWS = 1024
#: rows x 6 x n gathered per block when rows of a coupled chunk have different sets
COUPLED_GATHER_BYTES_PER_ELEMENT = 2 * 4096 * 6 * 8
#: built-in FE: scikit-fem's bases and quadrature whatever the mesh, then per hexahedron the
#: gradients, element matrices, sparse assembly and LU fill-in (a fit over meshes of 3 to
#: 42 patches)
FE_FIXED_BYTES = 192 << 20
FE_BYTES_PER_HEX = 560 << 10
#: dense (dofs x 6n) blocks of the FE's condensation alive at once (fitted, rounded up)
FE_DENSE_COPIES = 4
#: solving a chunk, its extras and the chunks waiting for the writer, per value
#: (sample x element)
CHUNK_BYTES_PER_VALUE = 48
#: ``--shear``: tangential forces (m, n, 3) and their temporaries, per value
SHEAR_BYTES_PER_VALUE = 96
#: coupled arm, per value: indicator, output map and set keys beside the spring terms
COUPLED_BYTES_PER_VALUE = 48
#: writer, per cell (sample x output column) of the chunks in flight: rounding, transposing
#: and the text (CSV) or the encoded pages (Parquet). The CSV figure was raised once a
#: whole 2,100-element CSV run peaked above its estimate in CI
#: (tests/faults/test_fault_memory.py): the allocators' slack varies from run to run
CSV_BYTES_PER_CELL = 112
PARQUET_BYTES_PER_CELL = 24
#: writer, per output column whatever the rows
CSV_BYTES_PER_COLUMN = 4 << 10
PARQUET_BYTES_PER_COLUMN = 8 << 10
#: Parquet footer metadata per column per row group, held until the file closes
PARQUET_BYTES_PER_COLUMN_CHUNK = 2 << 10
#: address space pyarrow's CSV encoder reserves per column for each chunk it encodes
#: (its batch of 16,384 rows x 8 B), for the header and two encoders
CSV_RESERVED_PER_COLUMN = 3 * (128 << 10)
#: address space a streamed run maps beyond its data: pyarrow's libraries, the
#: allocators' arenas and the stacks of its threads. Under a tighter ``ulimit -v``
#: pyarrow's CSV encoder ends in std::bad_alloc and an abort: refused
STREAM_RESERVED = 1600 << 20
#: pyarrow's CSV writer sizes one buffer as columns x 128 KiB in a 2^34-byte range: a
#: table of 131,072 columns or more fails ("Negative buffer resize") or worse
CSV_MAX_COLUMNS = 131_071
#: ``--plot``: the max-pool (2 x 2,000 groups x 8 B) and the drawn heat map (per group
#: and element)
PLOT_BYTES_PER_ELEMENT = 2 * 2000 * (8 + 56)
#: Monte Carlo: forces of every draw over a block, their percentiles and the sort's copy
DRAW_BYTES_PER_VALUE = 3 * 8
#: Monte Carlo draws hold at least this many forces per block (uncertainty._CHUNK_ENTRIES)
DRAW_BLOCK_ENTRIES = 1 << 23
#: one drawn config (a dataclass sharing the base's arrays) and its row of drawn inputs
DRAW_FIXED_BYTES = 2 << 10
#: ``phri design``: one design's config mapping, Config and results beside its
#: per-element arrays
DESIGN_FIXED_BYTES = 12 << 10
#: a worker process of ``phri design``: interpreter and libraries
WORKER_RUNTIME_BYTES = 256 << 20
#: evaluating one design over its load set, per value (forces, pressures, objectives)
DESIGN_BYTES_PER_VALUE = 64
#: fewest samples per chunk a streamed run is reduced to before it is refused
MIN_CHUNK_ROWS = 16
#: most samples per chunk: any larger hint means "the whole log", and a count beyond 64
#: bits made pyarrow's Parquet reader fail (OverflowError)
MAX_CHUNK_ROWS = 1 << 31
#: a chunk of about this many values is fast and small (``simulate``'s default cap)
PREFERRED_CHUNK_VALUES = 1 << 22
#: fine meshes still get at least this many rows per chunk when memory allows
PREFERRED_MIN_ROWS = 1024


# --------------------------------------------------------------------------- estimate
@dataclass(frozen=True)
class MemoryEstimate:
    """Bytes a run needs: named terms (see the module's table), and untouched reservations.

    Attributes
    ----------
    terms : dict
        Term name -> bytes, in the order they were added.
    reserved : int
        Address space reserved but not touched (counted against ``RLIMIT_AS`` only).
    chunk_rows : int
        Samples per chunk the streamed terms assume (0: no stream).
    """

    terms: dict = field(default_factory=dict)
    reserved: int = 0
    chunk_rows: int = 0

    @property
    def total(self) -> int:
        return int(sum(self.terms.values()))

    def breakdown(self, most: int = 3) -> str:
        """The largest terms, e.g. ``writer 12 GB, model 3.1 GB``."""
        big = sorted(((v, k) for k, v in self.terms.items() if v > 0), reverse=True)[:most]
        return ", ".join(f"{k} {format_bytes(v)}" for v, k in big)


def format_bytes(n: float) -> str:
    """``1.2 GB``, ``340 MB``, ``12 kB`` (powers of 1000, as people read sizes)."""
    n = float(n)
    if n >= 1e21:
        return f"{n:.2g} B"
    for unit, scale in (("EB", 1e18), ("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6),
                        ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{int(n)} B"


def _size(size) -> tuple:
    """(n_rows, n_angles) of a Config or of a pair."""
    if hasattr(size, "n_rows") and hasattr(size, "angle_count"):
        return int(size.n_rows), int(size.angle_count)
    rows, angles = size
    return int(rows), int(angles)


def estimate(size, arm: str = "compliant", chunk_rows: int = 0, *,
             output_format: Optional[str] = None, shear: bool = False, plot: bool = False,
             samples: Optional[int] = None, extra_columns: int = 6, columns_per_element: int = 0,
             draws: int = 0, distinct_draws: bool = False, draw_rows: Optional[int] = None,
             designs: int = 0, workers: int = 1,
             load_samples: int = 0, fe: Optional[tuple] = None) -> MemoryEstimate:
    """Estimated bytes of a run; a pure function of its sizes (nothing is read or allocated).

    Parameters
    ----------
    size : Config or (n_rows, n_angles)
    arm : str or ArmModel
        A registered arm (its declared :class:`~phri_spring.plugins.ArmMemory` terms; a
        name not registered: the spring network's terms only).
    chunk_rows : int
        Samples per streamed chunk (0: no stream, the model only).
    output_format : {'csv', 'parquet'}, optional
        The streamed table's format (its writer terms).
    shear, plot : bool
        ``--shear`` columns, ``--plot`` figure.
    samples : int, optional
        Samples in the log (Parquet's row groups; unknown: not counted).
    extra_columns, columns_per_element : int
        The output table's columns beside the per-element ones (time and the extras), and
        columns per element (default 1, 3 with ``shear``).
    draws, distinct_draws : int, bool
        Monte Carlo draws, and whether every draw has its own model.
    draw_rows : int, optional
        Samples solved at once for every draw (default: the streamed block, about
        :data:`DRAW_BLOCK_ENTRIES` forces over all draws).
    designs, workers, load_samples : int
        ``phri design``: designs, worker processes, samples in the load set.
    fe : (hexahedra, dofs), optional
        The built-in tissue FE's mesh (:func:`fe_mesh_size`) an arm builds; None when it is
        not built (cached, or the user's own surface stiffness).
    """
    n_rows, n_angles = _size(size)
    n = n_rows * n_angles
    mem = arm_record(arm).memory
    terms = {"config": n * CONFIG_BYTES_PER_ELEMENT}
    model = MODEL_FIXED_BYTES + n * MODEL_BYTES_PER_ELEMENT
    n_models = max(1, draws) if (draws and distinct_draws) else 1
    terms["model"] = n_models * model
    if mem.model_terms is not None:
        terms.update(mem.model_terms(n, n_models))
    if fe is not None:
        hexes, dofs = fe
        terms["tissue FE"] = (FE_FIXED_BYTES + int(hexes) * FE_BYTES_PER_HEX
                              + FE_DENSE_COPIES * int(dofs) * 6 * n * 8)
    reserved = 0
    rows = max(0, int(chunk_rows))
    if draws:
        block = max(1, DRAW_BLOCK_ENTRIES // max(1, draws * n)) if draw_rows is None \
            else int(draw_rows)
        rows = block
        terms["draws"] = (draws * (DRAW_FIXED_BYTES + 3 * 8 * n)
                          + max(DRAW_BLOCK_ENTRIES, draws * block * n) * DRAW_BYTES_PER_VALUE)
    if rows:
        per_value = CHUNK_BYTES_PER_VALUE + (SHEAR_BYTES_PER_VALUE if shear else 0) \
            + mem.bytes_per_value
        terms["chunk"] = rows * n * per_value + n * mem.bytes_per_element
    if output_format in ("csv", "parquet"):
        per_el = columns_per_element or (3 if shear else 1)
        cols = 1 + per_el * n + int(extra_columns)
        csv = output_format == "csv"
        terms["writer"] = cols * (CSV_BYTES_PER_COLUMN if csv else PARQUET_BYTES_PER_COLUMN) \
            + max(rows, 1) * cols * (CSV_BYTES_PER_CELL if csv else PARQUET_BYTES_PER_CELL)
        reserved += STREAM_RESERVED
        if csv:
            reserved += cols * CSV_RESERVED_PER_COLUMN
        elif samples:
            groups = math.ceil(int(samples) / max(rows, 1))
            terms["row groups"] = groups * cols * PARQUET_BYTES_PER_COLUMN_CHUNK
    if plot:
        terms["plot"] = n * PLOT_BYTES_PER_ELEMENT
    if designs:
        terms["designs"] = designs * (DESIGN_FIXED_BYTES + n * (CONFIG_BYTES_PER_ELEMENT + 24))
        terms["design workers"] = max(1, workers) * (
            WORKER_RUNTIME_BYTES + model + int(load_samples) * n * DESIGN_BYTES_PER_VALUE)
    return MemoryEstimate(terms={k: int(v) for k, v in terms.items()}, reserved=int(reserved),
                          chunk_rows=rows)


# --------------------------------------------------------------------------- checks
def element_key(n_rows: int, n_angles: int) -> str:
    """The config key that sets the element count's larger factor."""
    return "geometry.rows" if n_rows > n_angles else "geometry.angles.count"


def fits(est: MemoryEstimate, budget: Optional[MemoryBudget] = None) -> bool:
    budget = available_memory() if budget is None else budget
    if est.total > budget.memory:
        return False
    return budget.address_space is None or est.total + est.reserved <= budget.address_space


def check(est: MemoryEstimate, *, what: str, key: str, advice: str, file=None,
          error=ConfigError, budget: Optional[MemoryBudget] = None) -> None:
    """Raise ``error`` (one line: key, need, limit and why, advice) when ``est`` cannot fit."""
    budget = available_memory() if budget is None else budget
    if fits(est, budget):
        return
    if est.total > budget.memory:
        raise error(f"{what} need about {format_bytes(est.total)} of memory "
                    f"({est.breakdown()}), more than the {format_bytes(budget.memory)} this "
                    f"machine can give ({budget.source}); {advice}", file=file, key=key)
    # only the address space is short: libraries, arenas and reservations count there
    if est.reserved > est.total:
        advice = "expected a larger ulimit -v"
    raise error(f"{what} need about {format_bytes(est.total + est.reserved)} of address space "
                f"({est.breakdown(2)}, libraries, threads and reservations "
                f"{format_bytes(est.reserved)}), more than the "
                f"{format_bytes(budget.address_space)} the address-space limit (ulimit -v) "
                f"leaves; {advice}", file=file, key=key)


def _elements_text(n_rows: int, n_angles: int) -> str:
    return f"{n_rows * n_angles:,} elements ({n_rows:,} rows x {n_angles:,} angles)"


def check_elements(n_rows: int, n_angles: int, *, path=None) -> None:
    """Refuse a geometry whose config and model alone cannot fit, before its labels exist.

    Called by :func:`phri_spring.io.config.config_from_dict` as soon as the counts are known.
    """
    est = estimate((n_rows, n_angles), "rigid")
    check(est, what=_elements_text(n_rows, n_angles), key=element_key(n_rows, n_angles),
          advice="expected fewer elements", file=path)


def fe_mesh_size(cfg, geometry=None) -> tuple:
    """(hexahedra, dofs) of the built-in FE's mesh for a config, without building it
    (:func:`phri_spring.physics.continuum.mesh.mesh_size` at the shipped level, with the config's
    ``tissue.continuum.patch_gap``)."""
    from ...physics.continuum import mesh as fe_mesh
    g = cfg.geometry() if geometry is None else geometry
    return fe_mesh.mesh_size(g, float(cfg.continuum_thickness),
                             patch_gap=cfg.continuum_patch_gap)


def dense_coupling_terms(n_elements: int, n_models: int = 1) -> dict:
    """The ``coupled`` term of a model holding dense (6n x 6n) matrices (about
    :data:`COUPLED_DENSE_COPIES` live while it is built, :data:`COUPLED_HELD_COPIES` held per
    further model) and its cached solves, and the ``coupled_reading`` term of its patches'
    node rows (:data:`READING_NODES_PER_PATCH`): an arm's :attr:`ArmMemory.model_terms`."""
    nd = 6 * int(n_elements)
    nodes = READING_NODES_PER_PATCH * int(n_elements)
    return {"coupled": (COUPLED_DENSE_COPIES + COUPLED_HELD_COPIES * (n_models - 1)) * nd * nd * 8
            + n_models * COUPLED_CACHED_SETS * 69 * int(n_elements) * 8,
            "coupled_reading": ((READING_BUILD_COPIES + n_models - 1) * nodes * nd
                                + READING_CHUNK_ROWS * nodes) * 8}


def fe_to_build(cfg, cache_dir=None) -> Optional[tuple]:
    """The FE mesh size when the built-in tissue FE will be built for ``tissue.continuum``,
    else None (cached, or the user's own surface stiffness, or a config the model refuses
    anyway): an arm's :attr:`ArmMemory.fe_mesh`."""
    if cfg.continuum_surface_stiffness is not None or cfg.continuum_thickness is None:
        return None
    from ..cache.surface_stiffness import cache_key, default_cache_dir
    g = cfg.geometry()
    radius = float(g.radius[0])
    if len(set(g.radius.tolist())) != 1 or not 0 < cfg.continuum_thickness < radius \
            or not cfg.poisson_ratio < 0.5:
        return None      # the model's own checks refuse it with their message
    key = cache_key(g, cfg.continuum_thickness, cfg.poisson_ratio,
                    patch_gap=cfg.continuum_patch_gap)
    folder = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    if (folder / f"surface-stiffness-{key[:32]}.npz").is_file():
        return None
    try:
        return fe_mesh_size(cfg, g)
    except ValueError:   # overlapping patches or rows: the FE refuses them with its message
        return None


def _checked_fe(cfg, arm, cache_dir=None) -> Optional[tuple]:
    """The arm's tissue FE mesh size (None: not built), after refusing a model whose dense
    matrices (checked first: cheap, so that a huge model is refused before its mesh is
    even sized) or tissue FE cannot fit (an arm with :attr:`ArmMemory.dense` terms)."""
    rec = arm_record(arm)
    if not rec.memory.dense:
        return None
    n_rows, n_angles = _size(cfg)
    what, key = _elements_text(n_rows, n_angles), element_key(n_rows, n_angles)
    advice = f"expected fewer elements for the {rec.name} arm{rec.memory.advice}"
    check(estimate(cfg, rec), key=key, advice=advice, file=cfg.path,
          what=f"the {rec.name} arm's matrices for {what}")
    fe = None if rec.memory.fe_mesh is None else rec.memory.fe_mesh(cfg, cache_dir)
    if fe is not None:
        check(estimate(cfg, rec, fe=fe), key=key, advice=advice, file=cfg.path,
              what=f"the {rec.name} arm's tissue FE ({fe[0]:,} hexahedra, {fe[1]:,} dofs) "
                   f"for {what}")
    return fe


def check_model(cfg, arm: str, *, cache_dir=None) -> None:
    """Refuse a model (any arm; the coupled arm with its FE) that cannot be built in this
    machine's memory.

    Called by :func:`phri_spring.workflows.common.model_from_config` before it builds.
    """
    if arm_record(arm).memory.dense:
        _checked_fe(cfg, arm, cache_dir)
        return
    n_rows, n_angles = _size(cfg)
    check(estimate(cfg, arm), what=_elements_text(n_rows, n_angles),
          key=element_key(n_rows, n_angles), advice="expected fewer elements", file=cfg.path)


def preferred_chunk_rows(n_elements: int, chunk_rows: int) -> int:
    """Rows per chunk before memory is considered: the user's hint, capped at about
    :data:`PREFERRED_CHUNK_VALUES` values (fine meshes), and at least
    :data:`PREFERRED_MIN_ROWS` (smaller chunks only cost time)."""
    cap = PREFERRED_CHUNK_VALUES // max(1, n_elements)
    return min(max(PREFERRED_MIN_ROWS, min(int(chunk_rows), cap)), MAX_CHUNK_ROWS)


def check_csv_columns(columns: int, *, what: str, key: str, file=None,
                      parquet: bool = True) -> None:
    """Refuse a CSV table wider than pyarrow's CSV writer can write (``parquet``: whether to
    suggest a Parquet output, which has no such limit)."""
    if columns > CSV_MAX_COLUMNS:
        raise ConfigError(f"{what} make a table of {columns:,} columns; a CSV output holds at "
                          f"most {CSV_MAX_COLUMNS:,} (pyarrow's CSV writer); expected fewer "
                          "elements" + (", or a .parquet output" if parquet else ""),
                          file=file, key=key)


def log_samples(log, columns=None, group: Optional[str] = None) -> Optional[int]:
    """Samples in a log (in the TDMS/MAT ``group`` read): its metadata or a newline count
    (None when unknown)."""
    from ..logs import count_rows

    return count_rows(log, group, columns=columns)


def plan_stream(cfg, arm: str, chunk_rows: int, *, output_format: str, shear: bool = False,
                plot: bool = False, log=None, columns=None, cache_dir=None,
                group: Optional[str] = None) -> int:
    """Rows per chunk for a streamed ``simulate``, or a one-line refusal.

    The preferred chunk (:func:`preferred_chunk_rows`) is taken when it fits;
    otherwise the largest that fits, down to :data:`MIN_CHUNK_ROWS`. Below that
    the model is too large to stream: :class:`ConfigError` naming the element key.

    Raises
    ------
    ConfigError
        The run cannot fit (or its CSV table is too wide for pyarrow).
    """
    n_rows, n_angles = _size(cfg)
    n = n_rows * n_angles
    key = element_key(n_rows, n_angles)
    what = _elements_text(n_rows, n_angles)
    fe = _checked_fe(cfg, arm, cache_dir)
    budget = available_memory()
    want = preferred_chunk_rows(n, chunk_rows)
    samples = None
    if output_format == "parquet" and log is not None:
        # the footer's row groups matter for wide tables on long logs only: count then
        probe = estimate(cfg, arm, want, output_format="parquet", shear=shear,
                         samples=_samples_bound(log))
        if probe.terms.get("row groups", 0) > budget.memory // 100:
            samples = log_samples(log, columns, group)

    def at(rows):
        return estimate(cfg, arm, rows, output_format=output_format, shear=shear, plot=plot,
                        samples=samples, fe=fe)

    rows = _largest_fitting(at, want, budget, samples, shear, output_format, what, key, cfg,
                            arm)
    if output_format == "csv":   # a limit of the writer, not of memory: after the estimate
        parquet = fits(estimate(cfg, arm, MIN_CHUNK_ROWS, output_format="parquet", shear=shear,
                                plot=plot, fe=fe), budget)
        check_csv_columns(1 + (3 if shear else 1) * n + 6, what=what, key=key, file=cfg.path,
                          parquet=parquet)
    return rows


def _largest_fitting(at, want, budget, samples, shear, output_format, what, key, cfg,
                     arm) -> int:
    """The largest rows <= want whose estimate ``at(rows)`` fits; a refusal below
    :data:`MIN_CHUNK_ROWS` (or Parquet's best chunk, see :func:`plan_stream`)."""
    if fits(at(want), budget):
        return want
    low = min(want, MIN_CHUNK_ROWS)
    if samples and output_format == "parquet":
        # fewer rows make more row groups: the total is smallest near sqrt(samples x ratio)
        shear_v = SHEAR_BYTES_PER_VALUE if shear else 0
        per_row = CHUNK_BYTES_PER_VALUE + shear_v + PARQUET_BYTES_PER_CELL
        best = int(math.sqrt(samples * PARQUET_BYTES_PER_COLUMN_CHUNK / per_row))
        low = max(low, min(want, best))
    if not fits(at(low), budget):
        csv_ok = 1 + (3 if shear else 1) * (cfg.n_rows * cfg.angle_count) + 6 <= CSV_MAX_COLUMNS
        advice = "expected fewer elements" + arm_record(arm).memory.advice \
            + (", or a CSV output" if samples and csv_ok else "")
        check(at(low), what=f"{what}, streamed {low:,} samples at a time,", key=key,
              advice=advice, file=cfg.path, budget=budget)
    hi = want
    while hi - low > 1:          # the largest chunk that fits (the terms grow with rows)
        mid = (low + hi) // 2
        if fits(at(mid), budget):
            low = mid
        else:
            hi = mid
    return low


def _samples_bound(log) -> Optional[int]:
    """An upper bound on a log's samples from its size (a CSV row has 14 bytes or more)."""
    try:
        return max(1, os.stat(log).st_size // 14)
    except (OSError, TypeError, ValueError):
        return None


def check_draws(cfg, arm: str, draws: int, *, distinct: bool,
                output_format: Optional[str] = None, rows: Optional[int] = None, log=None,
                columns=None, group: Optional[str] = None) -> None:
    """Refuse Monte Carlo draws whose models and forces cannot fit (``--uncertainty N``).

    ``rows``: samples solved at once for every draw (``compare``'s conditions); default the
    streamed block of ``simulate --uncertainty``, written to ``output_format``.
    """
    n_rows, n_angles = _size(cfg)
    n = n_rows * n_angles
    if output_format == "csv":
        check_csv_columns(1 + 3 * n + 3, what=_elements_text(n_rows, n_angles),
                          key=element_key(n_rows, n_angles), file=cfg.path)
    samples = None
    if output_format == "parquet" and log is not None and n * draws > 10_000:
        samples = log_samples(log, columns, group)
    est = estimate(cfg, arm, output_format=output_format, columns_per_element=3,
                   extra_columns=3, draws=int(draws), distinct_draws=distinct, draw_rows=rows,
                   samples=samples)
    models = "a model each" if distinct else "one model"
    check(est, what=f"{int(draws):,} Monte Carlo draws of {n:,} elements ({models})",
          key="--uncertainty", advice="expected fewer draws", error=DataError)


def design_count(study) -> int:
    """Designs of a study's plan, without making them (a grid: the product of the levels)."""
    if study.plan == "grid":
        return math.prod(max(1, int(p.count) if p.kind == "range" else len(p.levels))
                         for p in study.parameters)
    return int(study.n_samples)


def check_design(study, base, workers: int, load_samples: int = 0) -> None:
    """Refuse a ``phri design`` study whose designs (every design's config is kept for the
    run) and local workers (each evaluates one design over the whole load set at once)
    cannot fit. The one line names what dominates: the plan, the workers, the load set or
    the elements."""
    designs = design_count(study)
    workers = max(0, min(int(workers), designs))
    arm = study.arm
    # the best design's Monte Carlo (``uncertainty.draws``) keeps every drawn config
    draws = int(getattr(study.uncertainty, "draws", 0) or 0)
    est = estimate(base, arm, designs=designs, workers=workers, load_samples=load_samples,
                   draws=draws, draw_rows=1)
    if fits(est):
        return
    n_rows, n_angles = _size(base)
    n = n_rows * n_angles
    t = est.terms
    evaluation = workers * load_samples * n * DESIGN_BYTES_PER_VALUE
    runtime = workers * WORKER_RUNTIME_BYTES
    what = f"{designs:,} designs of {n:,} elements ({workers:,} workers, {load_samples:,} " \
           f"load samples)"
    if t.get("draws", 0) >= max(t["designs"], evaluation, runtime):
        key, file, advice = "uncertainty.draws", study.path, "expected fewer draws"
        what = f"{draws:,} Monte Carlo draws of the best design ({n:,} elements)"
    elif t["designs"] >= max(evaluation, runtime):
        key, file, advice = ("vary" if study.plan == "grid" else "plan"), study.path, \
            "expected fewer designs (fewer levels, or a smaller lhs:N or sobol:N)"
    elif runtime >= evaluation:
        key, file, advice = "--workers", None, "expected fewer workers"
    elif load_samples * DESIGN_BYTES_PER_VALUE > n * 8 * 1024:
        key, file, advice = "loads", study.path, "expected a smaller load set (or a " \
            "merge_tolerance that merges near-identical samples) or fewer workers"
    else:
        key, file, advice = element_key(n_rows, n_angles), base.path, "expected fewer elements"
    check(est, what=what, key=key, advice=advice, file=file, error=DataError)
