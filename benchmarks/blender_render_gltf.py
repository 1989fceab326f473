"""Child of ``benchmarks/blender_gltf.py``, run by the Python of a virtual environment with
Blender's ``bpy`` module (not the project's): import a ``.glb`` with Blender's own glTF importer
into an empty scene, light and frame it as a Pavonine scene, render linear float EXRs with Cycles
(and EEVEE where it starts), and say what the importer made of the materials.

    BPY_PYTHON benchmarks/blender_render_gltf.py JOB.json

``JOB.json``: ``glb``, ``out`` (folder), ``resolution`` (width, height), ``views`` (each ``name``,
``position``: the camera in glTF's frame, metres, +Y up; ``rotate_y_deg``: its turn about +Y from
looking down -Z; ``fov_deg``: vertical field of view; ``near``, ``far``), ``sun`` (unit vector
toward the sun, glTF frame), ``sun_irradiance`` (W/m²), ``sun_angle_deg``, ``sky`` (radiance),
``engines`` (``"cycles"``, ``"eevee"``, and last ``"cycles_film"``: Cycles after wiring by hand
the film the importer leaves out, :func:`wire_film`), ``cycles_samples``, ``eevee_samples``, ``threads``.
Writes ``OUT/<engine>_<view>.exr`` and ``OUT/blender.json`` (versions, per engine what rendered
or why not, per material what feeds each Principled BSDF input).
"""

from __future__ import annotations

import json
import math
import struct
import sys
import traceback
from pathlib import Path

import bpy
from mathutils import Euler, Vector

#: Principled BSDF inputs a glTF PBR material (with the two extensions we write) can reach.
INPUTS = (
    "Base Color",
    "Metallic",
    "Roughness",
    "IOR",
    "Alpha",
    "Specular IOR Level",
    "Specular Tint",
    "Thin Film Thickness",
    "Thin Film IOR",
    "Coat Weight",
    "Sheen Weight",
    "Transmission Weight",
    "Emission Strength",
)

#: glTF's dielectric F0 (index 1.5), which KHR_materials_specular's colour scales.
DEFAULT_F0 = 0.04


def uniform_sky(scene, colour) -> None:
    """A new world for ``scene``: a uniform background of ``colour`` (linear RGB), strength 1."""
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    if hasattr(world, "use_nodes"):
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    background.inputs["Color"].default_value = [*colour, 1.0]
    background.inputs["Strength"].default_value = 1.0


def to_blender(v) -> Vector:
    """A glTF (+Y up) vector in Blender's +Z-up frame, as the importer converts: (x, -z, y)."""
    x, y, z = v
    return Vector((x, -z, y))


def _value(v):
    try:
        return [round(float(c), 6) for c in v]
    except TypeError:
        return round(float(v), 6)


def _upstream(socket, depth: int = 0) -> dict:
    """What feeds ``socket``: its default value, or the chain of nodes linked into it."""
    if not socket.is_linked:
        return {"value": _value(socket.default_value)} if hasattr(socket, "default_value") else {}
    link = socket.links[0]
    node = link.from_node
    info = {
        "node": node.bl_idname,
        "label": node.label or node.name,
        "output": link.from_socket.name,
    }
    if node.bl_idname == "ShaderNodeTexImage" and node.image:
        info["image"] = node.image.name
        info["colorspace"] = node.image.colorspace_settings.name
        info["interpolation"] = node.interpolation
    if node.bl_idname == "ShaderNodeMix":
        info["data_type"], info["blend_type"] = node.data_type, node.blend_type
        info["clamp_result"] = node.clamp_result
    if node.bl_idname == "ShaderNodeMath":
        info["operation"], info["use_clamp"] = node.operation, node.use_clamp
    if depth < 4:
        inputs = {}
        for i, inp in enumerate(node.inputs):
            if not inp.enabled:
                continue
            key = f"{i}:{inp.name}"
            if inp.is_linked:
                inputs[key] = _upstream(inp, depth + 1)
            elif hasattr(inp, "default_value"):
                inputs[key] = {"value": _value(inp.default_value)}
        info["inputs"] = inputs
    return info


def material_report() -> dict:
    """Per material: every node's type, and what feeds the Principled BSDF's inputs."""
    report = {}
    for mat in bpy.data.materials:
        if not mat.node_tree:
            continue
        nodes = mat.node_tree.nodes
        entry = {"nodes": sorted(n.bl_idname for n in nodes)}
        for attr in ("blend_method", "surface_render_method", "use_backface_culling"):
            if hasattr(mat, attr):
                entry[attr] = getattr(mat, attr)
        principled = [n for n in nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
        if principled:
            bsdf = principled[0]
            entry["principled"] = {
                name: _upstream(bsdf.inputs[name]) for name in INPUTS if name in bsdf.inputs
            }
        report[mat.name] = entry
    return report


def _glb(path: str) -> tuple[dict, bytes]:
    """A binary glTF's JSON and its BIN chunk."""
    data = Path(path).read_bytes()
    size = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20 : 20 + size])
    rest = 20 + size
    return doc, data[rest + 8 : rest + 8 + struct.unpack_from("<I", data, rest)[0]]


