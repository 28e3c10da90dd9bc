"""The ``hairinv`` command: click commands only.

Arguments become settings, settings go to the library, results go to stage
files. This is the only layer that prints, draws progress bars and chooses
exit codes: 0 success, 1 a run that failed, 2 bad input or usage.
"""

from __future__ import annotations

import functools
import json
import os
import sys
from pathlib import Path

import click

from hairinv import __version__

# Exit codes
OK, FAILED, BAD_INPUT = 0, 1, 2


def _say(ctx_obj, line: str) -> None:
    if not ctx_obj.get("quiet"):
        click.echo(line)


def handle_errors(fn):
    """Turn library errors into one sentence on stderr and an exit code."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from hairinv.errors import HairinvError

        try:
            return fn(*args, **kwargs)
        except HairinvError as exc:
            click.echo(f"hairinv: error: {exc}", err=True)
            sys.exit(exc.exit_code)
        except KeyboardInterrupt:
            click.echo("hairinv: interrupted; no output was written", err=True)
            sys.exit(130)
        except click.exceptions.Exit:
            raise
        except click.ClickException:
            raise
        except Exception as exc:  # an internal failure: one sentence, the traceback only on request
            if os.environ.get("HAIRINV_DEBUG"):
                raise
            click.echo(
                f"hairinv: internal error: {type(exc).__name__}: {exc} (set HAIRINV_DEBUG=1 for the traceback)",
                err=True,
            )
            sys.exit(FAILED)

    return wrapper


class Progress:
    """A tqdm bar on stderr when it is a terminal; silent otherwise."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit="strand", leave=False, file=sys.stderr)

    def __call__(self, n: int) -> None:
        if self.bar is not None:
            self.bar.update(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def import_options(fn):
    """Options shared by every command that reads a hairstyle."""
    options = [
        click.option("--units", type=click.Choice(["auto", "m", "cm", "mm", "in"]), default=None,
                     help="Unit of the hairstyle (and body) file; auto guesses from the size and says so."),
        click.option("--scale", type=float, default=None,
                     help="Metres per file unit, for odd units (overrides --units), e.g. 0.00254."),
        click.option("--up", type=click.Choice(["auto", "x", "y", "z"]), default=None,
                     help="World up axis of the file; gravity is along -up. auto uses the format's convention."),
        click.option("--flip", default=None, metavar="AXES",
                     help="Axes to negate on import, e.g. z for a left-handed export."),
        click.option("--guides", type=click.IntRange(min=0), default=None,
                     help="Keep N guide strands, a seeded random subset spread evenly over the scalp."),
        click.option("--seed", type=int, default=None, help="Seed of the guide selection."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def settings_options(fn):
    """--quality, --config and --set."""
    options = [
        click.option("--quality", type=click.Choice(["draft", "default", "final"]), default="default",
                     show_default=True, help="Preset trading speed for accuracy (configs/quality/)."),
        click.option("--config", "config_file", type=click.Path(dir_okay=False), default=None,
                     help="TOML settings file ([import], [fit], ...)."),
        click.option("--set", "sets", multiple=True, metavar="SECTION.KEY=VALUE",
                     help="Override one setting, e.g. --set fit.tolerance=1e-4 (repeatable)."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def _import_extra(units, scale, up, flip, guides, seed) -> dict:
    values = {"units": units, "scale": scale, "up": up, "flip": flip, "guides": guides, "seed": seed}
    return {k: v for k, v in values.items() if v is not None}


def _default_output(source: Path, suffix: str) -> Path:
    """``./<name>.<suffix>.h5``: the input's name without its extension (and,
    for a stage file, without its stage suffix such as ``.fit``)."""
    stem = source.stem
    if source.suffix.lower() in (".h5", ".hdf5"):
        for known in (".fit", ".contacts", ".model", ".frames"):
            stem = stem.removesuffix(known)
    return Path.cwd() / f"{stem}.{suffix}.h5"


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="hairinv")
@click.option("-q", "--quiet", is_flag=True, help="Print only errors.")
@click.option("--no-progress", is_flag=True, help="Never draw progress bars.")
@click.pass_context
def main(ctx, quiet, no_progress):
    """Inverse dynamic hair modeling with frictional contact.

    Stages read and write HDF5 stage files: fit (curves to super-helices),
    then the later stages as they become available. `hairinv info FILE.h5`
    summarises any stage file.
    """
    ctx.ensure_object(dict)
    ctx.obj["quiet"] = quiet
    ctx.obj["progress"] = not no_progress and not quiet


@main.command()
@click.argument("curves", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Output stage file [default: ./<name>.fit.h5].")
@import_options
@click.option("--tolerance", type=float, default=None,
              help="Fit tolerance in metres: largest vertex distance the adaptive fit aims for.")
@click.option("--elements", type=click.IntRange(min=1), default=None,
              help="Fixed number of elements per strand (default: adaptive from the tolerance).")
@settings_options
@click.pass_obj
@handle_errors
def fit(obj, curves, output, units, scale, up, flip, guides, seed, tolerance, elements, quality, config_file, sets):
    """Fit every strand of CURVES with a G1 chain of super-helices.

    CURVES is any supported hairstyle file: Yuksel .hair, USC .data,
    TressFX .tfx (v2 ASCII, v3 and v4 binary), OBJ polylines, USD
    BasisCurves, or a hairinv .h5 file. Writes /curves and /helices.
    """
    from hairinv import config, stages
    from hairinv.fit import fit_groom
    from hairinv.groom import load_groom

    settings = config.resolve(quality, config_file, sets)
    settings = config.apply(settings, {"import": _import_extra(units, scale, up, flip, guides, seed)}, "command line")
    fit_extra = {}
    if tolerance is not None:
        fit_extra["tolerance"] = tolerance
    if elements is not None:
        fit_extra["elements"] = elements
    settings = config.apply(settings, {"fit": fit_extra}, "command line")
    output = output or _default_output(curves, "fit")
    stages.check_output_path(output, inputs=[curves])
    groom, report = load_groom(curves, settings.import_)
    for line in report.lines():
        _say(obj, line)
    progress = Progress(groom.n_strands, "fit", obj["progress"])
    try:
        helices, fit_report = fit_groom(groom, settings.fit, progress=progress)
    finally:
        progress.close()
    for line in fit_report.lines():
        _say(obj, line)
    inputs = [stages.file_record(curves)]
    stages.write_stage(
        output,
        [groom.curves_group(settings.import_, inputs), helices.group(settings.fit, inputs)],
        "fit",
    )
    _say(obj, f"wrote {output}")


@main.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@handle_errors
def info(file, as_json):
    """Summarise a hairinv stage file: groups, sizes and key figures."""
    from hairinv.errors import InputError
    from hairinv.summary import summarise
    from hairinv import stages

    if not file.exists():
        raise InputError("no such file", file)
    summary = summarise(stages.read_stage(file))
    if as_json:
        click.echo(json.dumps(summary, indent=2))
        return
    click.echo(f"{file}: {summary['producer']}, schema {summary['schema_version']}, stages {summary['stages']}")
    for name, group in summary["groups"].items():
        click.echo(f"/{name}")
        for key, value in group.items():
            click.echo(f"  {key}: {value}")


if __name__ == "__main__":
    main()
