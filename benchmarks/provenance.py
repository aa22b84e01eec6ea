"""What every record under benchmarks/results/ carries about how it was made.

``provenance()`` gives the command that wrote the record (as typed, from the repository's root)
and the commit of the code it ran (``git rev-parse HEAD``, with ``+dirty`` when the work tree had
uncommitted changes); ``tests/test_benchmark_records.py`` checks every committed record for both.
"""

from __future__ import annotations

import shlex
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def commit() -> str:
    """The checked-out commit, ``+dirty`` appended when tracked files differ from it."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()

    try:
        head = git("rev-parse", "HEAD")
        return head + ("+dirty" if git("status", "--porcelain", "--untracked-files=no") else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def command(argv: list[str] | None = None) -> str:
    """The command line that ran this script: ``python benchmarks/NAME.py ARGS``."""
    argv = sys.argv if argv is None else argv
    script = Path(argv[0]).resolve()
    try:
        script_text = script.relative_to(ROOT).as_posix()
    except ValueError:
        script_text = str(script)
    return " ".join(["python", script_text, *map(shlex.quote, argv[1:])])


def provenance() -> dict[str, str]:
    """``{"command": ..., "commit": ...}`` for a record written now."""
    return {"command": command(), "commit": commit()}
