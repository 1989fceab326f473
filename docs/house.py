"""Draw docs/images/house.png: the floors of the import contract (``pyproject.toml``), each room
with its sub-packages and lines, and the imports between rooms as they are in the code (grimp's
graph, imports inside functions included).

    .venv/bin/python docs/house.py            # rewrites docs/images/house.png
"""

from __future__ import annotations

import tomllib
from collections import Counter
from pathlib import Path

import grimp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "src" / "pavonine"


def floors() -> list[list[str]]:
    """The contract's layers, top first, each a list of its independent rooms."""
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]
    layers = config["contracts"][0]["layers"]
    return [[room.strip() for room in layer.split("|")] for layer in layers]


def lines_of(room: str) -> tuple[int, list[tuple[str, int]]]:
    """Lines of Python in ``room`` and per sub-package (or module), largest first."""
    path = PACKAGE / room
    if path.with_suffix(".py").is_file():
        n = len(path.with_suffix(".py").read_text().splitlines())
        return n, []
    parts: Counter[str] = Counter()
    for f in path.rglob("*.py"):
        rel = f.relative_to(path).parts
        key = rel[0].removesuffix(".py") if len(rel) > 1 else "(modules)"
        parts[key] += len(f.read_text().splitlines())
    return sum(parts.values()), parts.most_common()


def room_edges() -> Counter[tuple[str, str]]:
    """(importer room, imported room) → number of module-to-module imports."""
    graph = grimp.build_graph("pavonine", cache_dir=None)
    edges: Counter[tuple[str, str]] = Counter()
    for importer in graph.modules:
        for imported in graph.find_modules_directly_imported_by(importer):
            a, b = (m.split(".")[1] if m.count(".") else "" for m in (importer, imported))
            if a and b and a != b:
                edges[(a, b)] += 1
    return edges


def draw(out: Path) -> None:
    """Write the drawing to ``out``."""
    layout = floors()
    total = sum(lines_of(room)[0] for floor in layout for room in floor)
    fig, ax = plt.subplots(figsize=(12, 9), dpi=110)
    ax.set_xlim(0, 12)
    ax.set_ylim(0, len(layout) * 1.5 + 0.3)
    ax.axis("off")
    centre: dict[str, tuple[float, float]] = {}
    for level, floor in enumerate(layout):
        y = (len(layout) - 1 - level) * 1.5 + 0.3
        ax.text(0.05, y + 0.55, f"floor {len(layout) - level}", fontsize=9, color="0.4")
        width = 10.6 / len(floor)
        for k, room in enumerate(floor):
            x = 1.2 + k * width
            n, parts = lines_of(room)
            ax.add_patch(
                FancyBboxPatch(
                    (x, y), width - 0.3, 1.1, boxstyle="round,pad=0.02", fc="#eef3f8", ec="#33506e"
                )
            )
            ax.text(
                x + 0.1,
                y + 0.85,
                f"pavonine.{room}   {n:,} lines ({100 * n / total:.0f} %)",
                fontsize=10,
                weight="bold",
            )
            inside = ", ".join(f"{name} {count:,}" for name, count in parts[:9])
            if len(parts) > 9:
                inside += ", …"
            ax.text(x + 0.1, y + 0.2, _wrap(inside, int(width * 11)), fontsize=7.5, va="bottom")
            centre[room] = (x + (width - 0.3) / 2, y)
    for (a, b), count in sorted(room_edges().items()):
        if a not in centre or b not in centre:
            continue
        (xa, ya), (xb, yb) = centre[a], centre[b]
        upward = yb > ya
        ax.add_patch(
            FancyArrowPatch(
                (xa + 0.15, ya),
                (xb - 0.15, yb + 1.1),
                arrowstyle="-|>",
                mutation_scale=8,
                lw=0.4 + 0.02 * min(count, 60),
                color="#c0392b" if upward else "#7a8ea3",
                alpha=0.7,
                connectionstyle="arc3,rad=0.08",
            )
        )
    ax.set_title(
        "The house: rooms on floors, arrows = imports in the code (red would run upward)",
        fontsize=12,
    )
    fig.savefig(out, bbox_inches="tight")


def _wrap(text: str, width: int) -> str:
    words, lines, line = text.split(" "), [], ""
    for word in words:
        if len(line) + len(word) + 1 > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}".strip()
    return "\n".join([*lines, line])


if __name__ == "__main__":
    draw(REPO / "docs" / "images" / "house.png")
