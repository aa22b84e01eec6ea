"""``python -m symrom``: the ``symrom`` command, for an environment whose scripts are not on PATH."""

from symrom.cli import main

main()
