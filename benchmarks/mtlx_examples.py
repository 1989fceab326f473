"""Render the example materials MaterialX ships on a sphere and a plane, and check every input.

Usage::

    python benchmarks/mtlx_examples.py /path/to/MaterialX -o out/mtlx_examples [--size 96]
        [--spp 16] [--only TEXT]

``/path/to/MaterialX`` is a checkout of AcademySoftwareFoundation/MaterialX (Apache-2.0): its
``resources/Materials/Examples/StandardSurface`` and ``.../OpenPbr`` documents are read from there
(textures from ``resources/Images``), never copied into this repository.

usd-core has no usdMtlx, so each ``surfacematerial`` of each document is translated into UsdShade
by the renderer's own reader of referenced ``.mtlx`` documents
(:mod:`pavonine.render.shading.mtlx_documents`), with the ``MaterialX`` Python package, as
usdMtlx does: one ``Shader`` per node with ``info:id`` = its node definition (``ND_standard_surface_surfaceshader``, ``ND_tiledimage_color3``,
...), one ``NodeGraph`` per node graph (its outputs and interface inputs), file names resolved
through the document's ``fileprefix``, colour spaces kept on the file inputs, and the surface on
``outputs:mtlx:surface`` (a displacement on ``outputs:mtlx:displacement``). The material is bound to
a UV sphere (the plane under it is neutral grey), lit by a sun and a sky, seen by a camera; each
stage is rendered by ``benchmarks/usd_suites.py``'s worker and judged by its checks (runs, coverage,
lit, texture, supported), plus one of its own:

* ``inputs``: every input the document authors on the surface node is translated (an input of
  :mod:`pavonine.render.shading.materialx`'s lobe table) or named in a warning — never dropped.

Prints the results table (material, passes, warnings) and writes ``report.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import usd_suites

FOLDERS = ("resources/Materials/Examples/StandardSurface", "resources/Materials/Examples/OpenPbr")


# -- MaterialX → UsdShade ----------------------------------------------------------------------


def translate(doc, stage, material_name: str, root: str = "/Looks"):
    """The UsdShade Material for ``doc``'s ``surfacematerial`` ``material_name``: the renderer's
    own usdMtlx-like translation (:func:`pavonine.render.shading.mtlx_documents.translate`)."""
    from pavonine.render.shading.mtlx_documents import translate as usd_mtlx

    return usd_mtlx(doc, stage, material_name, root)


# -- the stage --------------------------------------------------------------------------------------


def uv_sphere(stage, path: str, radius: float = 1.0, rows: int = 48, cols: int = 96):
    """A UV sphere mesh (st: u around, v from the south pole up) with vertex normals."""
    from pxr import Sdf, UsdGeom

    theta = np.linspace(0.0, math.pi, rows + 1)  # from the north pole
    phi = np.linspace(0.0, 2.0 * math.pi, cols + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    normals = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1)
    st = np.stack([p / (2 * math.pi), 1.0 - t / math.pi], axis=-1)
    index = np.arange((rows + 1) * (cols + 1)).reshape(rows + 1, cols + 1)
    quads = np.stack(
        [index[:-1, :-1], index[1:, :-1], index[1:, 1:], index[:-1, 1:]], axis=-1
    ).reshape(-1, 4)
    mesh = UsdGeom.Mesh.Define(stage, path)
    mesh.CreatePointsAttr((radius * normals).reshape(-1, 3).tolist())
    mesh.CreateFaceVertexCountsAttr([4] * len(quads))
    mesh.CreateFaceVertexIndicesAttr(quads.ravel().tolist())
    mesh.CreateSubdivisionSchemeAttr("none")
    mesh.CreateNormalsAttr(normals.reshape(-1, 3).tolist())
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    primvar = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
        "st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex
    )
    primvar.Set(st.reshape(-1, 2).tolist())
    return mesh


def write_stage(doc, material_name: str, path: Path) -> None:
    """The sphere-and-plane stage with ``material_name`` bound to the sphere."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    sphere = uv_sphere(stage, "/World/Sphere")
    plane = UsdGeom.Mesh.Define(stage, "/World/Plane")
    plane.CreatePointsAttr([(-4, -1, -4), (-4, -1, 4), (4, -1, 4), (4, -1, -4)])
    plane.CreateFaceVertexCountsAttr([4])
    plane.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    plane.CreateSubdivisionSchemeAttr("none")
    material = translate(doc, stage, material_name)
    grey = UsdShade.Material.Define(stage, "/Looks/Ground")
    surface = UsdShade.Shader.Define(stage, "/Looks/Ground/Surface")
    surface.SetShaderId("UsdPreviewSurface")
    surface.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.18))
    grey.CreateSurfaceOutput().ConnectToSource(surface.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(sphere.GetPrim()).Bind(material)
    UsdShade.MaterialBindingAPI.Apply(plane.GetPrim()).Bind(grey)
    camera = UsdGeom.Camera.Define(stage, "/World/Camera")
    camera.CreateFocalLengthAttr(50.0)
    camera.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.6, 6.0))
    camera.AddRotateXOp().Set(-6.0)
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.CreateIntensityAttr(math.pi)
    sun.CreateAngleAttr(0.53)
    sun.CreateNormalizeAttr(True)
    sun.AddRotateXYZOp().Set(Gf.Vec3f(-45.0, 30.0, 0.0))
    sky = UsdLux.DomeLight.Define(stage, "/World/Sky")
    sky.CreateIntensityAttr(0.3)
    stage.GetRootLayer().documentation = f"MaterialX example {doc.getSourceUri()} ({material_name})"
    stage.Save()


