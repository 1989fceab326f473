"""Shading networks: following ``UsdShade`` connections (through ``NodeGraph``\\ s) to values.

Every input a translator reads goes through :class:`Network`: the input's *value-producing
attribute* is found with ``UsdShadeInput.GetValueProducingAttributes`` (which walks
``NodeGraph`` interface inputs and outputs, nested graphs and ``Material`` interface inputs), then

* an authored value (on the input itself or on an interface input) is returned as a constant;
* a shader output is handed to the translator of that shader's id: ``UsdUVTexture``
  (:mod:`.textures`), ``UsdPrimvarReader_*`` (:mod:`.primvars`), ``mitsuba_*`` nodes
  (:mod:`.mitsuba_context`), MaterialX ``ND_image_*``/``ND_tiledimage_*`` (:mod:`.materialx`);
  anything else is warned about, naming the input and the shader, and
  the input's fallback is used.

Values come back in Mitsuba's terms: a ``float``, an ``rgb`` dict, a texture dict (``bitmap``,
``d65``-wrapped ``bitmap`` for unbounded colours, ``mesh_attribute`` placeholders resolved per
mesh by :mod:`.primvars`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pxr import Sdr, Usd, UsdShade

from pavonine.render.diagnostics import Diagnostics

#: how a consumer reads a value: colour (3, spectrally upsampled), data (3, raw), scalar (1)
COLOR, VECTOR, FLOAT = "color", "vector", "float"
COMPONENTS = {COLOR: 3, VECTOR: 3, FLOAT: 1}


@dataclass
class Affine:
    """``a · v + b``, applied to a value after the network computed it (e.g. 1 − roughness)."""

    a: float = 1.0
    b: float = 0.0

    def apply(self, value: Any) -> Any:
        return np.asarray(value, dtype=np.float64) * self.a + self.b

    @property
    def identity(self) -> bool:
        return self.a == 1.0 and self.b == 0.0


@dataclass
class Network:
    """The state of translating one material: time, warnings, uv sets and primvars it reads."""

    material: str  # the material's path, for warnings and cache keys
    time: Usd.TimeCode
    diag: Diagnostics
    uv_names: list[str] = field(default_factory=list)  # st primvars, in the order they are read
    primvars: list[str] = field(default_factory=list)  # primvars read through mesh attributes
    textures: dict = field(default_factory=dict)  # decoded images, shared by the material's inputs

    def warn(self, where: str, message: str) -> None:
        self.diag.warn(where, message)

    def use_uv(self, name: str) -> None:
        if name not in self.uv_names:
            self.uv_names.append(name)

    def use_primvar(self, name: str) -> None:
        if name not in self.primvars:
            self.primvars.append(name)

    # -- reading inputs ------------------------------------------------------------------------

    def source(self, shader_input: UsdShade.Input | None) -> tuple[UsdShade.Shader, str] | None:
        """The shader output feeding ``shader_input`` (through node graphs), or ``None``."""
        if not shader_input:
            return None
        for attr in shader_input.GetValueProducingAttributes(shaderOutputsOnly=False):
            name, kind = UsdShade.Utils.GetBaseNameAndType(attr.GetName())
            if kind == UsdShade.AttributeType.Output:
                return UsdShade.Shader(attr.GetPrim()), str(name)
        return None

    def constant(self, shader: UsdShade.Shader, name: str, fallback: Any) -> Any:
        """An input's authored value (its own or an interface input's), else ``fallback``."""
        shader_input = shader.GetInput(name)
        if not shader_input:
            return fallback
        for attr in shader_input.GetValueProducingAttributes(shaderOutputsOnly=False):
            _, kind = UsdShade.Utils.GetBaseNameAndType(attr.GetName())
            if kind == UsdShade.AttributeType.Output:
                return fallback
            value = attr.Get(self.time)
            if value is not None:
                return value
        return fallback

    def setting(self, shader: UsdShade.Shader, name: str, fallback: Any, kind: str = FLOAT) -> Any:
        """An unconnectable input's constant (a float or a 3-vector); a wrong value is warned."""
        value = self._checked(shader, name, self.constant(shader, name, fallback), kind, fallback)
        return coerce(value, kind, fallback)

    def _checked(self, shader: UsdShade.Shader, name: str, value: Any, kind: str, fallback: Any):
        """``value`` when it is a ``kind`` value, else ``fallback`` (warned, naming the input)."""
        if _numeric(value, kind):
            return value
        self.warn(
            str(shader.GetPath()),
            f"input {name!r} = {value!r} is not a {kind} value; using {fallback}",
        )
        return fallback

    def differs(self, shader: UsdShade.Shader, name: str, default: Any) -> bool:
        """True when an input is connected or holds a value other than ``default``."""
        if self.source(shader.GetInput(name)) is not None:
            return True
        value = self.constant(shader, name, None)
        if value is None:
            return False
        try:
            return not np.allclose(np.atleast_1d(np.asarray(value, dtype=float)), default)
        except (TypeError, ValueError):
            return value != default

    def is_authored(self, shader: UsdShade.Shader, name: str) -> bool:
        """True when the input has a value or a connection that differs from nothing at all."""
        shader_input = shader.GetInput(name)
        return bool(shader_input) and bool(
            shader_input.GetValueProducingAttributes(shaderOutputsOnly=False)
        )

    def value(
        self,
        shader: UsdShade.Shader,
        name: str,
        kind: str,
        fallback: Any,
        affine: Affine | None = None,
    ) -> Any:
        """An input as a Mitsuba value: ``float``, ``rgb`` dict or texture dict (see module doc)."""
        affine = affine or Affine()
        source = self.source(shader.GetInput(name))
        if source is not None:
            upstream, output = source
            result = self.upstream(upstream, output, kind, affine, f"{shader.GetPath()}.{name}")
            if result is not None:
                return result
            value = upstream_fallback(upstream, self, fallback)
        else:
            value = self.constant(shader, name, fallback)
        value = self._checked(shader, name, value, kind, fallback)
        return as_mitsuba(affine.apply(coerce(value, kind, fallback)), kind)

    def upstream(
        self, shader: UsdShade.Shader, output: str, kind: str, affine: Affine, consumer: str
    ) -> Any | None:
        """The Mitsuba value of ``shader.outputs:<output>``; ``None`` (warned) if unsupported."""
        from pavonine.render.shading.shader_ids import node_translator

        shader_id = shader_identifier(shader)
        translate = node_translator(shader_id, affine)
        if translate is not None:
            return translate(shader, shader_id, output, kind, affine, self)
        self.warn(
            str(shader.GetPath()),
            f"shader {shader_id or '(no info:id)'!r} feeding {consumer} is not supported; "
            "using the input's fallback",
        )
        return None

    def audit(self, shader: UsdShade.Shader, identifier: str | None = None) -> None:
        """Warn about inputs the shader's Sdr definition does not know (they would be dropped)."""
        node = sdr_node(identifier or shader_identifier(shader))
        if node is None:
            return
        known = set(node.GetShaderInputNames())
        for shader_input in shader.GetInputs():
            name = shader_input.GetBaseName()
            if name not in known:
                self.warn(
                    str(shader.GetPath()),
                    f"input {name!r} is not an input of {node.GetIdentifier()}; ignored",
                )


