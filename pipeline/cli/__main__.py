"""``python -m pavonine.pipeline.cli``: the same as the ``pavonine`` console script."""

from pavonine.pipeline.cli import main

main()
