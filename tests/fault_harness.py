"""Fault-injection harness: run the real ``pavonine`` CLI in a subprocess, kill it at a named
commit step, fill its disk or cap its file size, and look at what a reader is left with.

Extend it by adding a checkpoint (``pavonine.base.faults.checkpoint("step", subject)``) to a
writer, listing the step in ``pavonine.base.faults.STEPS``, and a test in
``tests/base/test_commit.py`` that runs the command with ``fault="step"`` and checks the output
with :func:`snapshot` against the old and the new version.
"""

from __future__ import annotations

import hashlib
import os
import resource
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from pavonine.base.faults import FAULT_ENV

#: What a killed process returns (``-SIGKILL``).
KILLED = -signal.SIGKILL


@dataclass
class Run:
    """A finished CLI run."""

    returncode: int
    stdout: str
    stderr: str

    @property
    def killed(self) -> bool:
        return self.returncode == KILLED


def pavonine(
    *args: str | os.PathLike,
    fault: str | None = None,
    cwd: str | os.PathLike | None = None,
    file_size_limit: int | None = None,
    timeout: float = 300,
) -> Run:
    """Run ``python -m pavonine.apps.cli ARGS`` in a subprocess.

    ``fault``: the ``PAVONINE_FAULT`` step (``step`` or ``step@subject``) to die at.
    ``file_size_limit``: ``ulimit -f`` in bytes, with ``SIGXFSZ`` ignored so that writes past
    it fail with ``EFBIG`` instead of killing the process.
    """
    env = {k: v for k, v in os.environ.items() if k != FAULT_ENV}
    if fault is not None:
        env[FAULT_ENV] = fault
    preexec: Callable[[], None] | None = None
    if file_size_limit is not None:

        def preexec() -> None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size_limit, file_size_limit))

    command = [sys.executable, "-m", "pavonine.apps.cli", *map(str, args)]
    done = subprocess.run(
        command,
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=preexec,
    )
    return Run(done.returncode, done.stdout, done.stderr)


def snapshot(folder: str | os.PathLike, *, hidden: bool = False) -> dict[str, str]:
    """Relative path → SHA-256 of every file under ``folder`` (hidden entries only if asked)."""
    folder = Path(folder)
    found = {}
    for path in sorted(folder.rglob("*")):
        relative = path.relative_to(folder)
        if not hidden and any(part.startswith(".") for part in relative.parts):
            continue
        if path.is_file():
            found[str(relative)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return found


def hidden_entries(folder: str | os.PathLike) -> list[str]:
    """Hidden names directly in ``folder`` (staging folders, temporaries, journals)."""
    return sorted(p.name for p in Path(folder).iterdir() if p.name.startswith("."))


def version_of(state: dict[str, str], versions: dict[str, dict[str, str]]) -> str:
    """Which of ``versions`` (name → :func:`snapshot`) ``state`` is exactly; fails otherwise
    (a mix of two versions, or nothing)."""
    for name, files in versions.items():
        if state == files:
            return name
    differing = {
        name: sorted(k for k in set(state) | set(files) if state.get(k) != files.get(k))
        for name, files in versions.items()
    }
    raise AssertionError(f"neither version, files differing: {differing}")


def one_line_error(run: Run, path: str | os.PathLike, cause: str) -> None:
    """``run`` failed with exit 2 and one line ``error: PATH: ... CAUSE ...`` on stderr; other
    lines only ``warning:``/``info:`` (e.g. the converter meshing without pymeshlab)."""
    lines = [line for line in run.stderr.splitlines() if line.strip()]
    assert run.returncode == 2, run.stderr
    assert all(line.startswith(("warning: ", "info: ")) for line in lines[:-1]), run.stderr
    lines = lines[-1:]
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith(f"error: {path}"), lines[0]
    assert cause in lines[0], lines[0]
    assert "Traceback" not in run.stderr and "internal error" not in run.stderr
    assert ".pavonine-" not in lines[0], lines[0]  # never a hidden temporary's name


@contextmanager
def small_tmpfs(where: Path, size: str = "64k", *, read_only: bool = False) -> Iterator[Path]:
    """Mount a tmpfs of ``size`` at ``where`` (a full disk, or a read-only one); skips the test
    where mounting is not allowed (not root, no ``mount``, a container without the right)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root and mount(8)")
    where.mkdir(parents=True, exist_ok=True)
    options = f"size={size}" + (",ro" if read_only else "")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.decode().strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", str(where)], check=False)
