"""The house holds (docs/house.md): the import contract in ``pyproject.toml`` is kept by the tree,
breaks on a planted upward import, and the top-level rooms import one another without a cycle,
none holding more than 35 % of the package's lines.

Imports inside functions count everywhere here (import-linter's graph, grimp, reads every import
statement), so a lazy import cannot hide an upward edge.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

import pytest

grimp = pytest.importorskip("grimp")

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "src" / "pavonine"
LINT_IMPORTS = Path(sys.executable).parent / "lint-imports"
#: The largest share of the package's lines one top-level room may hold.
MAX_SHARE = 0.35


def _lint_imports(config: Path, source_root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` with ``config``, importing ``pavonine`` from ``source_root``."""
    if not LINT_IMPORTS.exists():
        pytest.skip("import-linter is not installed (make setup installs it)")
    env = {**os.environ, "PYTHONPATH": str(source_root)}
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache", "--config", str(config)],
        capture_output=True,
        text=True,
        env=env,
        cwd=config.parent,
        timeout=300,
    )


def test_the_tree_keeps_the_import_contract():
    run = _lint_imports(REPO / "pyproject.toml", REPO / "src")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


@pytest.mark.parametrize(
    ("module", "upward"),
    [
        ("pipeline/maps/paint.py", "pavonine.render.api"),  # sibling rooms are independent
        ("base/errors.py", "pavonine.apps.cli.options"),  # the ground floor imports nothing above
        ("materials/rod.py", "pavonine.schemas.authoring"),
    ],
)
def test_a_planted_upward_import_breaks_the_contract(tmp_path, module, upward):
    """An upward import planted inside a function of a scratch copy: ``make lint``'s check fails
    and names the importing module."""
    shutil.copytree(PACKAGE, tmp_path / "src" / "pavonine", ignore=shutil.ignore_patterns("assets"))
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    planted = tmp_path / "src" / "pavonine" / module
    with planted.open("a") as f:
        f.write(f"\n\ndef _planted():\n    import {upward}\n\n    return {upward}\n")
    run = _lint_imports(tmp_path / "pyproject.toml", tmp_path / "src")
    assert run.returncode != 0, run.stdout
    importer = "pavonine." + module.removesuffix(".py").replace("/", ".")
    assert f"{importer} -> {upward}" in run.stdout, run.stdout


def _rooms() -> dict[str, int]:
    """Top-level rooms of the package (sub-packages and modules) → their lines of Python."""
    rooms: dict[str, int] = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE).parts
        if parts == ("__init__.py",):
            continue
        room = "pavonine." + parts[0].removesuffix(".py")
        rooms[room] = rooms.get(room, 0) + len(path.read_text().splitlines())
    return rooms


def test_the_rooms_import_one_another_without_a_cycle_and_none_is_too_big():
    rooms = _rooms()
    graph = grimp.build_graph("pavonine", cache_dir=None)
    edges: dict[str, set[str]] = {room: set() for room in rooms}
    for importer in graph.modules:
        for imported in graph.find_modules_directly_imported_by(importer):
            a, b = (".".join(m.split(".")[:2]) for m in (importer, imported))
            if a != b and a in rooms and b in rooms:
                edges[a].add(b)
    try:
        order = list(TopologicalSorter(edges).static_order())
    except CycleError as exc:
        pytest.fail(f"the rooms import one another in a cycle: {exc.args[1]}")
    assert order[0] == "pavonine.base", order  # the ground floor comes first
    total = sum(rooms.values())
    too_big = {room: n / total for room, n in rooms.items() if n / total > MAX_SHARE}
    assert not too_big, too_big
