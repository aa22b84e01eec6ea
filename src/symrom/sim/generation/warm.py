"""The compiled routines a simulation's ticks call, made ready before its first tick.

The engines' reads and a hardware-like world's sensors and motors
(``symrom.sim.engines.compiled``) and the controllers' arithmetic
(``symrom.sim.controllers.compiled``) are compiled by numba once per installation and kept in
its disk cache; a later process loads them. ``prepare(motion, engine)`` makes them ready in
this process before a generation's first jump: loaded from the disk cache, or, on a cold
cache, compiled, the engine's (and the proxy's) in a helper process beside this one while this
one compiles the motion's (the longer: the froggy controller's routines are most of a cold
start), so that the helper's own start-up is off the critical path. The helper first compiles
the part of the motion's routines this one reaches seconds into compiling them
(``("beside", motion)``: the froggy force distribution), so that this one loads it from the disk
cache when it gets there.

``load_cached()`` loads every routine the disk cache holds and compiles none: the worker
processes' fork server does so (it imports ``preload``, ``generate._preload``), so that every
worker starts with them instead of loading them on its first tick.
"""

from __future__ import annotations

import os

from symrom.execution import HELPER_TIMEOUT, in_disk_cache, start_helper, wait_helper
from symrom.sim.controllers import compiled as controllers
from symrom.sim.engines import compiled as engines


def routines(kind: str, name: str) -> list:
    """The numba dispatchers of a group: ``("engine", name)``, ``("motion", name)`` or
    ``("beside", name)``, the motion's routines another process can compile while this one
    compiles the rest (``controllers.BESIDE_ROUTINES``)."""
    if kind == "engine":
        return engines.routines(name)
    return controllers.routines_beside(name) if kind == "beside" else controllers.routines(name)


def cached(kind: str, name: str) -> bool:
    """Whether numba's disk cache holds every routine of the group."""
    return all(in_disk_cache(d) for d in routines(kind, name))


def warm(kind: str, name: str) -> None:
    """Compile, or load from the disk cache, the routines of the group (``routines``) now, for
    the argument types the simulation passes them."""
    if kind == "engine":
        engines.warm_up((name,))
    elif kind == "beside":
        controllers.warm_beside((name,))
    else:
        controllers.warm_up((name,))


def prepare(motion: str, engine: str, helper: bool = True, load: bool = True, proxy: bool = False) -> None:
    """Make the routines a jump of ``motion`` in ``engine`` calls ready in this process (see the
    module docstring); ``proxy``: through a hardware-like world's sensors and motors too (its
    routines, ``("engine", "proxy")``). ``helper``: on a cold cache, compile the engine's (and
    the proxy's) in a second process while this one compiles the motion's (with more than one
    core). ``load=False``: only make sure the disk cache holds them (for worker processes that
    load them themselves): groups already there are not loaded here."""
    wanted = (("motion", motion), ("engine", engine)) + ((("engine", "proxy"),) if proxy else ())
    groups = [g for g in wanted if routines(*g)]  # a plug-in's: none
    cold = [g for g in groups if not cached(*g)]
    spare = helper and (os.cpu_count() or 1) > 1
    beside = cold[1:] if spare else []  # the first cold group is compiled here, the rest there
    # Before them, the helper compiles the part of a cold motion's routines that their compile
    # here reaches seconds in, to be loaded from the disk cache then; this process never makes it
    # ready itself, since the motion's routines hold it.
    part = ("beside", motion)
    first = [part] if spare and ("motion", motion) in cold and not cached(*part) else []
    proc = None
    if first or beside:
        proc = start_helper("from symrom.sim.generation.warm import warm; "
                            + "; ".join(f"warm{g!r}" for g in first + beside))
    for g in groups:
        if g not in beside and (load or g in cold):
            warm(*g)
    if proc is not None:
        wait_helper(proc, HELPER_TIMEOUT)
        for g in beside:
            if load or not cached(*g):
                warm(*g)  # from the disk cache the helper filled (or compiled here if it failed)


def load_cached() -> None:
    """Load every routine of every group that numba's disk cache holds; compile none."""
    for kind, names in (("engine", engines.ENGINE_ROUTINES), ("motion", controllers.MOTION_ROUTINES)):
        for name in names:
            if cached(kind, name):
                warm(kind, name)
