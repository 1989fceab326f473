"""Child of ``benchmarks/blender_gltf.py``, run by the Python of a virtual environment with
Blender's ``bpy`` module (not the project's): import a ``.glb`` with Blender's own glTF importer
into an empty scene, light and frame it as a Pavonine scene, render linear float EXRs with Cycles
(and EEVEE where it starts), and say what the importer made of the materials.

    BPY_PYTHON benchmarks/blender_render_gltf.py JOB.json

``JOB.json``: ``glb``, ``out`` (folder), ``resolution`` (width, height), ``views`` (each ``name``,
``position``: the camera in glTF's frame, metres, +Y up; ``rotate_y_deg``: its turn about +Y from
looking down -Z; ``fov_deg``: vertical field of view; ``near``, ``far``), ``sun`` (unit vector
toward the sun, glTF frame), ``sun_irradiance`` (W/m²), ``sun_angle_deg``, ``sky`` (radiance),
``engines`` (``"cycles"``, ``"eevee"``), ``cycles_samples``, ``eevee_samples``, ``threads``.
Writes ``OUT/<engine>_<view>.exr`` and ``OUT/blender.json`` (versions, per engine what rendered
or why not, per material what feeds each Principled BSDF input).
"""

from __future__ import annotations

import json
import math
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

    world = bpy.data.worlds.new("Sky")
    scene.world = world
    if hasattr(world, "use_nodes"):
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeBackground")
    background.inputs["Color"].default_value = [*job["sky"], 1.0]
    background.inputs["Strength"].default_value = 1.0

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
    if engine == "cycles":
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
        try:
            report["engines"][engine] = render(engine, job, out)
        except Exception as exc:  # EEVEE needs a GPU context; say why it did not render
            report["engines"][engine] = {"error": f"{type(exc).__name__}: {exc}"}
            traceback.print_exc()
    (out / "blender.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
