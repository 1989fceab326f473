"""The ``pavonine`` command-line convention, as reusable click decorators and helpers.

Every command uses these instead of declaring its own variant (docs/cli.md describes the result):

=====================  =========================================================================
``output_option``      ``-o/--output PATH``: the file or folder the command writes (param ``output``)
``json_option``        ``--json FILE|-``: the command's report as JSON, with a documented schema;
                       ``-`` = stdout, and then nothing else goes to stdout (param ``json_target``)
``junit_option``       ``--junit FILE``: results as JUnit XML for CI systems (param ``junit``)
``threads_option``     ``--threads N`` (or ``$PAVONINE_THREADS``): worker threads (in force in the body, no param)
(``values.py``)        ``FiniteFloat``, ``SEED``, ``max_pixels_option``: checked numbers, seeds and
                       the ``--max-pixels`` budget of images read
``display_options``    ``--ocio-config``/``--display``/``--view``/``--exposure``: the OCIO display
                       transform of the PNGs written (param ``display``, a ``DisplayTransform``)
``requires(*modules)`` the optional modules a command needs: checked before it starts, a missing
                       one is a one-line error naming the extra that installs it
(added by the group)   ``-v/--verbose``, ``-q/--quiet`` on every command: logging level; ``-q``
                       hides progress bars
=====================  =========================================================================

Human output goes through :func:`say` / :func:`stdout_console` (silent under ``--json -``),
messages through ``logging.getLogger("pavonine")`` (stderr, rich's handler on a terminal), progress
through :func:`progress_bar` (stderr, hidden by ``-q`` and when stderr is not a terminal), reports
through :func:`emit_json`. Errors: raise :class:`pavonine.base.errors.InputError`.
"""

from __future__ import annotations

import contextlib
import functools
import importlib.util
import json
import logging
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import click

from pavonine import LOGGER_NAME
from pavonine.apps.cli.values import FiniteFloat
from pavonine.base.backend import debian_hint, first_import_error
from pavonine.base.commit import atomic_path
from pavonine.base.errors import InputError
from pavonine.pipeline.convert.meshing import check_filters, meshing_backend

F = Callable[..., Any]

log = logging.getLogger(LOGGER_NAME)

_VERBOSITY = "pavonine.verbosity"
_JSON_STDOUT = "pavonine.json_stdout"
THREADS_ENV = "PAVONINE_THREADS"


# ----------------------------------------------------------------------------------- extras
#: Optional top-level module → the extra that installs it (``pip install 'pavonine[EXTRA]'``).
EXTRA_OF_MODULE = {
    "mitsuba": "render",
    "drjit": "render",
    "PyOpenColorIO": "render",
    "flip_evaluator": "render",
    "jinja2": "render",
    "pymeshlab": "convert",
    "xatlas": "convert",
    "MaterialX": "convert",
    "pygltflib": "convert",
    "dask": "farm",
    "distributed": "farm",
}


class MissingExtra(click.ClickException):
    """A command needs an optional extra that is not installed (one line, exit 2)."""

    exit_code = 2

    def __init__(self, command: str, module: str):
        extra = EXTRA_OF_MODULE[module]
        super().__init__(
            f"{command}: needs the [{extra}] extra (no module {module!r}); "
            f"install it with: pip install 'pavonine[{extra}]'"
        )


#: Checks beyond importing: module name → a function raising ImportError when it is unusable.
LOAD_CHECKS: dict[str, Callable[[Any], None]] = {"pymeshlab": check_filters}
#: Modules a command can do without when they cannot load: module → a probe choosing the fallback
#: (warning once) or raising ImportError when the user insists on the module.
FALLBACK_PROBES: dict[str, Callable[[], Any]] = {"pymeshlab": meshing_backend}


class MissingSystemLibrary(click.ClickException):
    """An installed module cannot load a system library (one line, exit 2)."""

    exit_code = 2

    def __init__(self, command: str, module: str, error: BaseException):
        message = first_import_error(error)
        super().__init__(f"{command}: {module} cannot load: {message}{debian_hint(message)}")


class BadEnvironment(click.ClickException):
    """An environment variable has a value Pavonine does not know (one line, exit 2)."""

    exit_code = 2


