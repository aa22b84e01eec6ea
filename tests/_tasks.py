"""Task functions for the execution back-end tests (module-level, so that workers import them)."""

from __future__ import annotations

import os
import signal
from pathlib import Path


def square(offset: int, x: int) -> int:
    return offset + x * x


def die_once(marker_dir: str, x: int) -> int:
    """Kill this worker process on the first attempt of ``x`` (a marker file remembers it)."""
    marker = Path(marker_dir) / f"attempted_{x}"
    if not marker.exists():
        marker.write_text("")
        os.kill(os.getpid(), signal.SIGKILL)
    return 10 * x


def always_die(x: int) -> int:
    os.kill(os.getpid(), signal.SIGKILL)
    return x


def refuse(x: int) -> int:
    if x == 2:
        raise ValueError(f"task {x} refuses: a bad input")
    return x
