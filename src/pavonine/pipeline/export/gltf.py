"""``pavonine export``: a feather asset as a glTF 2.0 binary (``.glb``), written with pygltflib.

One glTF node per mesh of the chosen LOD (render or default purpose), positions in metres
(``metersPerUnit``), +Y up, vertices split along the ``st`` atlas seams (glTF has one index per
vertex), ``TEXCOORD_0`` = ``st`` with ``v`` flipped (glTF's origin is the image's top left),
normals, and per material:

* the feather material (``PavonineFeatherAPI``, baked): the look fitted to the model's BRDF
  by :mod:`pavonine.pipeline.export.look` (a base colour, a film and a roughness per texel) for
  one viewer, the ``eye`` given or where ``pavonine view`` frames the asset, face-on and turned
  about the vertical through the asset's centre (recorded in ``asset.extras.pavonine``, metres):
  ``baseColorTexture`` = the fitted base (sRGB colour, linear alpha = the baked opacity),
  ``alphaMode`` ``MASK`` with ``alphaCutoff`` = the preview's ``opacityThreshold``,
  ``metallicRoughnessTexture`` (G = fitted roughness, B = metallic 0), double-sided,
  ``KHR_materials_specular``: factor 1, ``specularColorTexture`` = the fitted substrate's F0 over
  ``[0, SUBSTRATE_F0_MAX]`` (sRGB, as the extension stores it) times ``specularColorFactor``
  ``SUBSTRATE_F0_MAX / 0.04`` (glTF's F0 at its default index 1.5), and
  ``KHR_materials_iridescence``: factor 1 with ``iridescenceTexture`` R = the film's weight,
  ``iridescenceThicknessTexture`` G = its thickness over ``[0, 1000]`` nm (a ``NEAREST``
  sampler, neither mipmaps nor interpolation: a mean thickness would draw a colour of its own)
  and the fitted ``iridescenceIor`` (glTF has one index per material);
* any other material with a UsdPreviewSurface: its constant ``diffuseColor`` (linear, as glTF's
  ``baseColorFactor``), ``roughness`` and ``metallic``.

The baked textures are read from the materials' own networks (the preview's ``BakedColor`` and
``BakedRoughness``, the preview-purpose material's film images), through USD's asset resolver:
they must be there (the asset is baked), and give the atlas resolution.
"""

from __future__ import annotations

import logging
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from pavonine import LOGGER_NAME
from pavonine.base.commit import atomic_path
from pavonine.base.errors import InputError
from pavonine.materials import colour
from pavonine.materials.display import srgb_encode
from pavonine.pipeline.bake.asset import bound_meshes, mesh_data, root_layer_path
from pavonine.pipeline.bake.textures import THICKNESS_MAX_NM
from pavonine.pipeline.export.iridescence import SUBSTRATE_F0_MAX
from pavonine.pipeline.export.look import fitted_look
from pavonine.pipeline.export.ribbons import Tessellate
from pavonine.pipeline.export.selection import open_selected

IRIDESCENCE = "KHR_materials_iridescence"
SPECULAR = "KHR_materials_specular"
GENERATOR = "pavonine (pipeline/export/gltf.py, pygltflib)"
#: glTF's dielectric F0 at its default index 1.5, which ``specularColorFactor`` scales.
DEFAULT_F0 = 0.04


@dataclass
class ExportReport:
    """What :func:`export_gltf` wrote."""

    asset: str
    output: str
    lod: str | None
    meshes: list[dict] = field(default_factory=list)
    materials: list[str] = field(default_factory=list)
    bytes: int = 0
    eye: list[float] = field(default_factory=list)
    pivot: list[float] = field(default_factory=list)

    def as_dict(self) -> dict:
        return asdict(self)


