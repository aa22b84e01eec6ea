"""The ``symrom`` command line (typer): each command parses its options, calls one library
function and prints that result's own summary.

Every command exits non-zero with one clear line on bad input (a traceback only with
``--debug``; the library's parameters named as the command's flags), writes its outputs
atomically and never overwrites an existing output without ``--force``. One module per group
of commands: ``data`` (generate, import, show, forces), ``learn`` (train, finetune, sweep,
equations, export), ``evaluate`` (evaluate, aslip, newton), ``run`` (reproduce, demo, report),
``plan`` (jump), ``robot`` (robot init, robot show); ``common`` holds what they share. No module
imports a numerical library at import time: ``symrom --help`` and ``--version`` stay fast.
"""

from __future__ import annotations

import sys

from symrom.cli import data, evaluate, learn, plan, robot, run  # noqa: F401,E402 - registers the commands
from symrom.cli.common import app, console  # noqa: F401 - the entry point (pyproject: symrom.cli:app)

__all__ = ["app", "console", "main"]


def main() -> None:  # pragma: no cover - entry point
    app(sys.argv[1:])
