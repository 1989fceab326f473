"""The top floor: the applications built on the renderer and the pipeline.

The ``pavonine`` command line (:mod:`.cli`), batches on a Dask farm (:mod:`.farm`), render
comparisons and baselines (:mod:`.compare`) and the browser look-development page
(:mod:`.view`). Nothing below imports them; docs/house.md draws the floors.
"""