class _Binary:
    """A glTF document and its binary chunk, built up piece by piece."""

    def __init__(self):
        import pygltflib as gl

        self.gl = gl
        self.doc = gl.GLTF2(asset=gl.Asset(generator=GENERATOR, version="2.0"))
        self.blob = bytearray()
        # 0: mipmapped; 1 (the film's weight and thickness): nearest, neither mipmaps nor
        # interpolation, since a mean thickness draws a colour of its own, not the mean of its
        # texels' colours
        for magnify, minify in ((gl.LINEAR, gl.LINEAR_MIPMAP_LINEAR), (gl.NEAREST, gl.NEAREST)):
            self.doc.samplers.append(
                gl.Sampler(
                    magFilter=magnify,
                    minFilter=minify,
                    wrapS=gl.CLAMP_TO_EDGE,
                    wrapT=gl.CLAMP_TO_EDGE,
                )
            )

    def view(self, data: bytes, target: int | None = None) -> int:
        while len(self.blob) % 4:
            self.blob.append(0)
        view = self.gl.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(data))
        if target is not None:
            view.target = target
        self.blob.extend(data)
        self.doc.bufferViews.append(view)
        return len(self.doc.bufferViews) - 1

    def accessor(self, values: np.ndarray, kind: str, target: int, bounds: bool = False) -> int:
        gl = self.gl
        component = gl.UNSIGNED_INT if values.dtype == np.uint32 else gl.FLOAT
        accessor = gl.Accessor(
            bufferView=self.view(np.ascontiguousarray(values).tobytes(), target),
            componentType=component,
            count=len(values),
            type=kind,
        )
        if bounds:
            accessor.min = values.min(axis=0).astype(float).tolist()
            accessor.max = values.max(axis=0).astype(float).tolist()
        self.doc.accessors.append(accessor)
        return len(self.doc.accessors) - 1

    def texture(self, png: bytes, name: str, filtered: bool = True) -> int:
        gl = self.gl
        self.doc.images.append(gl.Image(bufferView=self.view(png), mimeType=gl.IMAGEPNG, name=name))
        sampler = 0 if filtered else 1
        self.doc.textures.append(gl.Texture(sampler=sampler, source=len(self.doc.images) - 1))
        return len(self.doc.textures) - 1

    def save(self, path: Path) -> None:
        self.doc.buffers.append(self.gl.Buffer(byteLength=len(self.blob)))
        self.doc.set_binary_blob(bytes(self.blob))
        self.doc.save_binary(str(path))


def _png(rgb: np.ndarray, encode=None) -> bytes:
    """An 8-bit PNG of ``rgb`` (``[row, column, channel]`` in [0, 1]), raw data (no colour tag);
    ``encode`` (e.g. sRGB) applies to the first three channels."""
    import OpenImageIO as oiio

    if encode is not None:
        rgb = np.concatenate([encode(rgb[..., :3]), rgb[..., 3:]], axis=-1)
    pixels = np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)
    height, width, channels = pixels.shape
    with tempfile.TemporaryDirectory(prefix="pavonine-gltf-") as tmp:
        path = os.path.join(tmp, "texture.png")
        buf = oiio.ImageBuf(oiio.ImageSpec(width, height, channels, oiio.UINT8))
        buf.set_pixels(oiio.ROI(0, width, 0, height), pixels)
        if not buf.write(path):
            raise OSError(f"cannot encode a PNG: {buf.geterror()}")
        return Path(path).read_bytes()


def _texture_file(shader_input) -> str | None:
    """The resolved file of the image feeding ``shader_input`` (through one remap, say);
    ``None`` when no image does. An image authored but not found is an :class:`InputError`
    naming the file (anchored to the layer that authors it) and the shader's ``inputs:file``."""
    from pxr import UsdShade

    from pavonine.schemas.authoring import anchored_path

    seen = 0
    current = shader_input
    while current and current.HasConnectedSource() and seen < 4:
        shader = UsdShade.Shader(current.GetConnectedSources()[0][0].source.GetPrim())
        file = shader.GetInput("file")
        value = file.Get() if file else None
        if value is not None:
            if value.path and not value.resolvedPath:
                attr = file.GetAttr()
                where = f"{anchored_path(attr, value.path)}: {attr.GetPath()}"
                raise InputError(where, "baked texture not found; run pavonine bake")
            return value.resolvedPath or None
        current = shader.GetInput("in")
        seen += 1
    return None


def _surface(material, context: str = ""):
    from pxr import UsdShade

    output = material.GetSurfaceOutput(context)
    if not output or not output.HasConnectedSource():
        return None
    return UsdShade.Shader(output.GetConnectedSources()[0][0].source.GetPrim())


