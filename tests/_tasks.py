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


def thread_limits(x: int) -> tuple[int, int]:
    """This worker's thread limits: symrom's kernels' and BLAS's (the highest of NumPy's and
    SciPy's libraries, loaded only now)."""
    import numpy  # noqa: F401
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    from symrom.execution import kernel_threads

    return kernel_threads(), max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
