"""Authoring: maps and recipes in, USD feather assets out, and the same assets made portable.

One sub-package per step: ``maps`` (painting the six maps), ``convert`` (recipes, the feather
mesh, atlas, barbs, USD component assets), ``bake`` (textures over the atlas), ``shading`` (looks
for hosts other than Pavonine's renderer), ``export`` (usdz, glTF), ``assemble`` (the train).
Beside the renderer, never above it: docs/house.md.
"""
