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

# The C module behind ``signal``: already loaded when Python starts, where ``signal`` itself
# builds its enums first (measured: a Ctrl-C landed inside that import, before anything was armed).
import _signal as signal
import os
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


def arm_if_console() -> None:
    """In the ``pavonine`` console script only (its ``__main__`` is the script named by
    ``sys.argv[0]``), end the process on Ctrl-C as :func:`main` does, from the first line of
    ``import pavonine`` on, before :func:`main` is reached. Other programs are left alone."""
    script = getattr(sys.modules.get("__main__"), "__file__", None)
    if not sys.argv or script != sys.argv[0] or os.path.basename(script) != "pavonine":
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupted)


def main() -> None:
    """Run ``pavonine`` with ``sys.argv``."""
    try:
        if signal.getsignal(signal.SIGINT) is _interrupted:  # armed by import pavonine
            signal.signal(signal.SIGINT, signal.default_int_handler)
        from pavonine.pipeline.cli import main as run

        run()
    except KeyboardInterrupt:  # while the command line loaded, or past its own handling
        _interrupted()
    finally:  # exiting (a SystemExit on its way): a Ctrl-C now ends the process the same way
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            signal.signal(signal.SIGINT, _interrupted)
