"""``phri init``: write a commented starter config (and the example wrench log)."""

from __future__ import annotations

from pathlib import Path

import click

from ._common import info


@click.command("init", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("file", metavar="FILE", required=False)
@click.option("--preset", default=None, metavar="NAME",
              help="Bundled preset to start from (default: harmony_upper_arm, the paper's "
                   "upper-arm cuff); --list shows them all.")
@click.option("--list", "list_presets", is_flag=True,
              help="List the bundled presets and what each models, then exit.")
@click.option("--example", default=None, metavar="DIR",
              help="Also write the bundled example wrench log (SYNTHETIC, horizontal "
                   "loading) as DIR/wrench_log.csv (DIR made if missing).")
@click.option("--force", is_flag=True, help="Replace FILE (and DIR/wrench_log.csv) if it exists.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing on success.")
def init(file, preset, list_presets, example, force, quiet):
    """Write a starter config FILE from a bundled preset, with comments on every key.

    The comments give each key's unit and where its value comes from ([paper],
    [literature] or [assumption]: replace those with your own). An existing FILE
    is never replaced without --force (exit status 2). The presets ship inside
    the package, so this works from any installed copy.

    \b
    Examples:
      phri init --list
      phri init cuff.yaml --example .
      phri simulate cuff.yaml wrench_log.csv -o forces.csv
      phri init --preset human_forearm forearm.yaml
    """
    from importlib.metadata import PackageNotFoundError, version

    from phri_spring.errors import UsageError
    from phri_spring.io.presets import DEFAULT_PRESET, preset_names, preset_title

    if list_presets:
        if file is not None or preset is not None or example is not None:
            raise UsageError("--list writes nothing; expected it alone", key="--list")
        for name in preset_names():
            mark = "  (default)" if name == DEFAULT_PRESET else ""
            click.echo(f"{name:<20} {preset_title(name)}{mark}")
        return
    if file is None and preset is not None:
        raise UsageError("--preset NAME needs the config FILE to write", key="--preset")
    if file is None and example is None:
        raise UsageError("expected a config FILE to write (or --example DIR, or --list)",
                         key="FILE")
    try:
        release = version("phri-spring")
    except PackageNotFoundError:  # pragma: no cover - run from a checkout never installed
        release = None
    from phri_spring.io.presets import check_starter_path, preset_text, write_starter_config
    from phri_spring.workflows.starter import check_example_folder, write_example_log

    name = preset or DEFAULT_PRESET
    # every refusal before anything is written
    preset_text(name)
    if file is not None:
        check_starter_path(file, force)
    if example is not None:
        log = check_example_folder(example, force)
        if file is not None and Path(file).resolve() == log.resolve():
            raise UsageError(f"FILE {file!r} is where --example writes the example log; "
                             "expected another name", key="FILE")
    if file is not None:
        written = write_starter_config(file, name, force=force, version=release)
        info(f"wrote {written} (preset {name})", quiet)
    if example is not None:
        log = write_example_log(example, force=force)
        info(f"wrote {log} (example wrench log, SYNTHETIC)", quiet)
