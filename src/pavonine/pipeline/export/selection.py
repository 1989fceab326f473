"""The asset an export reads: its root layer opened with the ``lod`` and ``geometry`` variants
asked for (selected in the session layer; the asset's own files are not touched)."""

from __future__ import annotations

from pathlib import Path

from pavonine.base.errors import InputError


def open_selected(root: Path, lod: str | None, geometry: str | None):
    """``(stage, default prim)`` of ``root`` with ``lod`` and ``geometry`` selected (``None``:
    the asset's own selection); one-line errors naming an unknown variant and the known ones."""
    from pxr import Tf, Usd

    import pavonine  # noqa: F401  (registers the schema)

    try:
        stage = Usd.Stage.Open(str(root))
    except Tf.ErrorException as exc:
        raise InputError(str(root), f"cannot open USD stage: {str(exc).strip()}") from None
    default = stage.GetDefaultPrim()
    if not default:
        raise InputError(str(root), "no defaultPrim")
    for option, name, value in (("--lod", "lod", lod), ("--geometry", "geometry", geometry)):
        if value is None:
            continue
        variants = default.GetVariantSet(name)
        if value not in variants.GetVariantNames():
            known = ", ".join(variants.GetVariantNames()) or "none"
            raise InputError(option, f"{root} has no {name} {value!r} (variants: {known})")
        with Usd.EditContext(stage, stage.GetSessionLayer()):
            variants.SetVariantSelection(value)
    return stage, default
