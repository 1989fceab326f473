"""Deep namespaces (``pavonine.base.nesting``): native recursion on a deep stack, a depth limit."""

from __future__ import annotations

import pytest
from pxr import Sdf, Usd

from pavonine.base.errors import InputError
from pavonine.base.nesting import check_nesting, deep_call, nesting_depth


def chain(depth: int) -> Usd.Stage:
    stage = Usd.Stage.CreateInMemory()
    path = Sdf.Path("/")
    for i in range(depth):
        path = path.AppendChild(f"X{i}")
    stage.DefinePrim(path, "Xform")
    return stage


def test_deep_call_returns_its_value_and_raises_its_error_here():
    assert deep_call(lambda a, b=0: a + b, 2, b=3) == 5
    with pytest.raises(KeyError, match="inner"):
        deep_call(lambda: {}["inner"])


def test_nesting_depth_is_the_deepest_path_and_the_limit_is_one_line():
    stage = chain(40)
    depth, path = nesting_depth(stage)
    assert depth == 40 and path.endswith("/X38/X39")
    assert check_nesting(stage, "s.usda", limit=40) == 40
    with pytest.raises(InputError) as error:
        check_nesting(stage, "s.usda", limit=39)
    assert "\n" not in str(error.value)
    assert "prims nested 40 deep" in str(error.value) and "limit of 39 levels" in str(error.value)