def importable(module: str) -> bool:
    """``module`` can be imported (without importing it)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def requires(*modules: str, may_not_load: tuple[str, ...] = ()) -> Callable[[F], F]:
    """Check before the command runs (so it writes nothing) that ``modules`` are installed and
    load (a wheel can lack a system library, such as pymeshlab's libGL). Modules in
    ``may_not_load`` must be installed, but the command handles their failing to load itself
    (``pavonine demo`` converts the feather and skips the render without Dr.Jit's libatomic).
    Modules in :data:`FALLBACK_PROBES` need not load: their probe picks the fallback (pymeshlab →
    NumPy meshing, one warning) unless the user insists on them."""

    def decorate(func: F) -> F:
        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            command = click.get_current_context().command_path
            for module in modules:
                if not importable(module):
                    raise MissingExtra(command, module)
                if module in may_not_load:
                    continue
                if module in FALLBACK_PROBES:
                    try:
                        FALLBACK_PROBES[module]()
                    except ImportError as exc:
                        raise MissingSystemLibrary(command, module, exc) from None
                    except InputError as exc:
                        raise BadEnvironment(str(exc)) from None
                    continue
                try:
                    loaded = importlib.import_module(module)
                    LOAD_CHECKS.get(module, lambda m: None)(loaded)
                except Exception as exc:  # a missing .so: ImportError, or worse from Dr.Jit
                    raise MissingSystemLibrary(command, module, exc) from None
            return func(*args, **kwargs)

        wrapper.pavonine_requires = modules  # type: ignore[attr-defined]  (for docs/cli.md)
        return wrapper  # type: ignore[return-value]

    return decorate


def required_extras(command: click.Command) -> list[str]:
    """The extras a command declares with :func:`requires`, in order."""
    modules = getattr(command.callback, "pavonine_requires", ())
    return list(dict.fromkeys(EXTRA_OF_MODULE[m] for m in modules))


# ------------------------------------------------------------------------------ -v / -q
def _count_verbosity(ctx: click.Context, param: click.Parameter, value: int) -> None:
    if value:
        root = ctx.find_root()
        sign = 1 if param.name == "verbose" else -1
        root.meta[_VERBOSITY] = root.meta.get(_VERBOSITY, 0) + sign * value
    configure_logging(verbosity(ctx))


def verbosity_options() -> list[click.Option]:
    """Fresh ``-v/--verbose`` and ``-q/--quiet`` options (the group adds them to every command)."""
    common = dict(count=True, expose_value=False, is_eager=True, callback=_count_verbosity)
    return [
        click.Option(["-v", "--verbose"], help="More messages (-vv: debug).", **common),  # type: ignore[arg-type]
        click.Option(
            ["-q", "--quiet"], help="Only warnings and errors; no progress bars.", **common
        ),  # type: ignore[arg-type]
    ]


def verbosity(ctx: click.Context | None = None) -> int:
    """``-v`` count minus ``-q`` count for the current command (0 outside a command)."""
    ctx = ctx or click.get_current_context(silent=True)
    return 0 if ctx is None else ctx.find_root().meta.get(_VERBOSITY, 0)


def quiet() -> bool:
    """``-q`` was given: no progress bars, no informational messages."""
    return verbosity() < 0


class _StderrHandler(logging.StreamHandler):
    """Plain ``level: message`` lines on whatever ``sys.stderr`` is when a record is emitted."""

    def emit(self, record: logging.LogRecord) -> None:
        # assigned, not setStream(): that flushes the previous stream, which a caller that ran a
        # command in its own process (click's CliRunner) may have closed since
        self.stream = sys.stderr
        super().emit(record)


class _LevelFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        return f"{record.levelname.lower()}: {record.getMessage()}"


def configure_logging(level_offset: int = 0) -> None:
    """Route ``pavonine`` log records to stderr: INFO by default, DEBUG with -v, WARNING with -q.

    On a terminal through rich's handler; otherwise (CI logs, pipes) one ``level: message`` line
    per record, so that logs stay greppable.
    """
    level = logging.INFO - 10 * max(-2, min(1, level_offset))
    logger = logging.getLogger(LOGGER_NAME)
    for handler in list(logger.handlers):
        logger.removeHandler(handler)
    if sys.stderr.isatty():
        from rich.console import Console
        from rich.logging import RichHandler

        handler: logging.Handler = RichHandler(
            console=Console(stderr=True), show_time=False, show_path=False, markup=False
        )
    else:
        handler = _StderrHandler()
        handler.setFormatter(_LevelFormatter())
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False


@contextlib.contextmanager
def warnings_to_log(*categories: type[Warning]) -> Iterator[None]:
    """Inside the block, every warning of ``categories`` becomes ``log.warning``, each distinct
    message once (a stage read twice, for its settings and for the render, warns twice)."""
    said: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None):
        if str(message) not in said:
            said.add(str(message))
            log.warning("%s", message)

    with warnings.catch_warnings():
        for category in categories or (Warning,):
            warnings.simplefilter("always", category)
        warnings.showwarning = show
        yield


@contextlib.contextmanager
def warnings_as_lines() -> Iterator[None]:
    """Every warning Python's filters let through (a library's, or one no command routed)
    becomes the command's own ``warning: …`` line, never Python's ``file:line: Category: …``;
    the filters themselves are left as they are."""

    def show(message, category, filename, lineno, file=None, line=None):
        log.warning("%s", " ".join(str(message).split()))  # one line, whatever it held

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def show_progress() -> bool:
    """Progress bars are shown: not ``-q``, and stderr is a terminal."""
    return not quiet() and sys.stderr.isatty()


class _NoProgress:
    """What :func:`progress_bar` gives when bars are hidden: the calls commands make, doing nothing
    (a disabled rich bar can still print a blank line on some rich versions)."""

    def __enter__(self) -> _NoProgress:
        return self

    def __exit__(self, *exc) -> None:
        return None

    def add_task(self, *args, **kwargs) -> int:
        return 0

    def advance(self, *args, **kwargs) -> None:
        return None

    def update(self, *args, **kwargs) -> None:
        return None


def progress_bar(*columns, transient: bool = True):
    """A rich progress bar on stderr; nothing under ``-q`` or when stderr is not a terminal."""
    if not show_progress():
        return _NoProgress()
    from rich.console import Console
    from rich.progress import Progress

    return Progress(*columns, console=Console(stderr=True), transient=transient)


# ------------------------------------------------------------------------------------ -o
def output_option(
    *,
    folder: bool,
    default: Path | None = None,
    required: bool = False,
    help: str,
) -> Callable[[F], F]:
    """``-o/--output PATH``: where the command writes (a ``folder`` or a file), param ``output``."""
    # No ``default=None`` when there is none: click >= 8.3 takes an explicit None default as a
    # value, so a required -o would go missing silently (and fail later with a TypeError).
    extra: dict[str, Any] = {} if default is None else {"default": default}
    return click.option(
        "-o",
        "--output",
        "output",
        type=click.Path(file_okay=not folder, dir_okay=folder, path_type=Path),
        **extra,
        required=required,
        show_default=default is not None,
        metavar="DIR" if folder else "FILE",
        help=help,
    )


# ---------------------------------------------------------------------------------- --json
class JsonOption(click.Option):
    """``--json FILE|-`` carrying the JSON Schema of the command's report (for docs and tests)."""

    def __init__(self, *args, schema: dict[str, Any], **kwargs):
        super().__init__(*args, **kwargs)
        self.schema = schema


def _json_target(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """``-``: stdout; a file is checked writable here, before the command writes anything else
    (the report is written last, so an unwritable one would otherwise leave the outputs behind)."""
    from pavonine.base.commit import check_writable

    if value == "-":
        ctx.meta[_JSON_STDOUT] = True
    elif value is not None and Path(value).is_dir():
        raise click.BadParameter(f"{value} is a folder; give a file name or '-'", ctx, param)
    elif value is not None and not ctx.resilient_parsing:
        check_writable(value)
    return value


def json_option(schema: dict[str, Any]) -> Callable[[F], F]:
    """``--json FILE|-``: write the report (documented by ``schema``) to FILE, or stdout for ``-``."""
    return click.option(
        "--json",
        "json_target",
        cls=JsonOption,
        schema=schema,
        metavar="FILE|-",
        callback=_json_target,
        help="Write the report as JSON to FILE ('-': stdout, and nothing else on stdout).",
    )


def json_schema(command: click.Command) -> dict[str, Any] | None:
    """The report schema of a command's ``--json`` option (``None`` if it has none)."""
    for param in command.params:
        if isinstance(param, JsonOption):
            return param.schema
    return None


def json_to_stdout() -> bool:
    """``--json -`` was given: stdout belongs to the JSON report."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx and ctx.meta.get(_JSON_STDOUT))


def emit_json(target: str | None, payload: Any) -> None:
    """Write ``payload`` as JSON to ``target`` (``-``: stdout; a file: atomically); ``None``: no-op."""
    if target is None:
        return
    text = json.dumps(payload, indent=2, ensure_ascii=False) + "\n"
    if target == "-":
        click.echo(text, nl=False)
        return
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")


def say(message: str = "", **kwargs) -> None:
    """Human output on stdout (suppressed under ``--json -``)."""
    if not json_to_stdout():
        click.echo(message, **kwargs)


def stdout_console():
    """A rich console for tables on stdout (silent under ``--json -``)."""
    from rich.console import Console

    return Console(quiet=json_to_stdout(), highlight=False)


# --------------------------------------------------------------------------------- --junit
def junit_option(func: F) -> F:
    """``--junit FILE``: write the results as JUnit XML (param ``junit``)."""
    return click.option(
        "--junit",
        "junit",
        type=click.Path(dir_okay=False, path_type=Path),
        metavar="FILE",
        help="Also write the results as JUnit XML (for CI test reports).",
    )(func)


# ------------------------------------------------------------------------------- --threads
def apply_threads(count: int | None) -> None:
    """Make ``count`` the worker-thread limit for the running command only (``None``: not
    given, one per core). The limits before are restored when the command's click context
    closes, also when it fails, so commands run in-process never leave them changed. Call it
    from the command's body, never from a parameter callback (see ``apply_pixel_budget``)."""
    from pavonine.base.backend import thread_limit

    click.get_current_context().with_resource(thread_limit(count))


def threads_option(func: F) -> F:
    """``--threads N`` (default ``$PAVONINE_THREADS``, else one per core), in force while the
    command's body runs (the function gets no parameter for it)."""

    @functools.wraps(func)
    def wrapper(*args: Any, threads: int | None, **kwargs: Any) -> Any:
        apply_threads(threads)
        return func(*args, **kwargs)

    return click.option(
        "--threads",
        type=click.IntRange(min=1),
        envvar=THREADS_ENV,
        show_envvar=True,
        metavar="N",
        help="Worker threads (Dr.Jit, OpenImageIO, BLAS) [default: one per core].",
    )(wrapper)


# -------------------------------------------------------------------------- display options
def display_options(func: F) -> F:
    """``--ocio-config``, ``--display``, ``--view``, ``--exposure`` → param ``display``.

    The checked :class:`pavonine.materials.display.DisplayTransform` is passed as ``display`` and
    is the current display transform while the command runs. Use :func:`display_overrides` to
    know which fields the user gave explicitly (``compare`` prefers what a PNG records).
    """
    from pavonine.materials.display import PINNED_CONFIG

    @functools.wraps(func)
    def wrapper(*args, ocio_config, display_name, view, exposure, **kwargs):
        from pavonine.materials.display import DisplayError, resolve, use_display

        try:
            transform = resolve(ocio_config, display_name, view, exposure)
        except DisplayError as exc:
            raise InputError(exc.field, exc.message) from None
        with use_display(transform):
            return func(*args, display=transform, **kwargs)

    options = [
        click.option(
            "--ocio-config",
            envvar="OCIO",
            show_envvar=True,
            metavar="CONFIG",
            help=f"OCIO config file or ocio:// name [default: $OCIO, else {PINNED_CONFIG}].",
        ),
        click.option(
            "--display",
            "display_name",
            metavar="NAME",
            help="OCIO display of the PNGs [default: 'sRGB - Display', or the config's default].",
        ),
        click.option(
            "--view",
            metavar="NAME",
            help="OCIO view of the PNGs [default: 'Un-tone-mapped', or the config's default].",
        ),
        click.option(
            "--exposure",
            type=FiniteFloat(-64.0, 64.0),
            default=0.0,
            show_default=True,
            metavar="STOPS",
            help="Exposure in stops, applied in scene-linear before the view.",
        ),
    ]
    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper  # type: ignore[return-value]


def display_overrides() -> dict[str, Any]:
    """The display fields given on the command line (not defaults, not ``$OCIO``)."""
    from click.core import ParameterSource

    ctx = click.get_current_context()
    names = {"ocio_config": "config", "display_name": "display", "view": "view"}
    names["exposure"] = "exposure"
    return {
        field: ctx.params[name]
        for name, field in names.items()
        if ctx.get_parameter_source(name) == ParameterSource.COMMANDLINE
    }
