"""Test-only fault injection: named checkpoints at every commit step of the writers.

``PAVONINE_FAULT=STEP`` makes the process kill itself with ``SIGKILL`` when it reaches
``checkpoint(STEP)``; ``PAVONINE_FAULT=STEP@SUBJECT`` only where the checkpoint's subject (an
asset or scene name) is ``SUBJECT``; ``PAVONINE_FAULT=STEP#N`` (also ``STEP#N@SUBJECT``) the
``N``-th time it reaches that step (a step reached several times: between each two renames). It exists so that ``tests/base/test_commit.py`` can crash a
real ``pavonine`` process exactly between two steps of a commit and check what a reader is left
with. It is for tests only: never set it in production. When it is unset a checkpoint is one
comparison with ``None``.

The steps (``docs/reliability.md`` lists which command reaches which):

``staging.written``
    A staging folder (asset, assembly, baseline) is complete, nothing committed yet.
``folder.exchanged``
    ``renameat2(RENAME_EXCHANGE)`` swapped the new folder in; the old one, now at the staging
    name, is not yet deleted.
``folder.moving``
    Fallback order only (no ``RENAME_EXCHANGE``): half the files of the new folder are moved in.
``files.journal``
    A group of files (EXR + PNG + variance, a set of maps) is written under temporary names and
    its commit journal is on disk; nothing renamed yet.
``files.renaming``
    Between two renames of such a group: ``files.renaming`` (or ``#1``) after the first file is
    renamed into place, ``files.renaming#N`` after the ``N``-th, the others not yet.
``convert.recipe``
    A ``convert`` worker starts a recipe (subject: the asset name); kills one worker of a batch.
"""

from __future__ import annotations

import os
import signal

#: The environment variable naming the step to die at (test-only).
FAULT_ENV = "PAVONINE_FAULT"

STEPS = (
    "staging.written",
    "folder.exchanged",
    "folder.moving",
    "files.journal",
    "files.renaming",
    "convert.recipe",
)

_FAULT: str | None = os.environ.get(FAULT_ENV) or None
#: Times the step named by ``PAVONINE_FAULT`` was reached (for ``STEP#N``).
_reached = 0


def checkpoint(step: str, subject: str | None = None) -> None:
    """Die here with ``SIGKILL`` if ``PAVONINE_FAULT`` names ``step`` (and ``subject``), at the
    ``N``-th time for ``STEP#N``."""
    global _reached
    if _FAULT is None:
        return
    wanted, _, wanted_subject = _FAULT.partition("@")
    wanted, _, count = wanted.partition("#")
    if wanted == step and (not wanted_subject or wanted_subject == subject):
        _reached += 1
        if _reached >= int(count or 1):
            os.kill(os.getpid(), signal.SIGKILL)
