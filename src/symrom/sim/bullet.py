"""PyBullet, imported without its banner.

PyBullet's C extension prints ``pybullet build time: ...`` when it is first
imported, once in every worker process too, so a command with workers shows
it several times in the middle of its own output. It is silenced here by
pointing the standard output and error descriptors (1, 2) at the null device
while the module loads (C's buffers flushed before they are pointed back).
Every module of symrom imports PyBullet as ``from symrom.sim.bullet import p``.

``client()`` and ``release(cid)`` hand out and take back DIRECT clients: a
released client is emptied (``resetSimulation``) and kept for the next request
of the process. Connecting anew costs ~15 ms (the allocator gives Bullet's ~30 MB
back to the system at each disconnect), a tenth of a jump's simulation.
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

_SPARE: list[int] = []  # released clients, emptied (at most one)


def client() -> int:
    """A connected, empty DIRECT client: a released one, else a new one."""
    try:
        return _SPARE.pop()
    except IndexError:
        return p.connect(p.DIRECT)


def release(cid: int) -> None:
    """Take back the client ``cid``: emptied and kept for the next ``client()``, or
    disconnected if one is kept already."""
    if _SPARE:
        p.disconnect(physicsClientId=cid)
        return
    p.resetSimulation(physicsClientId=cid)
    _SPARE.append(cid)


__all__ = ["client", "p", "release"]
