"""hdmitsuba's sensor settings on cameras and meshes: ``mitsuba:sensor:type``,
``mitsuba:sensor:film:pixel_filter:type`` and ``mitsuba:sensor``.

As hdmitsuba's translator does (``hdmitsuba/camera.cc``, ``prim_translator.cc`` ``BuildSensor``,
``scene_manager.cc``): a camera whose ``mitsuba:sensor:type`` is ``"irradiancemeter"`` becomes
Mitsuba's ``irradiancemeter`` sensor, attached to the mesh whose ``mitsuba:sensor`` names the
camera (a string or a relationship); rendering through that camera gives an image whose every
pixel is an independent estimate of the irradiance the mesh receives, averaged over its surface
(W m⁻²; Mitsuba samples a point on the shape by area and a cosine-weighted direction). The meter
has no transform of its own, so the camera's lens is not used. ``"perspective"`` (or nothing) is
the camera as USD describes it. ``mitsuba:sensor:film:pixel_filter:type`` picks the film's
reconstruction filter (Mitsuba's names). Any other value is warned about, naming the attribute.
"""

from __future__ import annotations

from pxr import Usd

from pavonine.render.diagnostics import Diagnostics

SENSOR_TYPE = "mitsuba:sensor:type"
PIXEL_FILTER = "mitsuba:sensor:film:pixel_filter:type"
ATTACHED = "mitsuba:sensor"
SENSOR_TYPES = ("perspective", "irradiancemeter")
PIXEL_FILTERS = ("box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos")
#: the attributes read here, per prim type (``integrator_settings.warn_unread`` skips them)
READ = {"Camera": (SENSOR_TYPE, PIXEL_FILTER), "Mesh": (ATTACHED,)}


def sensor_type(prim: Usd.Prim, diag: Diagnostics) -> str:
    """The camera's ``mitsuba:sensor:type`` (``"perspective"`` when absent or unknown, warned)."""
    return _choice(prim, SENSOR_TYPE, SENSOR_TYPES, "rendered as a perspective camera", diag)


def pixel_filter(prim: Usd.Prim, diag: Diagnostics) -> str:
    """The camera's film reconstruction filter (``"box"`` when absent or unknown, warned)."""
    return _choice(prim, PIXEL_FILTER, PIXEL_FILTERS, "box used", diag)


def _choice(prim: Usd.Prim, name: str, known: tuple[str, ...], instead: str, diag) -> str:
    """A string setting that must be one of ``known`` (the first when absent; warned if another)."""
    attr = prim.GetAttribute(name)
    value = attr.Get() if attr and attr.HasAuthoredValue() else None
    chosen = str(value) if value is not None else known[0]
    if chosen in known:
        return chosen
    diag.warn(
        str(prim.GetPath()),
        f"{name} = {chosen!r} (hdmitsuba's setting) is not supported by Mitsuba here (known: "
        f"{', '.join(known)}); {instead}",
    )
    return known[0]


def metered_meshes(stage: Usd.Stage, camera: str) -> list[str]:
    """Paths of the meshes whose ``mitsuba:sensor`` names ``camera``."""
    found = []
    for prim in stage.Traverse():
        prop = prim.GetProperty(ATTACHED)
        if not prop:
            continue
        if isinstance(prop, Usd.Relationship):
            targets = [str(t) for t in prop.GetTargets()]
        else:
            targets = [str(prop.Get() or "")]
        if camera in targets:
            found.append(str(prim.GetPath()))
    return found


def attach_meter(
    shapes: dict, stage: Usd.Stage, camera: str, sensor: dict, diag: Diagnostics
) -> object | None:
    """Rebuild the one mesh that names ``camera`` in ``mitsuba:sensor`` with the irradiance meter
    ``sensor`` (a Mitsuba dict with its film) attached; the loaded sensor, or ``None`` (warned)."""
    import mitsuba as mi

    meshes = metered_meshes(stage, camera)
    keys = [k for k in shapes if k.split("#")[0] in meshes]
    if len(meshes) != 1 or len(keys) != 1 or not isinstance(shapes[keys[0]], mi.Mesh):
        named = ", ".join(meshes) or "no mesh"
        diag.warn(
            camera,
            f"{SENSOR_TYPE} 'irradiancemeter' needs exactly one rendered mesh (one Mitsuba mesh, "
            f"no GeomSubsets) naming it in {ATTACHED}; {named} does; rendered as a perspective "
            "camera",
        )
        return None
    meter = mi.load_dict(sensor)
    shapes[keys[0]] = _with_sensor(shapes[keys[0]], meter)
    return meter


def _with_sensor(mesh, sensor) -> object:
    """A copy of the ``mi.Mesh`` (buffers, BSDF, emitter) with ``sensor`` attached."""
    import mitsuba as mi

    props = mi.Properties()
    if mesh.bsdf() is not None:
        props["bsdf"] = mesh.bsdf()
    if mesh.emitter() is not None:
        props["emitter"] = mesh.emitter()
    props["sensor"] = sensor
    old = mi.traverse(mesh)
    copy = mi.Mesh(
        mesh.id(),
        mesh.vertex_count(),
        mesh.face_count(),
        props=props,
        has_vertex_normals=mesh.has_vertex_normals(),
        has_vertex_texcoords=mesh.has_vertex_texcoords(),
    )
    new = mi.traverse(copy)
    for key in old.keys():
        if key in new.keys() and not key.startswith(("bsdf.", "emitter.")):
            new[key] = old[key]
    new.update()
    return copy
