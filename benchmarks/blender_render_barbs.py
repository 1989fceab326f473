"""Child of ``benchmarks/blender_barbs.py`` (and of tests/pipeline/test_portable_usd.py), run by
the Python of a virtual environment with Blender's ``bpy`` module: import a USD file with
Blender's own USD importer (``bpy.ops.wm.usd_import``, ``light_intensity_scale`` 0.25: the
importer multiplies light intensities by 4) into an empty scene, say what it made of every
object (type, materials, colour attributes, what feeds the Principled BSDF's Base Color) and of
the scene's camera and lights, and optionally render the imported camera's view with Cycles.

    BPY_PYTHON benchmarks/blender_render_barbs.py JOB.json

``JOB.json``: ``usd`` (the file to import), ``out`` (folder); to render also ``resolution``
(width, height), ``cycles_samples``, ``threads`` and ``sky`` (a uniform world colour, linear
RGB: Blender 5.3's importer makes no world of a ``DomeLight`` without a texture) and, optionally,
``seed`` (Cycles' seed, default 0). Writes
``OUT/blender.json`` and, when rendering, ``OUT/cycles.exr`` (linear, RGBA, film transparent).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from blender_render_gltf import _upstream, uniform_sky  # what feeds a socket, as its report says


def base_colour(material) -> dict:
    """What feeds the material's Principled BSDF Base Color: the first node (its type and, for
    an Attribute node, the attribute it reads) or the constant."""
    if material is None or not material.node_tree:
        return {"node": None}
    principled = [n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
    if not principled:
        return {"node": None}
    socket = principled[0].inputs["Base Color"]
    if not socket.is_linked:
        return {"value": [round(float(c), 4) for c in socket.default_value]}
    node = socket.links[0].from_node
    found = {"node": node.bl_idname}
    if node.bl_idname == "ShaderNodeAttribute":
        found["attribute"] = node.attribute_name
    else:
        found["chain"] = _upstream(socket)
    return found


def describe() -> dict:
    """Per imported object: type, materials (with their Base Color's source), colour attributes,
    faces (meshes) or curves; per camera and light what the importer set."""
    objects = {}
    for obj in bpy.data.objects:
        entry = {"type": obj.type}
        data = obj.data
        if obj.type in ("MESH", "CURVES"):
            entry["materials"] = [
                s.material.name if s.material else None for s in obj.material_slots
            ]
            entry["base_color"] = (
                base_colour(obj.material_slots[0].material)
                if obj.material_slots
                else {"node": None}
            )
            entry["color_attributes"] = sorted(a.name for a in data.color_attributes)
        if obj.type == "MESH":
            entry["faces"] = len(data.polygons)
            entry["vertices"] = len(data.vertices)
        if obj.type == "CURVES":
            entry["curves"] = len(data.curves)
        if obj.type == "LIGHT":
            entry.update(light=data.type, energy=round(data.energy, 5))
            if data.type == "SUN":
                entry["angle_deg"] = round(math.degrees(data.angle), 4)
        if obj.type == "CAMERA":
            entry.update(fov_y_deg=round(math.degrees(data.angle_y), 4), sensor_fit=data.sensor_fit)
        objects[obj.name] = entry
    return objects


def set_up(job: dict) -> dict:
    """Camera (the imported one), resolution, a uniform sky when the import made no world,
    Standard view transform, linear float EXR with alpha, Cycles with Pavonine's box pixel
    filter; what was added by hand."""
    scene = bpy.context.scene
    added = {}
    cameras = [o for o in bpy.data.objects if o.type == "CAMERA"]
    if scene.camera is None and cameras:
        scene.camera = cameras[0]
        added["camera"] = cameras[0].name
    width, height = job["resolution"]
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
    render.film_transparent = True
    render.image_settings.file_format = "OPEN_EXR"
    render.image_settings.color_depth = "32"
    render.image_settings.color_mode = "RGBA"
    render.threads_mode, render.threads = "FIXED", int(job.get("threads", 2))
    scene.view_settings.view_transform, scene.view_settings.look = "Standard", "None"
    if scene.world is None:
        uniform_sky(scene, job["sky"])
        added["world"] = job["sky"]
    render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = int(job["cycles_samples"])
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = int(job.get("seed", 0))
    # Pavonine's film: a box filter one pixel wide (Cycles' default: Blackman-Harris, 1.5 px)
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    return added


def main() -> None:
    job = json.loads(Path(sys.argv[-1]).read_text())
    out = Path(job["out"])
    out.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.wm.usd_import(filepath=job["usd"], light_intensity_scale=0.25)
    report = {"blender": bpy.app.version_string, "import": sorted(result), "objects": describe()}
    if "resolution" in job:
        report["added"] = set_up(job)
        path = out / "cycles.exr"
        bpy.context.scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        report["cycles"] = str(path)
    (out / "blender.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
