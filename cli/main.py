"""The ``hairinv`` command: click commands only.

Arguments become settings, settings go to the library, results go to stage
files. This is the only layer that prints, draws progress bars and chooses
exit codes: 0 success, 1 a run that failed, 2 bad input or usage, 130 interrupted (Ctrl-C), 143 terminated
(SIGTERM, as farm managers stop a task).
"""

from __future__ import annotations

import functools
import json
import os
import signal
import sys
import time
from pathlib import Path

import click

from hairinv import __version__

from ._memory import keep_freed_memory

# Exit codes (130, 143: 128 + SIGINT, SIGTERM, as shells report a job stopped by Ctrl-C or by a farm manager)
OK, FAILED, BAD_INPUT, INTERRUPTED, TERMINATED = 0, 1, 2, 130, 143


#: --log-json: one JSON object per event on stderr (set once the options are read; one command per process)
LOG_JSON = {"on": False}


def _event(kind: str, **fields) -> None:
    """With --log-json: one JSON object on one line of stderr, flushed: ``{"event": kind, "time": ..., ...}``."""
    if not LOG_JSON["on"]:
        return
    record = {"event": kind, "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), **fields}
    print(json.dumps(record, default=str), file=sys.stderr, flush=True)


def _say(ctx_obj, line: str) -> None:
    if LOG_JSON["on"]:
        _event("warning" if line.lstrip().startswith("warning") else "message", text=line)
    if ctx_obj.get("quiet"):
        return
    try:
        click.echo(line)
    except BrokenPipeError:
        # the reader went away (``hairinv ... | head``): stop printing, finish the job
        ctx_obj["quiet"] = True
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def _say_settings(ctx_obj, settings, *sections: str) -> None:
    """With -v: the settings in effect, one line per section the command uses."""
    if not ctx_obj.get("verbose") or ctx_obj.get("quiet"):
        return
    values = settings.to_dict()
    _say(ctx_obj, "settings in effect (defaults, preset, --config, --set and options applied):")
    for section in sections:
        _say(ctx_obj, f"  [{section}] " + ", ".join(f"{key} = {value!r}" for key, value in values[section].items()))


def _say_timings(ctx_obj, timings: dict) -> None:
    """With -v: the seconds of each stage run, and of the whole command (reading, checks, writing included)."""
    if not ctx_obj.get("verbose") or ctx_obj.get("quiet"):
        return
    parts = [f"{stage} {seconds:.3g} s" for stage, seconds in timings.items()]
    parts.append(f"whole command {time.perf_counter() - ctx_obj.get('started', time.perf_counter()):.3g} s")
    _say(ctx_obj, "timings: " + ", ".join(parts))


#: Whether this process received Ctrl-C (SIGINT) or SIGTERM (:func:`_on_interrupt`), and which. Where the
#: KeyboardInterrupt cannot propagate (numba compiling a kernel calls back into Python through ctypes, which
#: drops it), the command still ends as interrupted, not with the error that may follow nor as a success.
INTERRUPT = {"received": False, "signal": signal.SIGINT}


def _on_interrupt(signum, frame):
    """SIGINT or SIGTERM: note it, and raise KeyboardInterrupt as Python's own handler does for SIGINT (a farm
    manager stopping a task sends SIGTERM: it keeps what Ctrl-C keeps)."""
    INTERRUPT["received"] = True
    INTERRUPT["signal"] = signum
    raise KeyboardInterrupt


def _quiet_unraisable(default):
    """A ``sys.unraisablehook`` that says nothing of a KeyboardInterrupt raised where Python cannot pass it on
    (a ctypes callback): the command's one line says it was interrupted."""
    def hook(unraisable):
        if issubclass(unraisable.exc_type, KeyboardInterrupt):
            INTERRUPT["received"] = True
            return
        default(unraisable)
    hook.quiet_interrupts = True
    return hook


def _quiet_excepthook(default):
    """A ``sys.excepthook`` that prints no traceback of a KeyboardInterrupt: a compiled module that fails to
    import prints its error so (numpy's ``import_array``), then raises an ImportError the command reports."""
    def hook(kind, value, traceback):
        if issubclass(kind, KeyboardInterrupt):
            INTERRUPT["received"] = True
            return
        default(kind, value, traceback)
    hook.quiet_interrupts = True
    return hook


def _catch_interrupts() -> None:
    """Route Ctrl-C through :func:`_on_interrupt` (in the main thread, where signals are handled), and keep
    the tracebacks of interrupts that libraries print instead of raising off stderr."""
    INTERRUPT["received"] = False
    INTERRUPT["signal"] = signal.SIGINT
    try:
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _on_interrupt)
        if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
            signal.signal(signal.SIGTERM, _on_interrupt)
    except ValueError:  # not the main thread (a test's runner): Python's own handlers stay
        return
    if not getattr(sys.unraisablehook, "quiet_interrupts", False):
        sys.unraisablehook = _quiet_unraisable(sys.unraisablehook)
    if not getattr(sys.excepthook, "quiet_interrupts", False):
        sys.excepthook = _quiet_excepthook(sys.excepthook)


