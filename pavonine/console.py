"""The ``pavonine`` console script: the command line, with Ctrl-C handled from its first moment.

The script pip writes imports this module and calls :func:`main`. Importing it costs only
``import pavonine`` (4 ms by ``python -X importtime``: USD loads later, :mod:`pavonine.usd_import`); the
command line itself (click, numpy, the command's modules) is imported inside :func:`main`, so a
Ctrl-C while it loads, while a command runs (``pavonine.pipeline.cli.group`` reports those) or
while the process exits is one line ``error: pavonine: interrupted`` and exit status 130, never a
traceback. Python's own start-up (``site`` and ``.pth`` files) precedes any Pavonine code;
``docs/reliability.md`` says what that leaves.
"""

from __future__ import annotations

import os
import signal
import sys

#: Exit status of a command interrupted by Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130


def _interrupted(*_: object) -> None:
    """Report an interruption in one line and exit 130 at once (no clean-up left to do that a
    second Ctrl-C could interrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os.write(2, b"error: pavonine: interrupted\n")
    os._exit(EXIT_INTERRUPTED)


def main() -> None:
    """Run ``pavonine`` with ``sys.argv``."""
    try:
        from pavonine.pipeline.cli import main as run

        run()
    except KeyboardInterrupt:  # while the command line loaded, or past its own handling
        _interrupted()
    finally:  # exiting (a SystemExit on its way): a Ctrl-C now ends the process the same way
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _interrupted)
