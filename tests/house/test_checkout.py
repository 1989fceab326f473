"""The tests leave the checkout as shipped (tests/conftest.py): an edit a test leaves in memory on a
shipped USD layer is caught, and found by name.

Why: a helper once chose the eye feather's ``barbs`` variant on the shipped root layer in memory.
Later stages of the same pytest worker that referenced the eye saw barbs where the asset says
sheet, and a later ``Usd.Stage.Save()`` (which writes every dirty layer a stage uses) wrote it into
the checkout, where the wheel built from it rendered barbs in the sheet's baseline. Whether that
happened depended on which files xdist gave to which worker.
"""

from __future__ import annotations

from pathlib import Path

from conftest import _checkout_digest, _dirty_checkout_layers

EYE = (
    Path(__file__).resolve().parents[2] / "assets" / "feathers" / "eye_feather" / "eye_feather.usd"
)


def test_an_edit_in_memory_on_a_shipped_layer_is_found():
    from pxr import Usd

    stage = Usd.Stage.Open(str(EYE))
    try:
        assert _dirty_checkout_layers() == []
        stage.GetDefaultPrim().GetVariantSet("geometry").SetVariantSelection("barbs")
        assert _dirty_checkout_layers() == [str(EYE)]
    finally:
        stage.GetRootLayer().Reload(force=True)
    assert _dirty_checkout_layers() == []


def test_the_session_layer_keeps_the_shipped_layer_clean():
    from pxr import Usd

    stage = Usd.Stage.Open(str(EYE))
    stage.SetEditTarget(stage.GetSessionLayer())
    stage.GetDefaultPrim().GetVariantSet("geometry").SetVariantSelection("barbs")
    assert stage.GetPrimAtPath("/eye_feather/Geom/Barbs")
    assert _dirty_checkout_layers() == []
    again = Usd.Stage.Open(str(EYE))  # another stage of the process sees the file as shipped
    assert again.GetDefaultPrim().GetVariantSet("geometry").GetVariantSelection() == "sheet"


def test_the_digest_sees_a_changed_file(tmp_path, monkeypatch):
    import conftest

    (tmp_path / "assets").mkdir()
    shipped = tmp_path / "assets" / "a.usda"
    shipped.write_text("#usda 1.0\n")
    monkeypatch.setattr(conftest, "REPO", str(tmp_path))
    monkeypatch.setattr(conftest, "SHIPPED", ("assets",))
    before = _checkout_digest()
    shipped.write_text("#usda 1.0\n# changed\n")
    assert _checkout_digest() != before
    assert list(before) == [str(shipped)]


def test_every_test_module_has_its_own_basename():
    """pytest imports test files by basename (``pythonpath`` lists the test folders, no
    packages): two ``test_x.py`` in two folders are a collection error in a clean run."""
    tests = Path(__file__).resolve().parents[1]
    seen: dict[str, Path] = {}
    clashes = []
    for path in sorted(tests.rglob("test_*.py")):
        if path.name in seen:
            clashes.append(f"{seen[path.name].relative_to(tests)} and {path.relative_to(tests)}")
        seen.setdefault(path.name, path)
    assert not clashes, clashes
