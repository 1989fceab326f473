"""USD's own warnings (``TF_WARN``: composition errors, unresolved assets) as one-line warnings.

Without a diagnostic delegate USD prints ``Warning: in _ReportErrors at line 3326 of
/opt/USD/pxr/usd/usd/stage.cpp -- In </A>: Could not open asset …`` to stderr, once per stage it
opens (a command often opens the same stage twice), beside the command's own warning about the
same problem. While a command runs, a ``UsdUtils.CoalescingDiagnosticDelegate`` collects them
instead; when the command ends each distinct one becomes ``warning: <what USD said>``, unless
the command already warned about it in its own words, or reports USD's diagnostics itself
(``validate``: :func:`reported_by_command`), or stops for bad input (its one error line is the
answer). USD errors are unaffected: they reach Python as exceptions, which commands turn into
one-line errors.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
from collections.abc import Iterator, MutableMapping
from typing import Any

from pavonine.base.errors import EXIT_BAD_INPUT, InputError, one_line
from pavonine.materials.parameters import ParameterError

#: USD's suffix naming the stage object (``(instantiating stage on stage @a.usda@ <0x55…>)``).
_STAGE_SUFFIX = re.compile(
    r"\s*\((?:instantiating|recomposing) stage on stage @[^@]*@ <0x[0-9a-f]+>\)\s*$"
)
#: ``click.Context.meta`` key: the command reports USD's diagnostics itself.
REPORTED = "pavonine.usd_diagnostics_reported"
#: USD's prefix naming the prim (``In </A>: ``).
_PRIM_PREFIX = re.compile(r"^In <([^>]*)>: ")


class _Said(logging.Filter):
    """Records what the command logs, so USD's duplicates of it are dropped."""

    def __init__(self) -> None:
        super().__init__()
        self.messages: list[str] = []

    def filter(self, record: logging.LogRecord) -> bool:
        self.messages.append(record.getMessage())
        return True


def usd_warning_line(commentary: str) -> str:
    """USD's commentary in one line: the prim first, without the stage object's address."""
    text = _STAGE_SUFFIX.sub("", one_line(commentary))
    match = _PRIM_PREFIX.match(text)
    return f"{match.group(1)}: {text[match.end() :]}" if match else text


def _missing_assets(line: str) -> set[str]:
    """The absolute ``@paths@`` a USD line names that do not exist (what it is about)."""
    return {
        p for p in re.findall(r"@([^@]+)@", line) if p.startswith("/") and not os.path.exists(p)
    }


def _core(line: str) -> str:
    """What identifies a warning across wordings: the text after the prim, without ``@``."""
    return line.split(": ", 1)[-1].replace("@", "").rstrip(".")


def reported_by_command() -> None:
    """Called by a command that reports USD's diagnostics as its own findings (``validate``)."""
    import click

    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        ctx.meta[REPORTED] = True


@contextlib.contextmanager
def usd_warnings_to_log(
    logger: logging.Logger, meta: MutableMapping[str, Any] | None = None
) -> Iterator[None]:
    """Inside the block USD's warnings are collected; at its end each distinct one the block did
    not already log goes to ``logger.warning`` (none when ``meta`` says the command reported
    them: :func:`reported_by_command`)."""
    try:
        from pxr import UsdUtils
    except ImportError:  # no USD: nothing to collect
        yield
        return
    said = _Said()
    logger.addFilter(said)
    delegate = UsdUtils.CoalescingDiagnosticDelegate()
    refused = False
    try:
        yield
    except SystemExit as exc:
        refused = exc.code == EXIT_BAD_INPUT
        raise
    except (InputError, ParameterError):
        refused = True
        raise
    finally:
        logger.removeFilter(said)
        diagnostics = delegate.TakeUncoalescedDiagnostics()
        del delegate  # USD prints again from here on
        if refused or (meta is not None and meta.get(REPORTED)):
            diagnostics = []  # bad input: its one error line is the whole answer
        seen = {_core(m) for m in said.messages}
        for diagnostic in diagnostics:
            line = usd_warning_line(diagnostic.commentary)
            core = _core(line)
            if not core or any(core in m for m in seen):
                continue
            missing = _missing_assets(line)
            if missing and any(path in m for path in missing for m in said.messages):
                continue  # the command named that missing file already
            seen.add(core)
            logger.warning("USD: %s", line)
