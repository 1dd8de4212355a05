"""Figures of ``phri compare`` (the paper's Figs. 7 and 8), as matplotlib ``Figure`` objects.

Only :class:`matplotlib.figure.Figure` is used (never pyplot), so the figures
work in any thread and need no display. Save them with :func:`save_figure`.

- :func:`rmse_bars_figure`  Fig. 7: mean RMSE per condition and arm model,
  error bars = standard error, one panel per experiment and direction.
- :func:`heatmap_figure`    Fig. 8b: measured | rigid | compliant zeroed loads on
  the rows x locations grid, one diverging colour scale centred on zero.
- :func:`wrench_figure`     Fig. 8a: the load-cell wrench of a trial over time,
  with its condition windows shaded.

The heat maps are drawn in :mod:`phri_spring.reports.compare.heatmap`, the shared
style and the reused-figure renderer base live in
:mod:`phri_spring.reports.figure_base`; both are re-exported here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np
from matplotlib.figure import Figure

from .heatmap import HeatmapRenderer, heatmap_figure
from ..figure_base import (ARM_COLORS, ARM_NAMES, DEFAULT_DPI, ReusedFigure, figure_style,
                          fast_png, write_png)

__all__ = ["ARM_COLORS", "ARM_NAMES", "rmse_bars_figure", "heatmap_figure", "wrench_figure",
           "condition_label", "save_figure", "DEFAULT_DPI", "HeatmapRenderer", "render_job",
           "render_figures", "available_cores", "WrenchRenderer", "write_png"]


def condition_label(condition: str, load_n: Optional[float]) -> str:
    """Tick label of a condition: the label and, when known, its load, e.g. ``L2\\n33.4 N``."""
    if load_n is None or not np.isfinite(load_n):
        return str(condition)
    return f"{condition}\n{load_n:.1f} N"


def rmse_bars_figure(summary, rmse=None, *, arms: Sequence[str] = ("rigid", "compliant"),
                     ncols: Optional[int] = None) -> Figure:
    """Fig. 7: grouped bars of the mean RMSE per condition, one bar per arm model compared.

    Parameters
    ----------
    summary : pandas.DataFrame
        ``experiment, direction, condition, arm, mean_rmse_N, se_rmse_N, n_trials``
        and optionally ``load_N`` (the condition's mean load [N], shown in the
        tick labels). The baseline condition should not be in it.
    rmse : pandas.DataFrame, optional
        Per-trial ``experiment, direction, condition, arm, rmse_N``; each trial
        is drawn as a dot over its bar.
    arms : sequence of str
        Arm models to draw, in this order.
    ncols : int, optional
        Panels per row (default 2, or 1 for a single panel).

    Returns
    -------
    matplotlib.figure.Figure
        One axes per (experiment, direction), titled ``"<experiment>, <direction>"``,
        y label ``RMSE [N]``.
    """
    groups = list(dict.fromkeys(zip(summary["experiment"], summary["direction"])))
    if not groups:
        raise ValueError("rmse_bars_figure: the summary is empty")
    n = len(groups)
    ncols = ncols or (1 if n == 1 else 2)
    nrows = int(np.ceil(n / ncols))
    arms = [a for a in arms if a in set(summary["arm"])]
    with figure_style():
        fig = Figure(figsize=(3.7 * ncols, 2.9 * nrows + 0.35), layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False)
        for ax in axes.ravel()[n:]:
            fig.delaxes(ax)
        width = 0.8 / max(len(arms), 1)
        for (exp, direc), ax in zip(groups, axes.ravel()):
            sub = summary[(summary["experiment"] == exp) & (summary["direction"] == direc)]
            conds = list(dict.fromkeys(sub["condition"]))
            x = np.arange(len(conds))
            top = 0.0
            for k, arm in enumerate(arms):
                a = sub[sub["arm"] == arm].set_index("condition")
                mean = np.array([a["mean_rmse_N"].get(c, np.nan) for c in conds], dtype=float)
                se = np.array([a["se_rmse_N"].get(c, np.nan) for c in conds], dtype=float)
                pos = x + (k - (len(arms) - 1) / 2) * width
                ax.bar(pos, mean, width * 0.92, color=ARM_COLORS.get(arm, f"C{k}"),
                       label=ARM_NAMES.get(arm, arm), zorder=2,
                       yerr=np.where(np.isfinite(se), se, 0.0),
                       error_kw={"elinewidth": 1.0, "capsize": 3, "ecolor": "0.15"})
                top = max(top, np.nanmax(np.where(np.isfinite(se), mean + se, mean))
                          if np.isfinite(mean).any() else 0.0)
                if rmse is not None:
                    r = rmse[(rmse["experiment"] == exp) & (rmse["direction"] == direc)
                             & (rmse["arm"] == arm)]
                    for j, c in enumerate(conds):
                        vals = r.loc[r["condition"] == c, "rmse_N"].to_numpy(dtype=float)
                        if vals.size:
                            ax.plot(np.full(vals.size, pos[j]), vals, "o", ms=2.6,
                                    mfc="white", mec="0.1", mew=0.7, zorder=3)
                            top = max(top, float(np.nanmax(vals)))
            if "load_N" in sub.columns:
                loads = sub.drop_duplicates("condition").set_index("condition")["load_N"]
                ticks = [condition_label(c, loads.get(c)) for c in conds]
            else:
                ticks = list(conds)
            ax.set_xticks(x, ticks)
            ax.set_title(f"{exp}, {direc}")
            ax.set_ylabel("RMSE [N]")
            ax.set_ylim(0, top * 1.12 if top > 0 else 1.0)
            ax.grid(axis="y", color="0.88", lw=0.6, zorder=0)
            ax.set_axisbelow(True)
            for side in ("top", "right"):
                ax.spines[side].set_visible(False)
        handles, labels = axes.ravel()[0].get_legend_handles_labels()
        if rmse is not None:
            from matplotlib.lines import Line2D

            handles.append(Line2D([], [], ls="", marker="o", ms=3, mfc="white", mec="0.1"))
            labels.append("trial")
        fig.legend(handles, labels, loc="outside upper center", ncol=len(handles),
                   frameon=False)
    return fig


def wrench_figure(time, wrench, conditions, *, title: str = "",
                  force_unit: str = "N", moment_unit: str = "N*m") -> Figure:
    """Fig. 8a: the load-cell wrench over time with the condition windows shaded.

    Parameters
    ----------
    time : array_like, shape (m,)
        Sample times [s].
    wrench : array_like, shape (m, 6)
        Load-cell readings Fx Fy Fz [force unit], Mx My Mz [moment unit].
    conditions : array_like of str, shape (m,)
        Condition of each sample ('' between windows).
    title : str
    force_unit, moment_unit : str
        Units for the axis labels.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes: forces (x red, y green, z blue) and moments.

    See Also
    --------
    WrenchRenderer : draws many of these into one reused figure.
    """
    return WrenchRenderer(force_unit, moment_unit).fill(time, wrench, conditions, title=title)


class WrenchRenderer(ReusedFigure):
    """Many wrench traces (Fig. 8a) drawn into one figure built once.

    :meth:`fill` changes the lines' data, the shaded windows and their names
    and the title; :meth:`save` reuses the constrained layout of the same
    signature (the widest tick label of each axis). The images are those of
    :func:`wrench_figure` (a test compares them with a reference rendering).
    """

    _COLORS = ("#d62728", "#2ca02c", "#1f77b4")

    def __init__(self, force_unit: str = "N", moment_unit: str = "N*m"):
        with figure_style():
            fig = Figure(figsize=(7.0, 3.9), layout="constrained")
            ax_f, ax_m = fig.subplots(2, 1, sharex=True)
            self.lines = []
            for j, axis in enumerate("xyz"):
                self.lines.append(ax_f.plot([], [], color=self._COLORS[j], lw=0.9,
                                            label=f"F{axis}")[0])
            for j, axis in enumerate("xyz"):
                self.lines.append(ax_m.plot([], [], color=self._COLORS[j], lw=0.9,
                                            label=f"M{axis}")[0])
            ax_f.set_ylabel(f"force [{force_unit}]")
            ax_m.set_ylabel(f"moment [{moment_unit.replace('*', '·')}]")
            ax_m.set_xlabel("time [s]")
            for ax in (ax_f, ax_m):
                ax.legend(loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
                ax.grid(color="0.9", lw=0.6)
                for side in ("top", "right"):
                    ax.spines[side].set_visible(False)
            self.suptitle = fig.suptitle(" ", fontsize=9.5)
            self.suptitle.set_visible(False)
            self.suptitle.set_in_layout(False)
        self.ax_f, self.ax_m = ax_f, ax_m
        self.fig = fig
        self._marks = []          # the shaded windows and their names of the current trace
        self._ready()

    def _label_axes(self):
        return [self.ax_f.yaxis, self.ax_m.yaxis, self.ax_m.xaxis]

    def fill(self, time, wrench, conditions, *, title: str = "") -> Figure:
        """Put one trial's wrench into the figure (see :func:`wrench_figure`); returns it."""
        t = np.asarray(time, dtype=float)
        w = np.asarray(wrench, dtype=float)
        cond = np.asarray(conditions, dtype=object)
        ax_f, ax_m = self.ax_f, self.ax_m
        for mark in self._marks:
            mark.remove()
        self._marks = []
        with figure_style():
            for j, line in enumerate(self.lines):
                line.set_data(t, w[:, j])
            # shade each steady window and name it
            edges = np.flatnonzero(np.r_[True, cond[1:] != cond[:-1]])
            ends = np.r_[edges[1:], len(cond)]
            for k, (s, e) in enumerate(zip(edges, ends)):
                if not cond[s]:
                    continue
                for ax in (ax_f, ax_m):
                    self._marks.append(ax.axvspan(t[s], t[e - 1], color="0.5" if k % 2 else "0.7",
                                                  alpha=0.15, lw=0))
                self._marks.append(ax_f.text(0.5 * (t[s] + t[e - 1]), 1.0, str(cond[s]),
                                             ha="center", va="bottom", fontsize=8,
                                             transform=ax_f.get_xaxis_transform()))
            for ax in (ax_f, ax_m):
                ax.relim()
                ax.autoscale_view()
            self.suptitle.set_text(title or " ")
            self.suptitle.set_visible(bool(title))
            self.suptitle.set_in_layout(bool(title))
        return self.fig