def _math(nodes, links, operation: str, a, b=None):
    node = nodes.new("ShaderNodeMath")
    node.operation = operation
    for socket, value in zip(node.inputs, (a, b), strict=False):
        if value is None:
            continue
        if isinstance(value, (int, float)):
            socket.default_value = value
        else:
            links.new(socket, value)
    return node.outputs[0]


def _ior_of_f0(nodes, links, tint):
    """Node math: the dielectric index whose F0 is the mean of ``tint`` times glTF's 0.04."""
    split = nodes.new("ShaderNodeSeparateColor")
    links.new(split.inputs[0], tint)
    total = _math(nodes, links, "ADD", split.outputs[0], split.outputs[1])
    total = _math(nodes, links, "ADD", total, split.outputs[2])
    f0 = _math(nodes, links, "MULTIPLY", total, DEFAULT_F0 / 3.0)
    f0 = _math(nodes, links, "MINIMUM", _math(nodes, links, "MAXIMUM", f0, 1e-4), 0.9)
    root = _math(nodes, links, "SQRT", f0)
    top = _math(nodes, links, "ADD", root, 1.0)
    return _math(nodes, links, "DIVIDE", top, _math(nodes, links, "SUBTRACT", 1.0, root))


def _texture(mat, doc: dict, blob: bytes, ext: dict, key: str, out: Path):
    """A Separate Color node on the (data) texture ``ext[key]`` of the glTF, written to ``out``."""
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    source = doc["textures"][ext[key]["index"]]["source"]
    view = doc["bufferViews"][doc["images"][source]["bufferView"]]
    start = view.get("byteOffset", 0)
    path = out / f"{mat.name}_{key}.png"
    path.write_bytes(blob[start : start + view["byteLength"]])
    node = nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.load(str(path))
    node.image.colorspace_settings.name = "Non-Color"
    node.interpolation = "Linear"
    split = nodes.new("ShaderNodeSeparateColor")
    links.new(split.inputs[0], node.outputs["Color"])
    return split