def _feather_material(
    out: _Binary, material, portable, name: str, meshes: list, viewer: tuple
) -> int:
    """The glTF material of a baked feather material (see the module docstring), fitted for the
    ``viewer`` (eye, pivot: :func:`~pavonine.pipeline.export.look.look_targets`)."""
    from pavonine.pipeline.bake.textures import read_data_textures

    gl = out.gl
    preview = _surface(material)
    film = _surface(portable, "mtlx") if portable else None
    where = str(material.GetPath())
    files = {
        "base_color": _texture_file(preview.GetInput("diffuseColor")) if preview else None,
        "roughness": _texture_file(preview.GetInput("roughness")) if preview else None,
    }
    for key, input_name in (
        ("film_thickness", "thin_film_thickness"),
        ("film_ior", "thin_film_ior"),
        ("film_weight", "thin_film_weight"),
    ):
        files[key] = _texture_file(film.GetInput(input_name)) if film else None
    missing = sorted(k for k, v in files.items() if not v)
    if missing:
        raise InputError(where, f"no baked textures ({', '.join(missing)}); run pavonine bake")
    data = read_data_textures(files)
    threshold = preview.GetInput("opacityThreshold")
    cutoff = float(threshold.Get()) if threshold and threshold.Get() else 0.5
    look = fitted_look(material, meshes, data["roughness"].shape[0], *viewer)
    base = _png(look.base_rgba, colour.display_encode)
    zeros = np.zeros_like(look.weight)
    rough = out.texture(_png(np.stack([zeros, look.roughness, zeros], -1)), f"{name} roughness")
    iridescence = out.texture(
        _png(np.stack([look.weight, look.thickness_nm / THICKNESS_MAX_NM, zeros], -1)),
        f"{name} iridescence",
        filtered=False,
    )
    substrate = out.texture(
        _png(look.substrate / SUBSTRATE_F0_MAX, srgb_encode), f"{name} substrate"
    )
    specular = {
        "specularFactor": 1.0,
        "specularColorFactor": [SUBSTRATE_F0_MAX / DEFAULT_F0] * 3,
        "specularColorTexture": {"index": substrate},
    }
    extension = {
        "iridescenceFactor": 1.0,
        "iridescenceTexture": {"index": iridescence},
        "iridescenceIor": look.film_ior,
        "iridescenceThicknessMinimum": 0.0,
        "iridescenceThicknessMaximum": THICKNESS_MAX_NM,
        "iridescenceThicknessTexture": {"index": iridescence},
    }
    out.doc.materials.append(
        gl.Material(
            name=name,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorTexture=gl.TextureInfo(index=out.texture(base, f"{name} base colour")),
                metallicFactor=0.0,
                roughnessFactor=1.0,
                metallicRoughnessTexture=gl.TextureInfo(index=rough),
            ),
            alphaMode=gl.MASK,
            alphaCutoff=cutoff,
            doubleSided=True,
            extensions={IRIDESCENCE: extension, SPECULAR: specular},
        )
    )
    return len(out.doc.materials) - 1


def _preview_material(out: _Binary, material, name: str) -> int:
    """A glTF material from a UsdPreviewSurface's constants (a warning-free subset)."""
    gl = out.gl
    shader = _surface(material)

    def constant(input_name: str, fallback):
        inp = shader.GetInput(input_name) if shader else None
        value = inp.Get() if inp and not inp.HasConnectedSource() else None
        return fallback if value is None else value

    colour = [float(c) for c in constant("diffuseColor", (0.18, 0.18, 0.18))]
    out.doc.materials.append(
        gl.Material(
            name=name,
            pbrMetallicRoughness=gl.PbrMetallicRoughness(
                baseColorFactor=[*colour, 1.0],
                metallicFactor=float(constant("metallic", 0.0)),
                roughnessFactor=float(constant("roughness", 0.5)),
            ),
            doubleSided=True,
        )
    )
    return len(out.doc.materials) - 1


def _split_vertices(mesh) -> tuple[np.ndarray, np.ndarray]:
    """glTF vertices (one per distinct (vertex, st) pair) as indices into the welded vertices
    and ``st``, and the triangles over them."""
    corners = np.stack([mesh.faces.ravel(), mesh.st_indices], axis=1)
    pairs, triangles = np.unique(corners, axis=0, return_inverse=True)
    return pairs, triangles.reshape(-1).astype(np.uint32)