def save_figure(fig: Figure, path, dpi: int = DEFAULT_DPI) -> Path:
    """Write a figure (PNG, PDF or SVG by the extension) without pyplot.

    A PNG is drawn once on a text-caching Agg canvas
    (:mod:`phri_spring.reports.agg_text`) and written by :func:`write_png`:
    the pixels ``Figure.savefig`` writes, without its extra layout pass.
    """
    path = Path(path)
    with figure_style():
        if not fast_png(path):
            fig.savefig(path, dpi=dpi)
            return path
        from ..agg_text import CachedTextCanvas

        old, engine = fig.dpi, fig.get_layout_engine()
        fig.dpi = dpi
        try:
            canvas = CachedTextCanvas(fig)
            if engine is not None:
                # as savefig: the layout computed once, then the figure drawn without it
                engine.execute(fig)
                fig._layout_engine = None
            canvas.draw()
            write_png(path, np.asarray(canvas.buffer_rgba()), dpi)
        finally:
            fig.dpi = old
            fig._layout_engine = engine
    return path


# --------------------------------------------------------------------------- many figures
#: heat-map renderers of this process, by layout (kept between figures and between tasks)
_RENDERERS: dict = {}


def _heatmap_renderer(n_panels: int, row_labels, n_angles: int) -> "HeatmapRenderer":
    key = (int(n_panels), tuple(row_labels), int(n_angles))
    r = _RENDERERS.get(key)
    if r is None:
        r = _RENDERERS[key] = HeatmapRenderer(n_panels, row_labels=row_labels,
                                              n_angles=n_angles)
    return r


