"""Ctrl-C in the ``pavonine`` console script: one line and exit status 130 from its first moment.

``import pavonine`` arms :func:`arm_if_console` first thing (in the console script only), and
:func:`pavonine.console.main` keeps the same handling while the command line loads, runs and
exits; ``docs/reliability.md`` says what Python's own start-up leaves.
"""

from __future__ import annotations

# The C module behind ``signal``: already loaded when Python starts, where ``signal`` itself
# builds its enums first (measured: a Ctrl-C landed inside that import, before anything was armed).
import _signal as signal
import os
import sys

#: Exit status of a command interrupted by Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130


def interrupted(*_: object) -> None:
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
        signal.signal(signal.SIGINT, interrupted)
