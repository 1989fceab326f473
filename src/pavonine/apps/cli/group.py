"""The ``pavonine`` click group: lazy subcommands, global ``-v/-q``, one-line errors.

* Subcommands are imported only when invoked or listed, so ``pavonine --help`` is fast and a
  command's heavy imports (Mitsuba, USD) stay out of the others.
* ``-v/--verbose`` and ``-q/--quiet`` are accepted before the command and by every command
  (``pavonine -q render …`` = ``pavonine render -q …``), including commands added later.
* Usage errors (unknown option, bad value, missing argument), bad input
  (:class:`~pavonine.base.errors.InputError`) and a missing optional extra each print one line
  ``error: <where>: <message>`` on stderr and exit with status 2.
* Every warning, a library's included, is the command's own ``warning: …`` line
  (:func:`~pavonine.apps.cli.options.warnings_as_lines`), never Python's ``file:line:``.
* Ctrl-C (``KeyboardInterrupt``) prints ``error: <command>: interrupted`` and exits with 130
  (128 + SIGINT, as shells do).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Mapping

import click

from pavonine.apps.cli.options import (
    EXTRA_OF_MODULE,
    MissingExtra,
    configure_logging,
    verbosity_options,
)
from pavonine.base.errors import EXIT_BAD_INPUT, InputError
from pavonine.base.interrupt import EXIT_INTERRUPTED
from pavonine.materials.parameters import ParameterError


class Interrupted(Exception):
    """Ctrl-C inside a command (carried past click, which would turn it into "Aborted!")."""

    def __init__(self, command: str):
        super().__init__(command)
        self.command = command


def _param_name(param: click.Parameter) -> str:
    if isinstance(param, click.Option):
        return max(param.opts, key=len)
    return param.human_readable_name


def usage_error_line(exc: click.UsageError) -> str:
    """One line ``error: <option or argument>: <message> (see '<command> --help')``."""
    ctx = exc.ctx
    command = ctx.command_path if ctx is not None else "pavonine"
    where, message = command, exc.format_message()
    if isinstance(exc, click.NoSuchOption):
        where = exc.option_name
        message = "no such option"
        if exc.possibilities:
            message += f" (did you mean {', '.join(exc.possibilities)}?)"
    elif isinstance(exc, click.MissingParameter) and exc.param is not None:
        where = _param_name(exc.param)
        message = f"missing {exc.param.param_type_name}" + (
            f": {exc.message}" if exc.message else ""
        )
    elif isinstance(exc, click.BadParameter) and exc.param is not None:
        where = _param_name(exc.param)
        message = exc.message
    return f"error: {where}: {' '.join(message.split()).rstrip('.')} (see '{command} --help')"


def missing_extra(exc: ModuleNotFoundError, command: str) -> MissingExtra | None:
    """:class:`MissingExtra` for a missing optional dependency, or ``None`` if it is not one."""
    module = (exc.name or "").split(".")[0]
    return MissingExtra(command, module) if module in EXTRA_OF_MODULE else None


def _add_global_options(command: click.Command) -> click.Command:
    """Give ``command`` (and a group's subcommands) ``-v/-q`` once."""
    if not any(p.name == "verbose" for p in command.params):
        command.params.extend(verbosity_options())
    if isinstance(command, click.Group):
        for sub in command.commands.values():
            _add_global_options(sub)
    return command


class PavonineGroup(click.Group):
    """Lazy subcommands from a ``name → "module:attribute"`` table, and the error convention."""

    def __init__(self, *args, lazy_commands: Mapping[str, str], **kwargs):
        super().__init__(*args, **kwargs)
        self.lazy_commands = lazy_commands
        self.params.extend(verbosity_options())

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(self.lazy_commands)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        target = self.lazy_commands.get(cmd_name)
        if target is None:
            return None
        module_name, attr = target.split(":")
        try:
            command = getattr(importlib.import_module(module_name), attr)
        except ModuleNotFoundError as exc:
            error = missing_extra(exc, f"{ctx.command_path} {cmd_name}")
            if error is None:
                raise
            raise error from None
        return _add_global_options(command)

    def invoke(self, ctx: click.Context):
        from pavonine.apps.cli.options import log, warnings_as_lines
        from pavonine.apps.cli.usd_diagnostics import usd_warnings_to_log

        try:
            with usd_warnings_to_log(log, ctx.meta), warnings_as_lines():
                return super().invoke(ctx)
        except KeyboardInterrupt:
            command = f"{ctx.command_path} {ctx.invoked_subcommand or ''}".strip()
            raise Interrupted(command) from None
        except ModuleNotFoundError as exc:
            error = missing_extra(exc, f"{ctx.command_path} {ctx.invoked_subcommand or ''}".strip())
            if error is None:
                raise
            raise error from None

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """click's ``main`` with every error reported on one line (exit 2 for bad input)."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        configure_logging()
        no_args = getattr(click.exceptions, "NoArgsIsHelpError", ())
        try:
            result = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except no_args as exc:  # ``pavonine`` alone (click >= 8.2): the help, not an error
            click.echo(exc.ctx.get_help())
            sys.exit(0)
        except click.UsageError as exc:
            click.echo(usage_error_line(exc), err=True)
            sys.exit(EXIT_BAD_INPUT)
        except click.ClickException as exc:
            click.echo(f"error: {' '.join(exc.format_message().split())}", err=True)
            sys.exit(exc.exit_code)
        except click.Abort as exc:
            if isinstance(exc.__cause__, KeyboardInterrupt):  # Ctrl-C before a command ran
                click.echo(f"error: {prog_name or 'pavonine'}: interrupted", err=True)
                sys.exit(EXIT_INTERRUPTED)
            click.echo("aborted", err=True)
            sys.exit(1)
        except Interrupted as exc:
            click.echo(f"error: {exc.command}: interrupted", err=True)
            sys.exit(EXIT_INTERRUPTED)
        except KeyboardInterrupt:  # Ctrl-C outside a command's invoke (click's own parsing)
            click.echo(f"error: {prog_name or 'pavonine'}: interrupted", err=True)
            sys.exit(EXIT_INTERRUPTED)
        except (InputError, ParameterError) as exc:  # commands use @one_line_errors; the rest
            click.echo(f"error: {exc}", err=True)
            sys.exit(EXIT_BAD_INPUT)
        sys.exit(result if isinstance(result, int) else 0)