def handle_errors(fn):
    """Turn library errors into one sentence on stderr and an exit code."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from hairinv.errors import HairinvError

        started = time.perf_counter()
        _event("start", command=fn.__name__, argv=sys.argv[1:])
        code = OK

        def interrupted(line: str = "interrupted; no output was written"):
            nonlocal code
            code = INTERRUPTED
            if INTERRUPT["signal"] == signal.SIGTERM:
                code = TERMINATED
                line = line.replace("interrupted", "terminated (SIGTERM)", 1)
            _event("error", text=line, exit=code)
            click.echo(f"hairinv: {line}", err=True)
            sys.exit(code)

        _catch_interrupts()
        try:
            result = fn(*args, **kwargs)
            if INTERRUPT["received"]:  # swallowed where Python cannot raise it (numba compiling: a ctypes callback)
                interrupted("interrupted, but Ctrl-C came where it could not stop the command (in compiled code): "
                            "it ran to its end, and what it wrote is complete")
            return result
        except HairinvError as exc:
            if INTERRUPT["received"]:  # the error of a library that swallowed Ctrl-C
                interrupted()
            _event("error", text=str(exc), exit=exc.exit_code)
            click.echo(f"hairinv: error: {exc}", err=True)
            code = exc.exit_code
            sys.exit(exc.exit_code)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else FAILED
            raise
        except KeyboardInterrupt as exc:
            # Ctrl-C: what the command kept (``simulate``: the frames done), else that nothing was written
            interrupted(getattr(exc, "kept", None) or "interrupted; no output was written")
        except click.exceptions.Exit:
            raise
        except click.ClickException:
            raise
        except Exception as exc:  # an internal failure: one sentence, the traceback only on request
            if INTERRUPT["received"]:  # the error of a library that swallowed Ctrl-C
                interrupted()
            if os.environ.get("HAIRINV_DEBUG"):
                raise
            _event("error", text=f"internal error: {type(exc).__name__}: {exc}", exit=FAILED)
            click.echo(
                f"hairinv: internal error: {type(exc).__name__}: {exc} (set HAIRINV_DEBUG=1 for the traceback)",
                err=True,
            )
            code = FAILED
            sys.exit(FAILED)
        finally:
            _event("end", command=fn.__name__, exit=code, seconds=round(time.perf_counter() - started, 3))

    return wrapper


#: s between two plain progress lines when stderr is not a terminal (a farm's or CI's log);
#: ``HAIRINV_PROGRESS_SECONDS`` overrides it (0: a line at every update)
PLAIN_PROGRESS_SECONDS = 5.0


class Progress:
    """A tqdm bar on stderr when it is a terminal; otherwise a plain line at most every
    :data:`PLAIN_PROGRESS_SECONDS`, ``stage: N of M units (P %)``, flushed, for software that parses logs."""

    def __init__(self, total: int, desc: str, enabled: bool, unit: str = "strand"):
        self.bar = None
        self.plain = False
        self.total, self.desc, self.unit, self.n, self.extra = int(total), desc, unit, 0, ""
        if LOG_JSON["on"]:  # progress as events, at the plain lines' pace
            enabled = True
            self.every = self._every()
            self.last = time.monotonic()
            self.plain = True
        elif enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=desc, unit=unit, leave=False, file=sys.stderr)
        elif enabled:
            self.plain = True
            self.every = self._every()
            self.last = time.monotonic()

    @staticmethod
    def _every() -> float:
        try:
            return max(0.0, float(os.environ.get("HAIRINV_PROGRESS_SECONDS", PLAIN_PROGRESS_SECONDS)))
        except ValueError:
            return PLAIN_PROGRESS_SECONDS

    def __call__(self, n: int = 1) -> None:
        if self.bar is not None:
            self.bar.update(n)
        self._advance(self.n + n)

    def _advance(self, n: int) -> None:
        self.n = n
        if self.plain and time.monotonic() - self.last >= self.every:
            self.last = time.monotonic()
            if LOG_JSON["on"]:
                _event("progress", stage=self.desc, done=self.n, total=self.total, unit=self.unit,
                       percent=round(100.0 * self.n / self.total, 1) if self.total > 0 else None,
                       detail=self.extra.lstrip(", ") or None)
                return
            share = f" ({100.0 * self.n / self.total:.0f} %)" if self.total > 0 else ""
            print(f"{self.desc}: {self.n} of {self.total} {self.unit}s{share}{self.extra}", file=sys.stderr,
                  flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


class FiniteFloat(click.ParamType):
    """A finite number (``nan``, ``inf`` are refused as usage errors, exit 2); its range is checked where it
    is used (:data:`hairinv.config.SETTING_RANGE`, :func:`hairinv.dynamics.scene.check_run_length`)."""

    name = "number"

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            return value
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if number != number or number in (float("inf"), float("-inf")):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number


class Length(click.ParamType):
    """A length in metres, written with its unit (``0.2mm``, ``4 mm``, ``1e-4m``) or as a bare number of
    metres: the rule of every length setting (:func:`hairinv.config.parse_length`); its setting's range
    then judges its size and sign."""

    name = "length"

    def convert(self, value, param, ctx):
        from hairinv.config import parse_length
        from hairinv.errors import InputError

        if isinstance(value, float):
            return value
        try:
            # a length written right but not > 0 goes on to its setting's range, whose refusal names the
            # setting in one sentence; what is not a finite length at all is a usage error here
            return parse_length(str(value), "length", bare_metres=True, positive=False)
        except InputError as error:
            self.fail(error.message.removeprefix("length: "), param, ctx)


FINITE, LENGTH = FiniteFloat(), Length()


def import_options(fn):
    """Options shared by every command that reads a hairstyle."""
    options = [
        click.option("--units", type=click.Choice(["auto", "m", "cm", "mm", "in"]), default=None,
                     help="Unit of the hairstyle (and body) file; auto guesses from the size and says so."),
        click.option("--scale", type=FINITE, default=None,
                     help="Metres per file unit, for odd units (overrides --units), e.g. 0.00254."),
        click.option("--up", type=click.Choice(["auto", "x", "y", "z"]), default=None,
                     help="World up axis of the file; gravity is along -up. auto uses the format's convention."),
        click.option("--flip", default=None, metavar="AXES",
                     help="Axes to negate on import, e.g. z for a left-handed export."),
        click.option("--guides", type=click.IntRange(min=0), default=None,
                     help="Keep N guide strands, a seeded random subset spread evenly over the scalp "
                          "[import.guides; default: every strand, as 0 also says]."),
        click.option("--seed", type=int, default=None,
                     help="Seed of the guide selection: the same seed picks the same strands [import.seed; "
                          "default 0]."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def body_options(fn):
    """--body-units, --body-scale, --body-up and --body-flip: the body file's own unit and axes, and --bind-time
    and --body-rest: the pose of an animated body the groom was made on ([body]), passed on as one
    ``body_frame`` dict of the options given."""
    @functools.wraps(fn)
    def with_body_frame(*args, body_units=None, body_scale=None, body_up=None, body_flip=None, bind_time=None,
                        body_rest=None, **kwargs):
        values = {"units": body_units, "scale": body_scale, "up": body_up, "flip": body_flip,
                  "bind_time": bind_time, "rest_mesh": body_rest}
        return fn(*args, body_frame={k: v for k, v in values.items() if v is not None}, **kwargs)

    options = [
        click.option("--body-units", type=click.Choice(["hair", "auto", "m", "cm", "mm", "in"]), default=None,
                     help="Unit of the body file when it is not the hair's: a groom in cm on a head in m "
                          "[body.units, default hair]."),
        click.option("--body-scale", type=FINITE, default=None,
                     help="Metres per body file unit (overrides --body-units) [body.scale]."),
        click.option("--body-up", type=click.Choice(["hair", "x", "y", "z"]), default=None,
                     help="Up axis of the body file when it is not the hair's: the body is turned onto the "
                          "hair's up [body.up, default hair]."),
        click.option("--body-flip", default=None, metavar="AXES|none",
                     help="Axes of the body file to negate, or none [body.flip, default: the hair's --flip]."),
        click.option("--bind-time", default=None, metavar="SECONDS|rest",
                     help="An animated body's pose the groom was made on: a time of its animation, from its start "
                          "[body.bind_time; default rest: the pose its file stores, a skinned mesh's bind pose]. "
                          "simulate and verify take the one the model was inverted on."),
        click.option("--body-rest", default=None, metavar="FILE",
                     help="A mesh of the animated body in the pose the groom was made on: its vertices in the same "
                          "order, in the body file's units and axes [body.rest_mesh]."),
    ]
    for option in reversed(options):
        with_body_frame = option(with_body_frame)
    return with_body_frame


def if_stale_option(fn):
    """--if-stale: do nothing when the output is current (hairinv.staleness)."""
    return click.option("--if-stale", "if_stale", is_flag=True,
                        help="Do nothing (exit 0) when the output is current: made by this command from inputs "
                             "with the same contents, with the same settings and options.")(fn)


def _up_to_date(obj, if_stale: bool, output: Path, record: dict, check=None) -> bool:
    """With --if-stale: True (and the output's time set to now, for make) when ``output`` is current for
    ``record`` (by ``check``, default :func:`hairinv.staleness.check_current`); else say why it is made
    again."""
    from hairinv.staleness import check_current, mark_current

    if not if_stale:
        return False
    current, reasons = (check or check_current)(output, record)
    if current:
        mark_current(output)
        _say(obj, f"{output} is current (the same inputs, settings and options): nothing to do")
        return True
    if Path(output).exists():
        _say(obj, f"{output} is stale: " + "; ".join(reasons))
    return False


def settings_options(fn=None, *, example: str = "fit.tolerance=0.1mm"):
    """--quality, --config and --set (``example``: a setting the command uses)."""
    if fn is None:
        return functools.partial(settings_options, example=example)
    options = [
        click.option("--quality", type=click.Choice(["draft", "default", "final"]), default="default",
                     show_default=True, help="Preset trading speed for accuracy (configs/quality/)."),
        click.option("--config", "config_file", type=click.Path(dir_okay=False), default=None,
                     help="TOML settings file ([import], [fit], ...)."),
        click.option("--set", "sets", multiple=True, metavar="SECTION.KEY=VALUE",
                     help=f"Override one setting, e.g. --set {example} (repeatable); lengths take a unit "
                          "or are metres."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def _import_extra(units, scale, up, flip, guides, seed) -> dict:
    values = {"units": units, "scale": scale, "up": up, "flip": flip, "guides": guides, "seed": seed}
    return {k: v for k, v in values.items() if v is not None}


def _pipeline_record(subcommand: str, style: Path, body: Path | None, settings, sections) -> dict:
    """The command record (hairinv.staleness) of a run on STYLE and BODY; missing files are refused first."""
    from hairinv.errors import InputError
    from hairinv.staleness import command_record

    for path in (style, body):
        if path is not None and not Path(path).exists():
            raise InputError("no such file", path)
    return command_record(subcommand, [style, body], settings, sections)


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
@click.option("-v", "--verbose", is_flag=True, help="Also print the settings in effect and each stage's time.")
@click.option("--no-progress", is_flag=True, help="Never draw progress bars.")
@click.option("--log-json", is_flag=True,
              help="Also write one JSON object per event (start, message, warning, progress, error, end) to stderr.")
@click.pass_context
def main(ctx, quiet, verbose, no_progress, log_json):
    """Inverse dynamic hair modeling with frictional contact.

    Stages read and write HDF5 stage files: fit (curves to super-helices),
    detect (hair-body and hair-hair contacts), invert (rest shape and
    contact forces), simulate (the model under a scene), verify (does it
    stay still). `hairinv invert STYLE BODY` runs whatever stage is missing;
    `info` summarises any stage file, body mesh or hairstyle file; `export FILE.h5 -o OUT` writes its
    groom as USD, .hair, .data or OBJ, its summary as JSON, a picture (PNG)
    or a report (HTML); `status` and `--if-stale` tell whether a file is
    current; `diff` compares two stage files; `batch` runs many grooms on
    a Dask cluster.
    """
    keep_freed_memory()  # the command's own process only (cli/_memory.py)
    ctx.ensure_object(dict)
    ctx.obj["quiet"] = quiet
    ctx.obj["verbose"] = verbose
    ctx.obj["progress"] = not no_progress and not quiet
    ctx.obj["started"] = time.perf_counter()
    LOG_JSON["on"] = LOG_JSON["on"] or log_json


@main.command()
@click.argument("curves", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Output stage file [default: ./<name>.fit.h5].")
@import_options
@click.option("--tolerance", type=LENGTH, default=None,
              help="Fit tolerance, a length with its unit (0.2mm) or in metres: largest vertex distance the "
                   "adaptive fit aims for [fit.tolerance].")
@click.option("--elements", type=click.IntRange(min=1), default=None,
              help="Fixed number of elements per strand (default: adaptive from the tolerance).")
@settings_options
@if_stale_option
@click.pass_obj
@handle_errors
def fit(obj, curves, output, units, scale, up, flip, guides, seed, tolerance, elements, quality, config_file, sets,
        if_stale):
    """Fit every strand of CURVES with a G1 chain of super-helices.

    CURVES is any supported hairstyle file: Yuksel .hair, USC .data,
    TressFX .tfx (v2 ASCII, v3 and v4 binary), OBJ polylines, USD
    BasisCurves, or a hairinv .h5 file. Writes /curves and /helices.
    """
    from hairinv import config, stages
    from hairinv.fit import fit_groom
    from hairinv.groom import load_groom

    fit_extra = {}
    if tolerance is not None:
        fit_extra["tolerance"] = tolerance
    if elements is not None:
        fit_extra["elements"] = elements
    options = {"import": _import_extra(units, scale, up, flip, guides, seed), "fit": fit_extra}
    settings = config.Sources(quality, config_file, sets, options).settings()
    _say_settings(obj, settings, "import", "fit")
    output = output or _default_output(curves, "fit")
    stages.check_output_path(output, inputs=[curves])
    record = _pipeline_record("fit", curves, None, settings, ("import", "fit"))
    if _up_to_date(obj, if_stale, output, record):
        return
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
        [groom.curves_group(settings.import_, inputs),
         helices.group(settings.fit, inputs, {"seconds": fit_report.seconds})],
        "fit",
        record,
    )
    _say(obj, f"wrote {output}")
    _say_timings(obj, {"fit": fit_report.seconds})


def _stage_progress(enabled: bool):
    """A factory of per-stage progress bars for :func:`hairinv.pipeline.prepare`."""
    if not enabled:
        return None
    return lambda name, total: Progress(total, name, True)


class SolverProgress(Progress):
    """A bar of Gauss-Seidel sweeps showing the relative residual and the rest-shape bound (1/m), or of
    interior-point steps showing the bound."""

    def __init__(self, total: int, enabled: bool, unit: str = "sweep", measure: str = "residual",
                 stops: dict | None = None):
        super().__init__(total, "invert", enabled, unit=unit)
        self.measure = measure
        self.stops = stops or {}
        """what stops each method before its cap, by unit ("sweep", "step"): the count shown is a cap, not a
        forecast (the interior point's 100 steps at most usually end near 20)"""

    def __call__(self, sweeps: int, relative: float, bound: float = float("nan")) -> None:
        shown = f"{self.measure} {relative:.1e}"
        if bound == bound:  # not NaN: the sweeps' own bound
            shown += f", rest shape within {bound:.2g} 1/m"
        if self.unit in self.stops:
            shown += f"; {self.stops[self.unit]}"
        if self.bar is not None:
            self.bar.update(sweeps - self.bar.n)
            self.bar.set_postfix_str(shown)
        self.extra = f", {shown}"
        self._advance(sweeps)

    def interior(self, steps: int) -> "SolverProgress":
        """The same bar counting interior-point steps and showing the rest-shape bound (solver.method = auto)."""
        self.total, self.unit, self.measure, self.n, self.extra = int(steps), "step", "rest shape within (1/m)", 0, ""
        if self.bar is not None:
            self.bar.unit = "step"
            self.bar.reset(total=steps)
        return self


def solver_stops(solver) -> dict:
    """What stops the inversion's methods before their caps (``SolverProgress.stops``), from its settings."""
    return {"step": f"stops within {solver.rest_tolerance:g} 1/m, {solver.max_iterations} steps at most",
            "sweep": f"stops within {solver.rest_tolerance:g} 1/m or at residual {solver.tolerance:g}, "
                     f"{solver.max_sweeps} sweeps at most"}


def _contact_extra(body_distance, hair_distance, mu, no_hair_hair) -> dict:
    extra = {}
    if body_distance is not None:
        extra["body_distance"] = body_distance
    if hair_distance is not None:
        extra["hair_distance"] = hair_distance
    if mu is not None:
        extra["mu_body"] = mu
        extra["mu_hair"] = mu
    if no_hair_hair:
        extra["hair_hair"] = False
    return extra


def contact_options(fn):
    """Options of the contact detection shared by detect and invert."""
    options = [
        click.option("--body-distance", type=LENGTH, default=None,
                     help="A length with its unit (4mm) or in metres: a strand closer than this to the body "
                          "touches it [contacts.body_distance; default 4mm]."),
        click.option("--hair-distance", type=LENGTH, default=None,
                     help="A length with its unit (1mm) or in metres: strands closer than this touch each other "
                          "[contacts.hair_distance; default 1mm]."),
        click.option("--mu", type=FINITE, default=None,
                     help="Friction coefficient of every contact (sets contacts.mu_body and contacts.mu_hair; "
                          "default 0.3 each)."),
        click.option("--no-hair-hair", is_flag=True, help="Declare no hair-hair contacts."),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


@main.command()
@click.argument("style", type=click.Path(path_type=Path))
@click.argument("body", type=click.Path(path_type=Path), required=False)
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Output stage file [default: ./<name>.contacts.h5].")
@import_options
@body_options
@contact_options
@settings_options
@if_stale_option
@click.pass_obj
@handle_errors
def detect(obj, style, body, output, units, scale, up, flip, guides, seed, body_distance, hair_distance, mu,
           no_hair_hair, quality, config_file, sets, if_stale, body_frame):
    """Declare the hair-body and hair-hair contacts of STYLE resting on BODY.

    STYLE is a fitted stage file (from `hairinv fit`) or any hairstyle file,
    which is then fitted first. BODY is the body mesh (.obj, .ply, .stl,
    .off, .glb, .gltf, .usd, .tfxmesh) in the hairstyle's original units, or in its own with --body-units
    and --body-up. Writes /curves,
    /helices and /contacts.
    """
    from hairinv import config, stages
    from hairinv.pipeline import prepare

    options = {"import": _import_extra(units, scale, up, flip, guides, seed), "body": body_frame,
               "contacts": _contact_extra(body_distance, hair_distance, mu, no_hair_hair)}
    settings = config.Sources(quality, config_file, sets, options).settings()
    _say_settings(obj, settings, "import", "body", "fit", "contacts")
    output = output or _default_output(style, "contacts")
    stages.check_output_path(output, inputs=[style, body])
    record = _pipeline_record("detect", style, body, settings, ("import", "body", "fit", "contacts"))
    if _up_to_date(obj, if_stale, output, record):
        return
    prepared = prepare(style, body, settings, contacts=True, progress=_stage_progress(obj["progress"]))
    for line in prepared.lines:
        _say(obj, line)
    _say(obj, prepared.features.line())
    stages.write_stage(output, list(prepared.groups.values()), "detect", record)
    _say(obj, f"wrote {output}")
    _say_timings(obj, prepared.timings)


@main.command()
@click.argument("style", type=click.Path(path_type=Path))
@click.argument("body", type=click.Path(path_type=Path), required=False)
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Output stage file [default: ./<name>.model.h5].")
@click.option("--target", type=click.Choice(["actual", "zero", "uniform", "tip", "gravity-only"]), default=None,
              help="Rest shape the inversion draws towards [solver.target, default actual: the input shape].")
@click.option("--gamma", type=FINITE, default=None, help="Weight of the contact forces, N^-2 m^-2 [solver.gamma; default 0.001].")
@click.option("--stabilize", type=click.Choice(["stiffen", "off"]), default=None,
              help="Strands whose equilibrium is unstable under their contact forces held fixed: stiffen each just "
                   "enough to hold (the default), or off: keep the material and only report them "
                   "[solver.stabilize; --set solver.stable_under=supports checks with the contact points held].")
@click.option("--no-stability-check", "no_stability_check", is_flag=True,
              help="Skip the stability check (and so stiffening): no margins, no unstable strands reported "
                   "[solver.check_stability = false, solver.stabilize = off].")
@click.option("--method", type=click.Choice(["auto", "sweeps", "interior-point"]), default=None,
              help="Contact solver: interior-point (to the optimum, stopped once the rest shape is within "
                   "solver.rest_tolerance 1/m of it), sweeps (Gauss-Seidel, stopped by solver.tolerance) or auto "
                   "(the default: the interior point unless the groom would make its steps costly) "
                   "[solver.method; docs/inverse.md].")
@import_options
@body_options
@contact_options
@settings_options
@if_stale_option
@click.pass_obj
@handle_errors
def invert(obj, style, body, output, target, gamma, stabilize, no_stability_check, method, units, scale, up, flip,
           guides, seed, body_distance, hair_distance, mu, no_hair_hair, quality, config_file, sets, if_stale,
           body_frame):
    """Invert STYLE resting on BODY: find the rest shape and contact forces
    that make the input shape a static equilibrium.

    STYLE is any hairstyle file or a stage file at any stage; missing stages
    (fit, detect) run first with the same settings. BODY is the body mesh in
    the hairstyle's original units (optional: without it only hair-hair
    contacts are declared). Writes /curves, /helices, /contacts and /model.
    """
    from hairinv import config, stages
    from hairinv.inverse.method import warm_start
    from hairinv.invert import invert as run_invert
    from hairinv.model import Material
    from hairinv.pipeline import check_invert_settings, model_features, model_groups, prepare

    solver_extra = {}
    if target is not None:
        solver_extra["target"] = target
    if gamma is not None:
        solver_extra["gamma"] = gamma
    if no_stability_check:
        solver_extra["check_stability"] = False
        solver_extra["stabilize"] = "off"
    if stabilize is not None:
        solver_extra["stabilize"] = stabilize
    if method is not None:
        solver_extra["method"] = method
    options = {"import": _import_extra(units, scale, up, flip, guides, seed), "body": body_frame,
               "contacts": _contact_extra(body_distance, hair_distance, mu, no_hair_hair), "solver": solver_extra}
    settings = config.Sources(quality, config_file, sets, options).settings()
    _say_settings(obj, settings, "import", "body", "fit", "contacts", "material", "solver")
    output = output or _default_output(style, "model")
    stages.check_output_path(output, inputs=[style, body])
    record = _pipeline_record("invert", style, body, settings,
                              ("import", "body", "fit", "contacts", "material", "solver"))
    if _up_to_date(obj, if_stale, output, record):
        return
    check_invert_settings(settings)  # before any fitting
    gravity_only = settings.solver.target == "gravity-only"
    prepared = prepare(style, body, settings, contacts=not gravity_only, progress=_stage_progress(obj["progress"]))
    for line in prepared.lines:
        _say(obj, line)
    material = Material.from_settings(settings.material, prepared.up)
    start, prior, factor = None, 0, None
    if prepared.model is not None:
        start, prior, line, factor = warm_start(prepared.model, material, settings.solver, Path(style).name,
                                                prepared.helices.n_strands)
        if line:
            _say(obj, line)
    stops = solver_stops(settings.solver)
    if settings.solver.method == "interior-point":
        bar = SolverProgress(settings.solver.max_iterations, obj["progress"], "step", "rest shape within (1/m)",
                             stops=stops)
    else:
        bar = SolverProgress(settings.solver.max_sweeps, obj["progress"], stops=stops)
    try:
        model, report = run_invert(prepared.helices, prepared.contacts, material, settings.solver, progress=bar,
                                   start=start, prior_sweeps=prior, stiffening=factor)
    finally:
        bar.close()
    for line in report.lines():
        _say(obj, line)
    features = model_features(prepared, settings, material)
    _say(obj, features.line())
    stages.write_stage(output, model_groups(prepared, model, settings, features), "invert", record)
    _say(obj, f"wrote {output}")
    _say_timings(obj, {**prepared.timings, "invert": report.seconds})
    _say(obj, next_commands(output, body))


def next_commands(model: Path, body: Path | None) -> str:
    """What a user runs on a model once ``invert`` wrote it: the still check, a motion, an export."""
    import shlex

    from hairinv import formats

    args = " ".join(shlex.quote(str(p)) for p in (model, body) if p is not None)
    usd = shlex.quote(str(Path(model).with_suffix("").with_suffix(".usda")))
    animated = body is not None and formats.is_animated_body(body)
    motion = f"`hairinv simulate {args}` (plays its animation)" if animated else \
        f"`hairinv simulate {args} --scene motion` (the head turns)"
    return (f"next: `hairinv verify {args}` (does it stay still), {motion}, "
            f"`hairinv export {shlex.quote(str(model))} -o {usd}` (for Blender, Houdini, ...)")


def _init_option(fn):
    return click.option("--init", "init", type=click.Choice(["inverted", "naive", "gravity-only"]),
                        default="inverted", show_default=True,
                        help="Rest shape: the inverted model's, the input shape itself (naive), or the "
                             "contact-free inversion (gravity-only), for comparison.")(fn)


def _simulation_progress(obj, run):
    """A bar of the time steps of ``run`` (:class:`hairinv.simulation.Run`)."""
    return Progress(run.steps, "shot" if run.shot is not None else run.scene.name, obj["progress"], unit="step")


@main.command()
@click.argument("model", type=click.Path(path_type=Path))
@click.argument("body", type=click.Path(path_type=Path), required=False)
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Output stage file [default: ./<name>.frames.h5].")
@click.option("--scene", "scene_name", default="still", show_default=True, metavar="NAME|FILE.toml",
              help="What the body does: still, motion, remove-body, trim, or a scene file (docs/scenes.md).")
@_init_option
@click.option("--seconds", type=FINITE, default=None, help="Simulated time, s [default: the scene's; an animated body's length].")
@click.option("--fps", type=FINITE, default=None,
              help="Frames written per second [default: the scene's; an animated body's own rate].")
@click.option("--preroll", type=FINITE, default=None, metavar="SECONDS",
              help="Animated body: seconds taken to move it from the groom's pose to the shot's first frame "
                   "before recording [default: 0.5 where they differ, else 0].")
@click.option("--body-fps", type=FINITE, default=None, metavar="NUMBER",
              help="Animated body: its frame rate, for a mesh sequence (which states none) or over the rate "
                   "its file states [default: the file's; 24 for a sequence].")
@body_options
@settings_options(example="dynamics.time_step=0.005")
@if_stale_option
@click.pass_obj
@handle_errors
def simulate(obj, model, body, output, scene_name, init, seconds, fps, preroll, body_fps, quality, config_file, sets,
             if_stale, body_frame):
    """Simulate an inverted MODEL under a scene and write its frames.

    MODEL is a stage file written by `hairinv invert`. BODY is the body mesh
    in the hairstyle's original units; without it, the body the model was
    inverted against is used if it is still where it was. An animated body
    (glTF/GLB with skin and animation, USD, an OBJ/PLY sequence) plays its
    animation: each root follows the triangle it sits on (docs/shots.md). Writes the model's
    groups and /frames; each frame's contacts, solver residual, energies and
    largest displacement are printed as it is done.
    """
    from hairinv import config, simulation
    from hairinv.errors import Interrupted

    output = output or _default_output(model, "frames")
    sources = config.Sources(quality, config_file, sets, {"body": body_frame})
    run = simulation.load(model, body, sources, scene_name, init, seconds, fps, output,
                          say=functools.partial(_say, obj), preroll=preroll, body_fps=body_fps)
    run.record = simulation.simulate_record(run, scene_name)
    if _up_to_date(obj, if_stale, output, run.record):
        return
    scene = run.scene
    if run.shot is not None:
        _say(obj, f"shot: {run.body.name} animated, {run.seconds:g} s at {run.fps:g} frames per second"
             + (f" after a pre-roll of {run.shot.preroll:g} s from the groom's pose" if run.shot.preroll else ""))
    else:
        _say(obj, f"scene {scene.name}, {run.seconds:g} s at {run.fps:g} frames per second"
             + (f": {scene.description}" if scene.description else ""))
    _say(obj, run.features().line())
    bar = _simulation_progress(obj, run)
    try:
        frames = run.simulate(on_frame=lambda log: _say(obj, log.line()), on_step=bar)
    except Interrupted as stop:  # Ctrl-C: keep the frames done
        bar.close()
        run.write(output)
        stop.kept = f"{_interrupted_at(run)}: {_kept_in(run, output)}"
        raise
    finally:
        bar.close()
    last = frames.log[-1]
    _say(obj, f"simulated {last.time:g} s in {sum(f.seconds for f in frames.log):.1f} s; largest displacement "
              f"{1e3 * max(f.displacement for f in frames.log):.3f} mm (of any strand point from where it started, "
              "in the body's frame: the motion the body carries is not counted)")
    run.write(output)
    _say(obj, f"wrote {output}")
    _say_timings(obj, {"simulate": sum(f.seconds for f in frames.log)})


def _interrupted_at(run) -> str:
    """``interrupted after 12 of 61 frames (0.367 s of 2 s)``: where Ctrl-C stopped ``run``."""
    frames = run.frames
    return (f"interrupted after {len(frames.log)} of {frames.requested} frames ({frames.log[-1].time:.3g} s of "
            f"{run.seconds:g} s)")


def _kept_in(run, output: Path) -> str:
    """``the 12 frames computed are in out.h5, marked interrupted``."""
    return f"the {len(run.frames.log)} frames computed are in {output}, marked interrupted"


# Rows of the table of moved strands that `verify` prints.
VERIFY_ROWS = 20


def _mm(metres: float) -> str:
    """A distance in mm: three decimals, or two significant digits below a micrometre."""
    mm = 1e3 * metres
    return f"{mm:.3f}" if mm == 0 or mm >= 1e-3 else f"{mm:.1e}"


def _verdict_lines(verdict, every_strand: bool, rows: int = VERIFY_ROWS) -> list[str]:
    """The verdict line, then the table of strands (those that moved, or every strand), at most ``rows`` rows."""
    tolerance = f"{1e3 * verdict.tolerance:g} mm"
    largest = verdict.largest
    biggest = f"largest {_mm(largest.displacement)} mm, strand {largest.index}" if largest else "no strands"
    if verdict.passed:
        lines = [(f"verify: PASS, no strand point moved more than {tolerance} in {verdict.seconds_simulated:.3g} s "
                  f"({biggest})")]
    else:
        head = f"verify: FAIL, {len(verdict.moved)} of {verdict.n_strands} strands moved more than {tolerance}"
        lines = [f"{head}; stopped at {verdict.seconds_simulated:.3g} s" if verdict.stopped_early
                 else f"{head} in {verdict.seconds_simulated:.3g} s ({biggest})"]
    listed = verdict.strands if every_strand else verdict.moved
    if listed:
        lines.append(f"{'strand':>8}  {'moved (mm)':>12}  {'passed at (s)':>13}")
        for s in listed[:rows]:
            passed = f"{s.passed_at:.3f}" if s.passed_at is not None else "-"
            lines.append(f"{s.index:8d}  {_mm(s.displacement):>12}  {passed:>13}")
        if len(listed) > rows:
            lines.append(f"... and {len(listed) - rows} more strands")
    return lines


@main.command()
@click.argument("model", type=click.Path(path_type=Path))
@click.argument("body", type=click.Path(path_type=Path), required=False)
@click.option("--seconds", type=FINITE, default=None,
              help="Simulated time, s [default: the still scene's, 2].")
@click.option("--tolerance", "tolerance_text", default="0.1mm", show_default=True, metavar="LENGTH",
              help="Largest distance any strand point may move, with its unit: 0.1mm, 1e-4m, 0.01cm, 100um "
                   "(a bare number is refused: a check's tolerance a thousand times too lax would pass silently).")
@click.option("--fps", type=FINITE, default=None,
              help="Checks per simulated second: the run stops at the first frame past the tolerance "
                   "[default: the still scene's, 30].")
@click.option("--full", is_flag=True,
              help="Run to the end even after a strand has moved, and report every strand's largest displacement.")
@_init_option
@click.option("--json", "as_json", is_flag=True, help="Print a JSON summary instead of the verdict and table.")
@click.option("-o", "--output", type=click.Path(path_type=Path), default=None,
              help="Also write the frames simulated to this stage file, as `simulate` does [default: none].")
@body_options
@settings_options(example="dynamics.time_step=0.005")
@if_stale_option
@click.pass_obj
@handle_errors
def verify(obj, model, body, seconds, tolerance_text, fps, full, init, as_json, output, quality, config_file,
           sets, if_stale, body_frame):
    """Check that an inverted MODEL stays still: exit 0 if no strand point
    moves more than the tolerance in the still scene, 1 if some do.

    Runs the scene `hairinv simulate MODEL --scene still` runs (the body
    still, the model's rest shape) and checks every strand after each frame;
    the first frame in which a strand point is farther than the tolerance
    from where it started ends the run (unless --full). Prints the verdict,
    then the strands that moved: largest displacement and when each first
    passed the tolerance. BODY is as for `simulate`. With -o and --if-stale,
    an output written by the same check (same inputs, settings and options)
    is not simulated again: its verdict is read back from it.
    """
    from hairinv import config, simulation
    from hairinv.config import parse_length
    from hairinv.errors import Interrupted

    tolerance = parse_length(tolerance_text, "--tolerance")
    if if_stale and output is None:
        raise click.UsageError("--if-stale needs -o: without an output file verify keeps nothing to compare")
    notes = []
    sources = config.Sources(quality, config_file, sets, {"body": body_frame})
    run = simulation.load(model, body, sources, "still", init, seconds, fps, output, say=notes.append,
                          animate=False)
    if output is not None:  # what the frames file records, and what --if-stale compares (inputs hashed once)
        run.record = simulation.verify_record(run, tolerance, full)
    notes.append(run.features().line())
    if output is not None and _up_to_date(obj, if_stale, output, run.record):
        verdict = simulation.recorded_verdict(output, tolerance, run.seconds)
        notes.append(f"the verdict recorded in {output}")
    else:
        bar = _simulation_progress(obj, run)
        try:
            verdict = run.check_still(tolerance, full, on_step=bar)
        except Interrupted as stop:  # Ctrl-C: no verdict; what the frames done showed, and them in -o
            bar.close()
            stop.kept = _verify_interrupted(run, tolerance, output)
            raise
        finally:
            bar.close()
        if output is not None:
            run.write(output)
        seconds_used = sum(f.seconds for f in run.frames.log)
        notes.append(f"init {init}; checked at {run.fps:g} frames per second; simulated "
                     f"{verdict.seconds_simulated:.3g} of {run.seconds:g} s in {seconds_used:.1f} s")
        if output is not None:
            notes.append(f"wrote {output}")
        _say_timings(obj, {"simulate": seconds_used})
    if as_json:
        summary = {"model": str(model), "init": init, "fps": run.fps, **verdict.as_dict(every_strand=full)}
        _say({**obj, "quiet": False}, json.dumps(summary, indent=2))
    else:
        for line in _verdict_lines(verdict, every_strand=full):
            _say(obj, line)
        for line in notes:
            _say(obj, line)
    if not verdict.passed:
        sys.exit(FAILED)


def _verify_interrupted(run, tolerance: float, output: Path | None) -> str:
    """The line of a still check stopped by Ctrl-C: no verdict, what the frames done showed; their file
    (written here) with ``-o``."""
    from hairinv._text import counted
    from hairinv.dynamics.verify import judge

    moved = len(judge(run.frames, tolerance, run.seconds).moved)
    line = (f"verify {_interrupted_at(run)}, no verdict: "
            + (f"no strand point had moved more than {1e3 * tolerance:g} mm" if not moved
               else f"{counted(moved, 'strand', 'strands')} had moved more than {1e3 * tolerance:g} mm"))
    if output is not None:
        run.write(output)
        line += f"; {_kept_in(run, output)}"
    return line


@main.command()
@click.argument("stage_files", metavar="STAGE_FILE...", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="Output file; its suffix chooses the format: .usda .usdc .usd (USD), .hair, .data, .obj, "
                   ".json (summary), .png (picture), .html (report).")
@click.option("--shape", default=None, metavar="input|rest|frame:N|all",
              help="What to write: the input shape, the rest shape (needs /model), frame N of /frames (from 0), "
                   "or all the file holds (USD only) [default: all for USD, input for the others].")
@click.option("--color", "color", default=None, metavar="contact-force|rest-curvature|stiffening|fit-error",
              help="PNG, HTML: the quantity the strands are coloured by [default: contact-force for a model, "
                   "fit-error for a fitted file].")
@click.option("--basis", default=None, type=click.Choice(["linear", "catmull-rom"]),
              help="USD: the curves' type, linear segments or pinned Catmull-Rom cubics through the same vertices "
                   "[default: linear].")
@click.option("--plot", default=None, metavar="groom|convergence|render",
              help="PNG: the groom from the front and the side, the contact solver's residual against its "
                   "sweeps (needs /model), or a still of the groom on the body rendered by Blender (needs bpy: "
                   "`make blender`) [default: groom].")
@click.option("--follow", is_flag=True,
              help="USD, .hair, .data, OBJ of a simulation of guides (--guides N): write the render groom, every "
                   "strand of the hairstyle the guides were picked from, each carried by its nearest simulated "
                   "guides.")
@click.option("--render", "render", type=click.Path(path_type=Path), default=None, metavar="STYLE",
              help="With --follow (which it implies): the render groom's hairstyle file [default: the one the "
                   "stage file records].")
@if_stale_option
@click.pass_obj
@handle_errors
def export(obj, stage_files, output, shape, color, plot, basis, follow, render, if_stale):
    """Write STAGE_FILE for other tools and for people: its groom as USD, Yuksel .hair, USC .data or OBJ
    polylines, its summary as JSON, a picture as PNG, or both in one HTML report.

    USD holds every shape the file carries: the input curves with their rest shape (a second prim and a
    `rest` primvar), the simulated frames as time samples, Unreal groom primvars and hairinv's per-strand
    and per-vertex quantities, and the body mesh if it is still where it was. The polyline formats hold
    one shape, in metres, with the format's up axis. JSON summarises every stage (what `hairinv info
    --json` prints); PNG shows the groom from the front and the side over the body, coloured by a
    quantity, or with --plot convergence the contact solver's residual against its sweeps; HTML holds them
    all, readable offline. Several simulations of one groom (stage files with /frames) go side by side in
    one PNG or HTML, a before/after column each. With --follow (or --render STYLE), a simulation of guides
    is written as its render groom: every strand of the groom, moved by its nearest guides. docs/export.md
    says what each file holds.
    """
    from hairinv.export import export as run_export

    record = None
    if if_stale:
        from hairinv.staleness import check_sidecar

        record = _export_record(stage_files, output, shape, color, plot, basis, follow, render)
        if _up_to_date(obj, if_stale, output, record, check=check_sidecar):
            return
    report = run_export(list(stage_files), output, shape, follow=follow, render=render, color=color, plot=plot,
                        basis=basis)
    if record is not None:
        from hairinv.staleness import write_sidecar

        write_sidecar(output, record)
    if not obj.get("quiet"):
        for line in report.warnings:
            click.echo(f"hairinv: {line}", err=True)
    for line in report.lines:
        _say(obj, line)


def _export_record(stage_files, output: Path, shape, color, plot, basis, follow=False, render=None) -> dict:
    """The command record of an export: the stage files, and each one's recorded body where it still is (USD
    holds the body when it is found), the render groom's file where one is named, with the options that change
    what is written."""
    from hairinv import config, stages
    from hairinv.errors import InputError
    from hairinv.groom import find_recorded_body
    from hairinv.staleness import command_record, is_sidecar, sidecar_path

    inputs = []
    for path in stage_files:
        if not Path(path).exists():
            raise InputError("no such file", path)
        if not stages.is_stage_file(path):
            raise InputError("is not a hairinv stage file", path)
        body, _, _ = find_recorded_body(stages.read_stage(path), path)
        inputs += [path, body]
    if render is not None:
        if not Path(render).exists():
            raise InputError("no such file (the render groom, --render)", render)
        inputs.append(render)
    sidecar = sidecar_path(output)
    if sidecar.exists() and not is_sidecar(sidecar):
        raise InputError("exists and is not a record hairinv wrote; refusing to overwrite it (with --if-stale, "
                         "export keeps its record there)", sidecar)
    options = {"format": output.suffix.lower(), "shape": shape, "color": color, "plot": plot, "basis": basis}
    if follow or render is not None:  # (absent otherwise: records written before the option stay current)
        options["follow"] = True
    return command_record("export", inputs, config.Settings(), (), options)


@main.command()
@click.argument("file", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
@click.pass_obj
@handle_errors
def info(obj, file, as_json):
    """Summarise a hairinv stage file (groups, sizes and key figures), a body mesh (vertices, triangles,
    bounds, units stated or guessed, whether it is closed), an animated body (frames, rate, time range,
    bounds, joints) or a hairstyle file (strands, points, bounds, units)."""
    from hairinv import formats, stages
    from hairinv.errors import InputError
    from hairinv.summary import body_lines, file_summary, hairstyle_lines, summarise, summary_lines

    say = functools.partial(_say, {**obj, "quiet": False})
    if formats.is_animated_body(file):
        from hairinv.formats.animated import summary_lines as body_lines

        body = formats.read_animated_body(file).summary()
        for line in [json.dumps(body, indent=2)] if as_json else body_lines(body, str(file)):
            say(line)
        return
    if not file.exists():
        raise InputError("no such file", file)
    if file.is_dir():
        raise InputError("is a folder, not a file (nor a folder of body frames)", file)
    if not stages.is_stage_file(file) and file.suffix.lower() not in (".h5", ".hdf5"):
        summary = file_summary(file)
        lines = body_lines if summary["kind"] == "body mesh" else hairstyle_lines
        for line in [json.dumps(summary, indent=2)] if as_json else lines(summary, str(file)):
            say(line)
        return
    summary = summarise(stages.read_stage(file))
    if as_json:
        say(json.dumps(summary, indent=2))
        return
    for line in summary_lines(summary, str(file)):
        say(line)


@main.command()
@click.argument("stage_file", type=click.Path(path_type=Path))
@click.argument("inputs", nargs=-1, type=click.Path(path_type=Path))
@click.option("--quality", type=click.Choice(["draft", "default", "final"]), default=None,
              help="Also compare the settings of this preset (with --config and --set) with the recorded ones.")
@click.option("--config", "config_file", type=click.Path(dir_okay=False), default=None,
              help="Also compare the settings of this TOML file with the recorded ones.")
@click.option("--set", "sets", multiple=True, metavar="SECTION.KEY=VALUE", help="Also compare this setting.")
@click.option("--check", "check_data", is_flag=True,
              help="Also read every array of STAGE_FILE and check it as the other commands do (slower on a large "
                   "file); without it only the file's metadata is checked.")
@click.pass_obj
@handle_errors
def status(obj, stage_file, inputs, quality, config_file, sets, check_data):
    """Say whether STAGE_FILE is current: exit 0 if its inputs still have the contents it was made from
    (and, with --quality/--config/--set, the same settings), 1 if stale (naming what changed), 2 if it
    cannot be read, breaks the stage-file format or records nothing to compare.

    The inputs are found where the file recorded them (as written, then next to STAGE_FILE), or given as
    INPUTS in the order the command took them (e.g. the hairstyle, then the body). An export written with
    --if-stale (a USD, PNG, ... with its OUTPUT.hairinv.json beside it) is checked the same way.

    It reads the stage file's attributes and the shapes of its datasets, not the arrays, so it answers at
    once on a large file: a file whose groups disagree in size or lack what hairinv reads is refused, but
    the numbers in it are not checked (the answer says so). --check reads and checks them too.
    """
    from hairinv import config, stages
    from hairinv.staleness import status as file_status

    settings = None
    if quality is not None or config_file is not None or sets:
        settings = config.resolve(quality or "default", config_file, sets)
    current, reasons = file_status(stage_file, inputs, settings, check_data=check_data)
    if current:
        unchecked = not check_data and stages.is_stage_file(stage_file)
        _say(obj, f"{stage_file}: current" + (" (its arrays were not read; --check checks them too)" if unchecked
                                               else ""))
        return
    for reason in reasons:
        _say(obj, f"{stage_file}: stale: {reason}")
    sys.exit(FAILED)


@main.command()
@click.argument("manifest", type=click.Path(path_type=Path))
@click.option("-o", "--output", "outdir", type=click.Path(path_type=Path), default=Path("batch"), show_default=True,
              help="Folder of the stage files, logs and summary (batch.json).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A running Dask scheduler (tcp://host:8786, tls://...) [default: a local cluster on 127.0.0.1].")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local cluster: worker processes [default: as many as grooms and shots, at most the cores].")
@click.option("--tls-ca-file", type=click.Path(dir_okay=False), default=None, help="TLS: the CA certificate.")
@click.option("--tls-cert", type=click.Path(dir_okay=False), default=None, help="TLS: this client's certificate.")
@click.option("--tls-key", type=click.Path(dir_okay=False), default=None, help="TLS: the certificate's key.")
@click.pass_obj
@handle_errors
def batch(obj, manifest, outdir, scheduler, workers, tls_ca_file, tls_cert, tls_key):
    """Run every groom of MANIFEST (TOML: hair, body, units, settings, stages, exports) as one task on a
    Dask cluster, each with its own log and stage files in OUTPUT, and print a summary table (also
    written to OUTPUT/batch.json). A groom that fails is reported with its message; the others go on.
    Exit 1 if any failed. A second run redoes only what changed. Shots ([[shot]]: a groom's model simulated
    under an animated body, then exported) run once their groom's model is made. docs/batch.md has the
    manifest format.
    """
    from hairinv.atomic import write_bytes
    from hairinv.batch import read_manifest_shots, run_batch, security_from, table

    grooms, shots, tls = read_manifest_shots(manifest)
    security = security_from(tls, tls_ca_file, tls_cert, tls_key)
    if security is not None and not scheduler:
        _say(obj, "note: TLS settings apply to a scheduler given with --scheduler; the local cluster listens "
                  "on 127.0.0.1 only")
        security = None
    _say(obj, f"{len(grooms)} grooms" + (f" and {len(shots)} shots" if shots else "") + f" from {manifest}"
         + (f" on {scheduler}" if scheduler else ", local cluster"))

    def done(row):
        _say(obj, f"{row['groom']}: {row['status']}" + (f" ({row['message']})" if row["message"] else ""))

    rows = run_batch(grooms, outdir, scheduler=scheduler, workers=workers, security=security, on_row=done,
                     shots=shots)
    _say(obj, table(rows))
    summary = {"manifest": str(manifest), "grooms": rows, "failed": sum(r["status"] != "ok" for r in rows)}
    write_bytes(Path(outdir) / "batch.json", json.dumps(summary, indent=2).encode())
    _say(obj, f"wrote {Path(outdir) / 'batch.json'}")
    if summary["failed"]:
        sys.exit(FAILED)


def _late_global(name: str):
    """``-q``, ``-v`` and ``--no-progress`` after the subcommand too (``hairinv invert ... -q`` is what people
    type)."""
    def callback(ctx, _param, value):
        if value:
            ctx.ensure_object(dict)
            if name == "verbose":
                ctx.obj["verbose"] = True
                return
            if name == "log_json":
                LOG_JSON["on"] = True
                return
            ctx.obj["progress"] = False
            if name == "quiet":
                ctx.obj["quiet"] = True
    return callback


import hairinv_cli.diff  # noqa: E402,F401  `hairinv diff`, registered on main before -q/-v are added below

for _command in main.commands.values():
    _command.params.append(click.Option(["-q", "--quiet"], is_flag=True, expose_value=False,
                                        callback=_late_global("quiet"), help="Print only errors."))
    _command.params.append(click.Option(["-v", "--verbose"], is_flag=True, expose_value=False,
                                        callback=_late_global("verbose"),
                                        help="Also print the settings in effect and each stage's time."))
    _command.params.append(click.Option(["--log-json"], is_flag=True, expose_value=False,
                                        callback=_late_global("log_json"),
                                        help="Also write one JSON object per event to stderr."))
    _command.params.append(click.Option(["--no-progress"], is_flag=True, expose_value=False,
                                        callback=_late_global("progress"), help="Never draw progress bars."))


if __name__ == "__main__":
    main()