def wire_film(glb: str, out: Path) -> dict:
    """What the importer leaves out, wired by hand: per material with KHR_materials_iridescence,
    a copy of its Principled BSDF with the film (Thin Film Thickness = the thickness texture's G
    over [minimum, maximum] nm, Thin Film IOR = iridescenceIor) mixed over the one without by
    the weight texture's R times iridescenceFactor (glTF's (1 - w) S + w I)."""
    doc, blob = _glb(glb)
    wired = {}
    for index, gmat in enumerate(doc.get("materials", [])):
        ext = gmat.get("extensions", {}).get("KHR_materials_iridescence")
        mat = bpy.data.materials.get(gmat.get("name", f"Material_{index}"))
        if not ext or mat is None:
            continue
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        bare = next(n for n in nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        output = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        film = nodes.new("ShaderNodeBsdfPrincipled")
        film.distribution, film.subsurface_method = bare.distribution, bare.subsurface_method
        for inp, copy in zip(bare.inputs, film.inputs, strict=True):
            if inp.is_linked:
                links.new(copy, inp.links[0].from_socket)
            elif hasattr(inp, "default_value"):
                copy.default_value = inp.default_value

        low = ext.get("iridescenceThicknessMinimum", 100.0)
        high = ext.get("iridescenceThicknessMaximum", 400.0)
        if "iridescenceThicknessTexture" in ext:
            scale = nodes.new("ShaderNodeMapRange")
            scale.inputs["To Min"].default_value, scale.inputs["To Max"].default_value = low, high
            links.new(
                scale.inputs["Value"],
                _texture(mat, doc, blob, ext, "iridescenceThicknessTexture", out).outputs[1],
            )
            links.new(film.inputs["Thin Film Thickness"], scale.outputs[0])
        else:
            film.inputs["Thin Film Thickness"].default_value = high
        film.inputs["Thin Film IOR"].default_value = ext.get("iridescenceIor", 1.3)
        # Blender's Specular Tint scales the whole (film) reflection, glTF's specular colour is
        # the F0 of the substrate under the film: the film branch gets tint 1 and, as its IOR,
        # the index of the substrate's mean F0 (one index: Blender's film has no RGB substrate).
        tint = film.inputs["Specular Tint"]
        if tint.is_linked:
            source = tint.links[0].from_socket
            links.remove(tint.links[0])
            links.new(film.inputs["IOR"], _ior_of_f0(nodes, links, source))
        else:
            f0 = min(max(DEFAULT_F0 * sum(tint.default_value[:3]) / 3.0, 1e-4), 0.9)
            film.inputs["IOR"].default_value = (1 + math.sqrt(f0)) / (1 - math.sqrt(f0))
        tint.default_value = (1.0, 1.0, 1.0, 1.0)
        mix = nodes.new("ShaderNodeMixShader")
        weight = nodes.new("ShaderNodeMath")
        weight.operation, weight.use_clamp = "MULTIPLY", True
        weight.inputs[1].default_value = ext.get("iridescenceFactor", 0.0)
        if "iridescenceTexture" in ext:
            links.new(
                weight.inputs[0],
                _texture(mat, doc, blob, ext, "iridescenceTexture", out).outputs[0],
            )
        else:
            weight.inputs[0].default_value = 1.0
        links.new(mix.inputs[0], weight.outputs[0])
        links.new(mix.inputs[1], bare.outputs[0])
        links.new(mix.inputs[2], film.outputs[0])
        links.new(output.inputs["Surface"], mix.outputs[0])
        wired[mat.name] = {
            "thickness_nm": [low, high],
            "ior": film.inputs["Thin Film IOR"].default_value,
        }
    return wired


def set_scene(job: dict) -> None:
    scene = bpy.context.scene
    width, height = job["resolution"]
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
    render.film_transparent = True  # the sky still lights the feather; alpha = coverage
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_depth = "32"
    render.image_settings.color_mode = "RGBA"
    render.threads_mode, render.threads = "FIXED", int(job.get("threads", 2))
    view = scene.view_settings
    view.view_transform, view.look, view.exposure, view.gamma = "Standard", "None", 0.0, 1.0
    scene.display_settings.display_device = "sRGB"

    uniform_sky(scene, job["sky"])

    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = float(job["sun_irradiance"])
    sun.angle = math.radians(float(job["sun_angle_deg"]))
    lamp = bpy.data.objects.new("Sun", sun)
    scene.collection.objects.link(lamp)
    # A sun lamp shines down its local -Z: point +Z toward the sun.
    lamp.rotation_mode = "QUATERNION"
    lamp.rotation_quaternion = to_blender(job["sun"]).normalized().to_track_quat("Z", "Y")

    cam = bpy.data.cameras.new("Camera")
    camera = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(camera)
    scene.camera = camera


def set_view(view: dict) -> None:
    camera = bpy.context.scene.camera
    cam = camera.data
    cam.sensor_fit = "VERTICAL"
    cam.lens_unit = "FOV"
    cam.angle_y = math.radians(view["fov_deg"])
    cam.clip_start, cam.clip_end = view["near"], view["far"]
    camera.location = to_blender(view["position"])
    # Blender's camera looks down its local -Z with +Y up; turned 90° about X it looks down
    # Blender's +Y (glTF's -Z) with +Z (glTF's +Y) up. glTF's turn about +Y is Blender's about +Z.
    camera.rotation_mode = "XYZ"
    camera.rotation_euler = Euler((math.pi / 2, 0.0, math.radians(view["rotate_y_deg"])), "XYZ")


def render(engine: str, job: dict, out: Path) -> dict:
    scene = bpy.context.scene
    if engine in ("cycles", "cycles_film"):
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = int(job["cycles_samples"])
        scene.cycles.use_adaptive_sampling = False
        scene.cycles.use_denoising = False
        scene.cycles.seed = 0
    else:
        scene.render.engine = next(
            e for e in ("BLENDER_EEVEE_NEXT", "BLENDER_EEVEE") if _has_engine(e)
        )
        scene.eevee.taa_render_samples = int(job["eevee_samples"])
    files = {}
    for view in job["views"]:
        set_view(view)
        path = out / f"{engine}_{view['name']}.exr"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        if not path.is_file():
            raise RuntimeError(f"{path} was not written")
        files[view["name"]] = str(path)
    return {"engine": scene.render.engine, "files": files}


def _has_engine(name: str) -> bool:
    items = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items
    return name in {e.identifier for e in items}


def main() -> None:
    job = json.loads(Path(sys.argv[-1]).read_text())
    out = Path(job["out"])
    out.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.gltf(filepath=job["glb"])
    report = {
        "blender": bpy.app.version_string,
        "import": sorted(result),
        "objects": sorted(o.name for o in bpy.data.objects),
        "materials": material_report(),
        "bounds": {},
        "engines": {},
    }
    for obj in bpy.data.objects:
        if obj.type == "MESH":
            corners = [obj.matrix_world @ Vector(c) for c in obj.bound_box]
            report["bounds"][obj.name] = [
                [round(min(c[i] for c in corners), 4) for i in range(3)],
                [round(max(c[i] for c in corners), 4) for i in range(3)],
            ]
    set_scene(job)
    for engine in job["engines"]:
        if engine == "cycles_film":
            report["film_wired"] = wire_film(job["glb"], out)
        try:
            report["engines"][engine] = render(engine, job, out)
        except Exception as exc:  # EEVEE needs a GPU context; say why it did not render
            report["engines"][engine] = {"error": f"{type(exc).__name__}: {exc}"}
            traceback.print_exc()
    (out / "blender.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