def documents(root: Path) -> list[Path]:
    """The example documents under a MaterialX checkout, sorted."""
    found = []
    for folder in FOLDERS:
        found.extend(sorted((root / folder).glob("*.mtlx")))
    return found


def materials_of(path: Path):
    """(document with the standard libraries, its surfacematerial names)."""
    import MaterialX as mx

    from pavonine.materials import materialx

    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(path))
    doc.importLibrary(materialx.load_libraries())
    return doc, [m.getName() for m in doc.getMaterialNodes()]


def authored_surface_inputs(doc, material_name: str) -> tuple[str, list[str]]:
    """(surface node id, the inputs the document authors on it that matter: connected, or set
    to a value other than the node definition's default)."""
    node = doc.getNode(material_name).getInput("surfaceshader").getConnectedNode()
    nodedef = node.getNodeDef()
    names = []
    for inp in node.getInputs():
        default = nodedef.getActiveInput(inp.getName())
        connected = inp.getNodeName() or inp.getNodeGraphString() or inp.getInterfaceName()
        if connected or default is None or not _same(inp.getValue(), default.getValue()):
            names.append(inp.getName())
    return nodedef.getName(), names


def _same(a, b) -> bool:
    """Two MaterialX values are equal (numbers and vectors compared as floats)."""
    try:
        return bool(
            np.allclose(
                np.asarray(
                    list(a) if hasattr(a, "__iter__") and not isinstance(a, str) else a, dtype=float
                ),
                np.asarray(
                    list(b) if hasattr(b, "__iter__") and not isinstance(b, str) else b, dtype=float
                ),
            )
        )
    except (TypeError, ValueError):
        return a == b


