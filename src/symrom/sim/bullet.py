"""PyBullet, imported without its banner.

PyBullet's C extension prints ``pybullet build time: ...`` when it is first
imported, once in every worker process too, so a command with workers shows
it several times in the middle of its own output. It is silenced here by
pointing the standard output and error descriptors (1, 2) at the null device
while the module loads (C's buffers flushed before they are pointed back).
Every module of symrom imports PyBullet as ``from symrom.sim.bullet import p``.
"""

from __future__ import annotations

import ctypes
import os
import sys


def _import_quietly():
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in saved:
            os.dup2(null, fd)
        import pybullet
        try:
            ctypes.CDLL(None).fflush(None)  # the banner may still sit in a C stream buffer
        except (OSError, AttributeError):
            pass
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)
    return pybullet


p = _import_quietly()

__all__ = ["p"]
