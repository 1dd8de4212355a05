"""``phri live``: the predicted pressure map while the experiment runs (docs/live.md)."""

from __future__ import annotations

import math
import sys

import click

from ._common import ArmChoice, info, progress_enabled


@click.command("live", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("config", metavar="CONFIG")
@click.option("--source", "source", required=True, metavar="SRC",
              help="- (CSV lines time,Fx,Fy,Fz,Mx,My,Mz on standard input, a header line "
                   "first allowed) | netft:HOST[:PORT] (ATI Net F/T, RDT over UDP, port "
                   "49152) | lsl:NAME (a Lab Streaming Layer stream of 6 channels; needs "
                   "the live extra).")
@click.option("--arm", type=ArmChoice(), default="compliant", show_default=True,
              help="compliant, rigid or coupled (as in phri simulate).")
@click.option("-o", "--out", "output", default=None, metavar="FILE",
              help="Forces table (.csv or .parquet), the columns of phri simulate, streamed "
                   "to disk and completed when the run ends (also on Ctrl-C).")
@click.option("--lsl-out", default=None, metavar="NAME",
              help="LSL outlet NAME: one channel per element force [N], the peak pressure "
                   "ratio and the contacts in touch, stamped with the input sample's time; "
                   "alarms and gaps on NAME-markers. Needs the live extra.")
@click.option("--dashboard", default=None, metavar="[HOST:]PORT",
              help="A local web page of the pressure map, heat map, peak ratio, alarm, "
                   "wrench and stream health, at http://HOST:PORT/ (HOST 127.0.0.1 unless "
                   "given; PORT 0: a free port). Updated at up to 25 Hz (server-sent events).")
@click.option("--baseline", default="none", show_default=True, metavar="SPEC",
              help="none | zero | first:SECONDS (the stream's first seconds, held until they "
                   "have passed) | window:T0:T1, as in phri simulate.")
@click.option("--alarm", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="RATIO",
              help="A line on stderr when the peak pressure / pain threshold reaches RATIO, "
                   "and one when it has come back below the clear level (--alarm-clear) and "
                   "has been raised for --alarm-hold seconds: a ratio dithering at RATIO "
                   "raises it once.")
@click.option("--alarm-clear", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="RATIO",
              help="The ratio below which the alarm clears, at most --alarm.  [default: 0.9 "
                   "times --alarm]")
@click.option("--alarm-hold", type=click.FloatRange(min=0), default=0.5, show_default=True,
              metavar="S",
              help="Shortest time [s] (of the stream's clock) the alarm stays raised; 0 with "
                   "--alarm-clear equal to --alarm: no hysteresis.")
@click.option("--tolerance", default=None, metavar="CURVE",
              help="Follow every element's dose against a pressure-time curve "
                   "(docs/tolerance.md); the table gets dose_max and dose_element. "
                   "Default: the config's tolerance.curve, else none.")
@click.option("--dose-alarm", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="DOSE",
              help="A line (and an LSL marker) when the largest dose reaches DOSE (1 = the "
                   "curve's limit); a dose never goes down, so it stays raised. Needs a curve.")
@click.option("--duration", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="S", help="Stop after S seconds [s].")
@click.option("--max-samples", type=click.IntRange(min=1), default=None, metavar="N",
              help="Stop after N samples.")
@click.option("--column", "columns", multiple=True, metavar="NAME=STREAM_NAME",
              help="Map a spec column (time, Fx, ..., Mz; optional activation, 0..1, from a "
                   "CSV header on standard input: docs/model.md section 15) to the header's or "
                   "LSL channel's name; overrides load_cell.columns.")
@click.option("--counts-per-force", type=float, default=1e6, show_default=True,
              help="netft: the box's counts per unit force (its calibration page).")
@click.option("--counts-per-torque", type=float, default=1e6, show_default=True,
              help="netft: the box's counts per unit torque.")
@click.option("--stall-timeout", type=click.FloatRange(min=0.05), default=1.0,
              show_default=True, metavar="S",
              help="Silence [s] after which the stream is reported stopped (a Net F/T is "
                   "then asked to start again, every S seconds).")
@click.option("--decimals", type=click.IntRange(min=-1, max=17), default=6, show_default=True,
              help="CSV output: decimals of forces and pressures; -1 keeps every digit.")
@click.option("--progress/--no-progress", default=None,
              help="A status line on stderr (default: only when stderr is a terminal).")
@click.option("-q", "--quiet", is_flag=True, help="No summary line.")
def live(config, source, arm, output, lsl_out, dashboard, baseline, alarm, alarm_clear,
         alarm_hold, duration, max_samples, columns, counts_per_force, counts_per_torque,
         stall_timeout, decimals, progress, quiet, tolerance=None, dose_alarm=None):
    """Predict the force on every cuff element for each sample of a live wrench stream.

    Every sample goes through CONFIG's model (single-sample solver, warm-started)
    as soon as it arrives. Stops at the end of the stream (standard input), after
    --duration or --max-samples, or on Ctrl-C/SIGTERM (exit 130/143, outputs
    complete).

    \b
    Examples:
      phri live configs/harmony_upper_arm.yaml --source - -o forces.csv < log.csv
      phri live CONFIG --source netft:192.168.1.1 --lsl-out cuff --alarm 0.8
      phri live CONFIG --source lsl:ForceTorque --out run.parquet --baseline first:2
    """
    from phri_spring.workflows.live import check_alarm_settings
    from phri_spring.workflows.simulate import parse_baseline

    base = parse_baseline(baseline)
    check_alarm_settings(alarm, alarm_clear, alarm_hold)
    if tolerance is not None:
        from phri_spring.io.config.tolerance import curve_option

        curve_option(tolerance)          # an unknown name is refused before anything opens
    dash = None
    if dashboard is not None:
        from phri_spring.io.live.dashboard import LiveDashboard, parse_address

        dash = LiveDashboard(*parse_address(dashboard))       # bound now: a port in use fails here
    try:
        _live(config, source, arm, output, lsl_out, dash, base, (alarm, alarm_clear, alarm_hold),
              duration, max_samples,
              columns, counts_per_force, counts_per_torque, stall_timeout, decimals, progress,
              quiet, (tolerance, dose_alarm))
    finally:
        if dash is not None:
            dash.close()


def _live(config, source, arm, output, lsl_out, dash, base, alarm_settings, duration,
          max_samples, columns, counts_per_force, counts_per_torque, stall_timeout, decimals,
          progress, quiet, dose_settings=(None, None)):
    from phri_spring.errors import UsageError
    from phri_spring.io.config import load_config
    from phri_spring.io.live.sources import import_pylsl, make_source
    from phri_spring.io.logs import parse_column_map, reader_options
    from phri_spring.workflows.live import LiveRun

    alarm, alarm_clear, alarm_hold = alarm_settings
    colmap = parse_column_map(columns)
    if lsl_out is not None:
        if not lsl_out.strip():
            raise UsageError("expected a stream name", key="--lsl-out")
        import_pylsl("--lsl-out")
    cfg = load_config(config)
    colmap, _ = reader_options(cfg, colmap, None)
    src = make_source(source, stdin=click.get_binary_stream("stdin"), columns=colmap,
                      counts_per_force=counts_per_force, counts_per_torque=counts_per_torque,
                      stall_timeout=stall_timeout)
    status_on = progress_enabled(progress)

    def notify(line: str) -> None:
        if status_on:
            sys.stderr.write("\r\033[K")
        click.echo(f"live: {line}", err=True)

    def status(health, max_ratio) -> None:
        peak = f", peak ratio {max_ratio:.3f}" if math.isfinite(max_ratio) else ""
        sys.stderr.write(f"\rlive: {health.samples:,} samples, {health.rate_hz:.0f} Hz, "
                         f"lost {health.lost:,}, malformed {health.malformed:,}{peak}\033[K")
        sys.stderr.flush()

    run = LiveRun(cfg, src, arm=arm, baseline=base, output=output, decimals=decimals,
                  lsl_out=lsl_out, alarm=alarm, alarm_clear=alarm_clear, alarm_hold=alarm_hold,
                  duration=duration, max_samples=max_samples,
                  notify=notify, tolerance=dose_settings[0], dose_alarm=dose_settings[1])
    if dash is not None:
        from phri_spring.workflows.plots.section import live_section_meta

        dash.set_layout(run.labels, cfg.row_labels, cfg.angle_count, alarm=alarm,
                        tolerance=None if run.curve is None else run.curve.name,
                        dose_alarm=dose_settings[1],
                        title=f"phri live: {cfg.path.name if cfg.path else 'config'}, {arm} arm, "
                              f"source {source}",
                        section=live_section_meta(cfg, cfg.geometry()))
        run.subscribe(dash.observe)
        dash.start()
        notify(f"dashboard on {dash.url}")
    try:
        summary = run.run(status=status if status_on else None)
    finally:
        if status_on:
            sys.stderr.write("\r\033[K")
            sys.stderr.flush()
    info(summary_line(summary, arm, base), quiet)
    if summary.signum is not None:
        sys.exit(128 + summary.signum)


def summary_line(summary, arm: str, baseline) -> str:
    """The line a live run ends with: counts, peak ratio, alarms, what was written."""
    import signal

    if summary.samples:
        peak = (f"peak pressure ratio {summary.max_ratio:.4g} at t = "
                f"{summary.max_ratio_time:g} s ({summary.max_ratio_element})"
                if math.isfinite(summary.max_ratio) else "no converged sample")
    else:
        peak = "no sample received"
    why = {"end": "end of stream", "duration": "duration reached",
           "max-samples": "sample count reached", "stop": "stopped"}.get(summary.stopped_by)
    if summary.signum is not None:
        try:
            why = f"interrupted ({signal.Signals(summary.signum).name})"
        except ValueError:
            why = f"interrupted (signal {summary.signum})"
    wrote = (f"; wrote {summary.output}" if summary.output is not None
             else "; nothing written" if not summary.samples else "")
    gaps = len(summary.gaps)
    nc = (f", {summary.not_converged:,} not converged (NaN)" if summary.not_converged else "")
    return (f"live: {summary.samples:,} samples from {summary.source} ({arm} arm, baseline "
            f"{baseline}), lost {summary.lost:,}, malformed {summary.malformed:,}, "
            f"gaps {gaps}{nc}; {peak}; alarms {summary.alarms}{_dose_text(summary)}; "
            f"{why}{wrote}")


def _dose_text(summary) -> str:
    """The summary's clause on the dose (nothing without a tolerance curve)."""
    ex = getattr(summary, "exposure", None)
    if ex is None or not summary.samples:
        return ""
    j, dose = ex.worst()
    return f"; dose ({ex.curve.name}) max {dose:.3g}, dose alarms {summary.dose_alarms}"
