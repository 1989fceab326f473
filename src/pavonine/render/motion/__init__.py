"""Motion: USD's time samples and shutter rendered as time slices of one Mitsuba scene.

* :mod:`.blur`: the camera's shutter, the slices of a frame, and moving the synced scene to a
  slice's time in place;
* :mod:`.reach`: how far the moving scene travels in the image over the shutter, so how many
  slices a frame needs;
* :mod:`.deform`: skinned meshes moved by their points alone (the fast path of a move).
"""
