"""Converters and the ``pavonine`` command line."""
