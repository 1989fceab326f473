"""Print constraints.txt: every distribution ``pavonine[all,dev]`` needs, pinned to the version
installed in the running environment (the one the render baselines were approved in).

    .venv/bin/python .ci/lock.py > constraints.txt      (make lock)
"""

from __future__ import annotations

import re
import sys
from importlib import metadata

try:
    from packaging.requirements import Requirement
except ImportError:  # pip's copy
    from pip._vendor.packaging.requirements import Requirement


def canonical(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def closure(root: str, extras: set[str]) -> dict[str, str]:
    """Installed name → version of ``root``'s dependencies (with ``extras``), transitively."""
    pinned: dict[str, str] = {}
    todo = [(root, frozenset(extras))]
    seen = set()
    while todo:
        name, wanted = todo.pop()
        if (canonical(name), wanted) in seen:
            continue
        seen.add((canonical(name), wanted))
        dist = metadata.distribution(name)
        if canonical(name) != canonical(root):
            pinned[dist.metadata["Name"]] = dist.version
        for text in dist.requires or []:
            req = Requirement(text)
            envs = [{"extra": e} for e in wanted] or [{"extra": ""}]
            if req.marker is not None and not any(req.marker.evaluate(env) for env in envs):
                continue
            if canonical(req.name) == canonical(root):  # pavonine[all] -> its own extras
                todo.append((root, frozenset(req.extras)))
                continue
            todo.append((req.name, frozenset(req.extras)))
    return pinned


def main() -> None:
    pins = closure("pavonine", {"all", "dev"})
    python = ".".join(map(str, sys.version_info[:3]))
    print(f"# Exact versions for `make` and CI (tested with Python {python}); regenerate with")
    print(
        "# `make lock` after changing a dependency. pip install -c constraints.txt -e '.[all,dev]'"
    )
    for name in sorted(pins, key=canonical):
        print(f"{name}=={pins[name]}")


if __name__ == "__main__":
    main()