def shader_identifier(shader: UsdShade.Shader) -> str:
    """``info:id`` of a shader ('' when it is defined by a source asset or code)."""
    shader_id = shader.GetShaderId() if shader else None
    return str(shader_id) if shader_id else ""


def sdr_node(identifier: str) -> Sdr.ShaderNode | None:
    """The Sdr definition of a shader id (``UsdPreviewSurface``, ``UsdUVTexture``...), if any."""
    if not identifier:
        return None
    node = Sdr.Registry().GetShaderNodeByIdentifier(identifier)
    return node if node and node.IsValid() else None


def upstream_fallback(shader: UsdShade.Shader, network: Network, fallback: Any) -> Any:
    """A source node's own ``inputs:fallback`` when it has one (texture, primvar reader)."""
    value = network.constant(shader, "fallback", None)
    return fallback if value is None else value


def _numeric(value: Any, kind: str) -> bool:
    """True for a finite number (scalar kinds) or a finite 1-4 vector (colours and vectors)."""
    if isinstance(value, (str, bytes)):
        return False
    try:
        array = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    except (TypeError, ValueError):
        return False
    return 1 <= array.size <= 4 and bool(np.all(np.isfinite(array)))


def coerce(value: Any, kind: str, fallback: Any) -> Any:
    """``value`` with the number of components ``kind`` needs (extra dropped, scalar broadcast)."""
    try:
        array = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    except (TypeError, ValueError):
        array = np.atleast_1d(np.asarray(fallback, dtype=np.float64)).ravel()
    if array.size == 0 or not np.all(np.isfinite(array)):
        array = np.atleast_1d(np.asarray(fallback, dtype=np.float64)).ravel()
    if COMPONENTS[kind] == 1:
        return float(array[0])
    return np.resize(array, 3) if array.size < 3 else array[:3]


def as_mitsuba(value: Any, kind: str) -> Any:
    """A constant as Mitsuba wants it: ``float`` for scalars, an ``rgb`` dict for colours."""
    array = np.atleast_1d(np.asarray(value, dtype=np.float64))
    if COMPONENTS[kind] == 1:
        return float(array.ravel()[0])
    return {"type": "rgb", "value": [float(c) for c in np.resize(array, 3)]}
