"""The package list for setuptools: Pavonine's code packages and the data folders inside them.

Everything else is declared in ``pyproject.toml``: ``package-dir`` puts the code under ``src/``
(each folder its import path) and the shipped data of ``assets/`` at ``pavonine.assets``;
``package-data`` names the files shipped. Python treats every folder whose name is an identifier
as a (namespace) package, so setuptools wants the folders that hold package data
(``assets/feathers/eye_feather/maps``, ``materials/data``, ...) among the packages too: without
them it printed one "Package would be ignored" warning per folder (34 of them, ~1,400 lines with
pip 26.3) and warns that a later version may leave their files out. The folders are found here,
so a new module, feather, scene or baseline needs no edit.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent


def packages_below(name: str, root: Path) -> list[str]:
    """``name`` and each folder below ``root`` whose path is made of identifiers."""
    found = [name] if name else []
    for sub in sorted(p for p in root.rglob("*") if p.is_dir()):
        parts = sub.relative_to(root).parts
        if "__pycache__" not in parts and all(part.isidentifier() for part in parts):
            found.append(".".join([name, *parts]) if name else ".".join(parts))
    return found


def packages(package_dir: dict[str, str]) -> list[str]:
    """Every package under each ``package-dir`` root; a package mapped on its own (the data
    package ``pavonine.assets``) is listed from its own folder, not from the root's."""
    found: set[str] = set()
    for name, folder in package_dir.items():
        found.update(packages_below(name, HERE / folder))
    return sorted(found)


with (HERE / "pyproject.toml").open("rb") as config:
    PACKAGE_DIR = tomllib.load(config)["tool"]["setuptools"]["package-dir"]

setup(packages=packages(PACKAGE_DIR))
