"""``python -m symrom.cli``: the ``symrom`` command."""

from symrom.cli import main

main()