def dropped_inputs(node_id: str, names: list[str], warnings: list[str]) -> list[str]:
    """Inputs neither translated (the lobe table) nor named in any warning."""
    from pavonine.render.shading.materialx import SURFACES, Layout

    layout = SURFACES.get(node_id)
    translated = {getattr(layout, f) for f in Layout.__dataclass_fields__} if layout else set()
    return [
        n
        for n in names
        if n not in translated and not any(f"{n} " in w or f"'{n}'" in w for w in warnings)
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument(
        "materialx", type=Path, help="a checkout of AcademySoftwareFoundation/MaterialX"
    )
    parser.add_argument("-o", "--output", type=Path, default=Path("out/mtlx_examples"))
    parser.add_argument("--size", type=int, default=96, help="image width (default 96)")
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--only", default=None, help="only documents whose name contains this")
    parser.add_argument(
        "--table", type=Path, nargs="*", help="print the table of earlier runs' report.json files"
    )
    args = parser.parse_args(argv)
    if args.table:
        rows = {}
        for report in args.table:
            rows.update({r["material"]: r for r in json.loads(report.read_text())})
        print_table(sorted(rows.values(), key=lambda r: r["material"]))
        return 0
    paths = [p for p in documents(args.materialx) if not args.only or args.only in p.name]
    if not paths:
        print(
            f"error: {args.materialx}: no MaterialX example documents under {FOLDERS}",
            file=sys.stderr,
        )
        return 2
    rows = []
    for path in paths:
        doc, names = materials_of(path)
        for name in names:
            stem = f"{path.stem}__{name}" if len(names) > 1 else path.stem
            stage_path = args.output / "stages" / f"{stem}.usda"
            stage_path.parent.mkdir(parents=True, exist_ok=True)
            try:
                write_stage(doc, name, stage_path)
            except ValueError as exc:
                rows.append(
                    {"material": stem, "checks": {"translates": False}, "warnings": [str(exc)]}
                )
                continue
            out = args.output / "renders" / stem
            metrics = usd_suites.run_one(stage_path, out, args)
            outcome = usd_suites.checks(metrics)
            node_id, authored = authored_surface_inputs(doc, name)
            warned = metrics.get("warnings", [])
            dropped = dropped_inputs(node_id, authored, warned)
            outcome["inputs"] = not dropped if outcome.get("runs") else None
            rows.append(
                {
                    "material": stem,
                    "surface": node_id,
                    "checks": outcome,
                    "dropped": dropped,
                    "warnings": warned,
                    "out": str(out),
                    "detail": metrics.get("detail", ""),
                }
            )
            failed = [k for k, ok in outcome.items() if ok is False]
            print(
                f"{'PASS' if not failed else 'FAIL'} {stem} {' '.join(failed)}",
                file=sys.stderr,
                flush=True,
            )
    print_table(rows)
    (args.output / "report.json").write_text(json.dumps(rows, indent=1, default=str))
    return 0


def print_table(rows: list[dict]) -> None:
    """The docs/render.md table: material, checks passed, the warnings it gives (short)."""
    print("| material | passes | warnings |\n|---|---|---|")
    for row in rows:
        checks = row["checks"]
        passed = [k for k, ok in checks.items() if ok]
        failed = [k for k, ok in checks.items() if ok is False]
        marks = f"{len(passed)}/{len(passed) + len(failed)}" + (
            f" (fails: {', '.join(failed)})" if failed else ""
        )
        print(f"| {row['material']} | {marks} | {summary(row['warnings'])} |")
    total = sum(not [k for k, ok in r["checks"].items() if ok is False] for r in rows)
    print(f"\n{total}/{len(rows)} materials pass every check")


UNTRANSLATED = " is not translated to Mitsuba's principled BSDF"


def summary(warnings: list[str]) -> str:
    """Warnings in short: the untranslated inputs by name, then every other message once
    (without the prim path's material prefix: the table names the material)."""
    names = sorted(
        {w.split(": ", 1)[-1].split(UNTRANSLATED)[0] for w in warnings if UNTRANSLATED in w}
    )
    others = sorted({_short(w) for w in warnings if UNTRANSLATED not in w})
    parts = ([f"not translated: {', '.join(names)}"] if names else []) + others
    return "; ".join(parts) or "none"


def _short(warning: str) -> str:
    """A warning with its prim path cut to the last element."""
    where, _, message = warning.partition(": ")
    return f"{where.rsplit('/', 1)[-1]}: {message}" if message else warning


if __name__ == "__main__":
    sys.exit(main())