def _renderer_for(job) -> "ReusedFigure":
    """This process's renderer for a heat-map or wrench job (built on first use)."""
    kind, _, kw = job
    if kind == "heatmap":
        return _heatmap_renderer(1 + len(kw["simulated"]), kw["row_labels"], kw["n_angles"])
    key = ("wrench", kw.get("force_unit", "N"), kw.get("moment_unit", "N*m"))
    r = _RENDERERS.get(key)
    if r is None:
        r = _RENDERERS[key] = WrenchRenderer(key[1], key[2])
    return r


def render_job(job, dpi: int = DEFAULT_DPI) -> str:
    """Draw and save one figure described by ``job = (kind, path, arguments)``.

    ``kind`` is ``"heatmap"`` (arguments of :func:`heatmap_figure`, drawn by a
    reused :class:`HeatmapRenderer`), ``"layout"`` (a free layout's patches, of
    :func:`~phri_spring.reports.layout_figures.layout_compare_figure`), ``"wrench"``
    (of :func:`wrench_figure`) or ``"bars"`` (of :func:`rmse_bars_figure`). Returns the path written.
    """
    kind, path, kw = job
    kw = dict(kw)
    if kind in ("heatmap", "wrench"):
        r = _renderer_for(job)
        for name in ("row_labels", "n_angles", "force_unit", "moment_unit"):
            kw.pop(name, None)
        if kind == "heatmap":
            r.fill(kw.pop("measured"), kw.pop("simulated"), **kw)
        else:
            r.fill(kw.pop("time"), kw.pop("wrench"), kw.pop("conditions"), **kw)
        r.save(path, dpi)
    elif kind == "layout":
        from ..layout_figures import layout_compare_figure

        save_figure(layout_compare_figure(kw.pop("x"), kw.pop("theta"), kw.pop("width"),
                                          kw.pop("length"), kw.pop("measured"),
                                          kw.pop("simulated"), **kw), path, dpi)
    elif kind == "bars":
        save_figure(rmse_bars_figure(kw.pop("summary"), kw.pop("rmse", None), **kw), path, dpi)
    else:
        raise ValueError(f"render_job: unknown figure kind {kind!r}")
    return str(path)


