"""Baking the feather's look into textures over its ``st`` atlas, for viewers that know nothing
of Pavonine: the model's colour under a reference light and view (UsdPreviewSurface, glTF base
colour), and what a thin-film approximation needs (OpenPBR, ``KHR_materials_iridescence``).

``texels`` rasterises the mesh into the atlas, ``appearance`` evaluates the model per texel,
``textures`` writes and reads the files, ``asset`` re-bakes an existing asset (``pavonine bake``).
"""