def _export_ribbons(
    out, prim, cache, default, scale, materials, report, children, tessellate
) -> None:
    """One glTF mesh of a ribbon ``BasisCurves`` prim: its triangles as ``tessellate`` draws
    them, normals and displayColor as ``COLOR_0``, with a vertex-colour material from its
    preview-purpose binding."""
    from pxr import UsdGeom, UsdShade

    from pavonine.pipeline.export.ribbons import ribbon_prim_mesh, vertex_colour_material

    purpose = UsdGeom.Imageable(prim).ComputePurpose()
    if tessellate is None:
        raise InputError(str(prim.GetPath()), "ribbon curves need the renderer's tessellation")
    found = ribbon_prim_mesh(prim, tessellate)
    if found is None or purpose not in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render):
        return
    ribbons, colours = found
    gl = out.gl
    matrix = np.array(cache.ComputeRelativeTransform(prim, default)[0], dtype=np.float64)
    points = ribbons.points @ matrix[:3, :3] + matrix[3, :3]
    normals = ribbons.normals @ np.linalg.inv(matrix[:3, :3]).T
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-20)
    binding = UsdShade.MaterialBindingAPI(prim)
    preview, _ = binding.ComputeBoundMaterial(UsdShade.Tokens.preview)
    key = f"{preview.GetPath()}#vertexColor" if preview else "#vertexColor"
    if key not in materials:
        name = preview.GetPrim().GetName() if preview else prim.GetName()
        materials[key] = vertex_colour_material(out, preview, name)
        report.materials.append(key.split("#")[0] or prim.GetName())
    attributes = gl.Attributes(
        POSITION=out.accessor((points * scale).astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER, True),
        NORMAL=out.accessor(normals.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER),
    )
    if colours is not None:
        attributes.COLOR_0 = out.accessor(
            np.clip(colours, 0.0, 1.0).astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER
        )
    primitive = gl.Primitive(
        attributes=attributes,
        indices=out.accessor(ribbons.triangles.ravel(), gl.SCALAR, gl.ELEMENT_ARRAY_BUFFER),
        material=materials[key],
    )
    out.doc.meshes.append(gl.Mesh(name=prim.GetName(), primitives=[primitive]))
    out.doc.nodes.append(gl.Node(name=prim.GetName(), mesh=len(out.doc.meshes) - 1))
    children.append(len(out.doc.nodes) - 1)
    report.meshes.append(
        {
            "path": str(prim.GetPath()),
            "vertices": len(ribbons.points),
            "triangles": len(ribbons.triangles),
        }
    )


def _warn_moved_meshes(meshes: list, cache) -> None:
    """Warn, naming them, about feather meshes a transform moves: the look is fitted at their
    own points (:func:`~pavonine.pipeline.export.look.look_targets`), the eye is in the asset's
    space, so their fitted views are off by that transform."""
    moved = [
        str(m.GetPath())
        for m in meshes
        if not np.allclose(np.array(cache.GetLocalToWorldTransform(m)), np.eye(4))
    ]
    if moved:
        logging.getLogger(LOGGER_NAME).warning(
            "%s: transformed; the glTF look is fitted in the mesh's own space, not the asset's "
            "where the eye is, so its colours are fitted for another view",
            ", ".join(moved),
        )


def fit_viewer(stage, eye=None) -> tuple[np.ndarray, np.ndarray]:
    """The eye the feather's look is fitted for (``eye``, else where ``pavonine view`` frames the
    stage) and the centre of the stage's bound it turns about (world space and units); an eye
    inside that bound is refused."""
    from pavonine.pipeline.export.framing import framing, stage_bound

    lo, hi = stage_bound(stage)
    framed, centre, _ = framing(lo, hi)
    if eye is None:
        return framed, centre
    eye = np.asarray(eye, dtype=np.float64)
    if np.all((lo <= eye) & (eye <= hi)):
        box = " – ".join(str(tuple(round(float(v), 3) for v in c)) for c in (lo, hi))
        raise InputError("--eye", f"{tuple(eye.tolist())} is inside the asset's bounds {box}")
    return eye, centre


