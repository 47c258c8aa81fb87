"""``python -m lenticalib.cli``: the same as the ``lenticalib`` console script."""

from . import entry_point

entry_point()
