"""``python -m pavonine.apps.cli``: the same as the ``pavonine`` console script."""

from pavonine.apps.cli import main

main()