def _worker_init() -> None:
    import signal

    # an interrupt is the parent's to handle: it stops the pool and cleans up
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def available_cores() -> int:
    """Processors this process may run on."""
    import os

    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def _pool(workers: int):
    """A process pool whose workers are forked from this process (None where fork is missing).

    Forked workers start at once, with matplotlib already imported, and never
    re-import the caller's main script (as spawned ones do, which breaks a
    script without an ``if __name__ == "__main__"`` guard). Where fork is not
    available the figures are drawn in this process.
    """
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    if "fork" not in mp.get_all_start_methods():
        return None
    return ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork"),
                               initializer=_worker_init)


def _submit(pool, *args):
    import warnings

    with warnings.catch_warnings():
        # Python >= 3.12 warns about fork in a process with threads (pyarrow's, the
        # writer's); the workers only draw with matplotlib, which those threads never touch
        warnings.simplefilter("ignore", DeprecationWarning)
        return pool.submit(*args)


def render_figures(jobs, dpi: int = DEFAULT_DPI, *, workers: Optional[int] = None,
                   local=()) -> list:
    """Draw and save many independent figures on the available cores.

    This process draws too (``local`` jobs, which need not be picklable, then
    jobs from the front of the list) while ``workers - 1`` worker processes
    take jobs from the back. A feeder thread hands each worker its next job as
    soon as one of its jobs is done (two are kept queued per worker), so no
    worker waits while this process draws a long figure, and the work is
    shared whatever each figure costs. Every image depends only on its own
    job (the same pixels whichever process draws it), so the output is
    deterministic. The caller writes into a temporary folder (the figures of a
    failed run never land); on an error or an interrupt the pending jobs are
    cancelled and the running ones finished before the error is raised.

    Parameters
    ----------
    jobs : sequence of (kind, path, arguments)
        See :func:`render_job`; the arguments are pickled to the workers.
    dpi : int
        Resolution [dots per inch].
    workers : int, optional
        Processes drawing, this one included (default: the available cores;
        1 draws everything here).
    local : sequence of (kind, path, arguments)
        Jobs drawn in this process only.

    Returns
    -------
    list of str
        The paths written, in the order of ``local`` then ``jobs``.
    """
    import collections

    jobs, local = list(jobs), list(local)
    workers = available_cores() if workers is None else max(1, int(workers))
    workers = min(workers, 1 + len(jobs) // 4)       # a process per few figures at most
    written = [str(j[1]) for j in (*local, *jobs)]
    if workers <= 1:
        for job in (*local, *jobs):
            render_job(job, dpi)
        return written
    # build the renderers before the workers are forked: they inherit them, built once
    for job in jobs:
        if job[0] in ("heatmap", "wrench"):
            _renderer_for(job)
    try:
        pool = _pool(workers - 1)
    except (OSError, ImportError, ValueError):   # no process support here: draw serially
        pool = None
    if pool is None:
        for job in (*local, *jobs):
            render_job(job, dpi)
        return written
    pending = collections.deque(jobs)
    feeder = _Feeder(pool, pending, dpi, queued=2 * (workers - 1))
    try:
        # the first jobs are submitted here, before the feeder thread runs: the pool forks its
        # workers on the first submission, and a fork while another thread runs may copy a
        # lock or a font in mid-use into the child
        feeder.fill()
        feeder.start()
        for job in local:
            render_job(job, dpi)
            feeder.check()
        while True:
            try:
                job = pending.popleft()              # the workers take from the other end
            except IndexError:
                break
            render_job(job, dpi)
            feeder.check()
        feeder.finish()                              # waits for the workers' last jobs
    finally:
        feeder.stop()
        pool.shutdown(wait=True, cancel_futures=True)
    return written


class _Feeder:
    """Keeps ``queued`` jobs from the back of ``pending`` submitted to a pool (a thread).

    :meth:`fill` tops the workers up (call it once before :meth:`start`: the
    first submission forks the workers, which must happen while no other
    thread draws); :meth:`check` raises a worker's error in the caller's
    thread; :meth:`finish` waits for the submitted jobs; :meth:`stop` ends
    the thread and cancels what has not started.
    """

    def __init__(self, pool, pending, dpi: int, queued: int):
        import threading

        self.pool, self.pending, self.dpi, self.queued = pool, pending, dpi, max(1, queued)
        self.inflight = set()
        self.error = None
        self.done = threading.Event()      # every job submitted and finished, or an error
        self.halt = threading.Event()
        self.thread = threading.Thread(target=self._run, name="phri-figure-feeder",
                                       daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _run(self) -> None:
        from concurrent.futures import FIRST_COMPLETED, wait

        try:
            while not self.halt.is_set():
                self.fill()
                if not self.inflight:
                    break                       # nothing left for the workers
                done, _ = wait(self.inflight, timeout=0.2, return_when=FIRST_COMPLETED)
                for fut in done:
                    self.inflight.discard(fut)
                    fut.result()                # a worker's error: stop feeding
        except BaseException as exc:            # noqa: BLE001 - handed to the caller
            self.error = exc
        finally:
            self.done.set()

    def fill(self) -> None:
        """Submit jobs from the back of ``pending`` until ``queued`` are in flight."""
        while len(self.inflight) < self.queued:
            try:
                job = self.pending.pop()
            except IndexError:
                break
            self.inflight.add(_submit(self.pool, render_job, job, self.dpi))

    def check(self) -> None:
        if self.error is not None:
            raise self.error

    def finish(self) -> None:
        while not self.done.wait(0.2):          # short waits: an interrupt is seen at once
            pass
        self.check()

    def stop(self) -> None:
        self.halt.set()
        self.thread.join()
        for fut in self.inflight:
            fut.cancel()
