"""``python -m lenticalib``: the same as the ``lenticalib`` console script."""

from .cli import entry_point

entry_point()
