"""The feather asset's materials for hosts other than Pavonine's renderer.

``mtlx`` builds the asset's MaterialX document: ``Feather`` (Pavonine's node fed by the six maps
at the mesh's feather coordinate) and ``FeatherPortable`` (standard nodes only: OpenPBR with a
thin film driven by the baked textures). ``usd`` writes the same networks as UsdShade prims (the
``mtlx`` render context), the baked UsdPreviewSurface, and the two bindings (full and preview
purpose).
"""
