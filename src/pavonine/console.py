"""The ``pavonine`` console script: the command line, with Ctrl-C handled from its first moment.

The script pip writes imports this module and calls :func:`main`. Importing it costs only
``import pavonine`` (4 ms by ``python -X importtime``: USD loads later, :mod:`pavonine.base.usd_import`); the
command line itself (click, numpy, the command's modules) is imported inside :func:`main`, so a
Ctrl-C while it loads, while a command runs (``pavonine.apps.cli.group`` reports those) or
while the process exits is one line ``error: pavonine: interrupted`` and exit status 130, never a
traceback (:mod:`pavonine.base.interrupt`). Python's own start-up (``site`` and ``.pth`` files)
precedes any Pavonine code; ``docs/reliability.md`` says what that leaves.
"""

from __future__ import annotations

from pavonine.base.interrupt import EXIT_INTERRUPTED, arm_if_console, interrupted, signal

__all__ = ["EXIT_INTERRUPTED", "arm_if_console", "main"]


def main() -> None:
    """Run ``pavonine`` with ``sys.argv``."""
    try:
        if signal.getsignal(signal.SIGINT) is interrupted:  # armed by import pavonine
            signal.signal(signal.SIGINT, signal.default_int_handler)
        from pavonine.apps.cli import main as run

        run()
    except KeyboardInterrupt:  # while the command line loaded, or past its own handling
        interrupted()
    finally:  # exiting (a SystemExit on its way): a Ctrl-C now ends the process the same way
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, interrupted)