def export_gltf(
    asset: str | os.PathLike,
    output: str | os.PathLike,
    lod: str | None = None,
    geometry: str | None = None,
    eye: tuple[float, float, float] | None = None,
    tessellate: Tessellate | None = None,
):
    """Write ``asset``'s meshes of ``lod`` (default: the asset's selection) to ``output``;
    ``geometry`` chooses the asset's ``geometry`` variant (``barbs``: the barbs as ribbon meshes
    drawn by ``tessellate``, the renderer's, :mod:`pavonine.pipeline.export.ribbons`); ``eye``
    (the asset's space and units) is the viewer the feather's look is fitted for (default: where
    ``pavonine view`` frames the asset)."""
    from pxr import Usd, UsdGeom, UsdShade

    root = root_layer_path(asset)
    output = Path(output)
    if output.suffix.lower() != ".glb":
        raise InputError(
            str(output), "the export must be a .glb file or a USD layer (.usd, .usdc, .usda)"
        )
    stage, default = open_selected(root, lod, geometry)
    variants = default.GetVariantSet("lod")
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y:
        raise InputError(str(root), "only +Y-up assets are exported (glTF is +Y up)")
    scale = UsdGeom.GetStageMetersPerUnit(stage)
    fit_eye, pivot = fit_viewer(stage, eye)
    out = _Binary()
    gl = out.gl
    report = ExportReport(str(root), str(output), variants.GetVariantSelection() or None)
    report.eye, report.pivot = fit_eye.tolist(), pivot.tolist()
    cache = UsdGeom.XformCache()
    materials: dict[str, int] = {}
    children = []
    for prim in Usd.PrimRange(default):
        if prim.IsA(UsdGeom.BasisCurves):
            _export_ribbons(
                out, prim, cache, default, scale, materials, report, children, tessellate
            )
            continue
        if not prim.IsA(UsdGeom.Mesh):
            continue
        purpose = UsdGeom.Imageable(prim).ComputePurpose()
        if purpose not in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render):
            continue
        mesh = mesh_data(prim)
        matrix = np.array(cache.ComputeRelativeTransform(prim, default)[0], dtype=np.float64)
        pairs, triangles = _split_vertices(mesh)
        points = mesh.points[pairs[:, 0]] @ matrix[:3, :3] + matrix[3, :3]
        normals = mesh.normals[pairs[:, 0]] @ np.linalg.inv(matrix[:3, :3]).T
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-20)
        st = mesh.st_values[pairs[:, 1]]
        texcoords = np.stack([st[:, 0], 1.0 - st[:, 1]], axis=1)
        bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        key = str(bound.GetPath()) if bound else ""
        if key and key not in materials:
            name = bound.GetPrim().GetName()
            if "PavonineFeatherAPI" in bound.GetPrim().GetAppliedSchemas():
                preview, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial(
                    UsdShade.Tokens.preview
                )
                meshes = bound_meshes(stage, default, bound)
                _warn_moved_meshes(meshes, cache)
                materials[key] = _feather_material(
                    out, bound, preview, name, meshes, (fit_eye, pivot)
                )
            else:
                materials[key] = _preview_material(out, bound, name)
            report.materials.append(key)
        attributes = gl.Attributes(
            POSITION=out.accessor(
                (points * scale).astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER, True
            ),
            NORMAL=out.accessor(normals.astype(np.float32), gl.VEC3, gl.ARRAY_BUFFER),
            TEXCOORD_0=out.accessor(texcoords.astype(np.float32), gl.VEC2, gl.ARRAY_BUFFER),
        )
        primitive = gl.Primitive(
            attributes=attributes,
            indices=out.accessor(triangles, gl.SCALAR, gl.ELEMENT_ARRAY_BUFFER),
            material=materials.get(key),
        )
        out.doc.meshes.append(gl.Mesh(name=prim.GetName(), primitives=[primitive]))
        out.doc.nodes.append(gl.Node(name=prim.GetName(), mesh=len(out.doc.meshes) - 1))
        children.append(len(out.doc.nodes) - 1)
        report.meshes.append(
            {"path": str(prim.GetPath()), "vertices": len(pairs), "triangles": len(triangles) // 3}
        )
    if not children:
        raise InputError(str(root), "no mesh to export")
    out.doc.nodes.append(gl.Node(name=default.GetName(), children=children))
    out.doc.scenes.append(gl.Scene(nodes=[len(out.doc.nodes) - 1]))
    out.doc.scene = 0
    if any(IRIDESCENCE in (m.extensions or {}) for m in out.doc.materials):
        out.doc.extensionsUsed = [IRIDESCENCE, SPECULAR]
        # the viewer the look was fitted for, in the glTF's space (metres)
        out.doc.asset.extras = {
            "pavonine": {
                "fittedForEye": (fit_eye * scale).tolist(),
                "turnedAbout": (pivot * scale).tolist(),
            }
        }
    with atomic_path(output) as tmp:
        out.save(tmp)
    report.bytes = output.stat().st_size
    return report
