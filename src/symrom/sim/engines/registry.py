"""The engine registry: engine names and where their worlds are, imported only when asked for.

``make_world(engine, robot, config)`` builds a world of the named engine (a
``symrom.sim.engines.world.World``); nothing of an engine is imported before
that, so a MuJoCo world never loads PyBullet. Adding an engine: a module with
a class meeting ``World`` and one line in ``ENGINES``.
"""

from __future__ import annotations

import importlib

from symrom.robots import ActuatorEffects, get_robot
from symrom.sim.engines.world import World, WorldConfig

# name -> "module:class"; imported only when asked for
ENGINES: dict[str, str] = {
    "pybullet": "symrom.sim.engines.bullet:BulletWorld",
    "mujoco": "symrom.sim.engines.mujoco:MujocoWorld",
}
DEFAULT_ENGINE = "pybullet"
NEEDS_URDF = ("pybullet",)  # engines that simulate a URDF: not a robot given as an MJCF alone


class UnknownEngineError(ValueError):
    """No engine of that name in ``ENGINES``."""


class EngineRobotError(ValueError):
    """A robot an engine cannot simulate (PyBullet: a robot given as an MJCF alone)."""


def engine_names() -> list[str]:
    return list(ENGINES)


def check_engine(name: str, robot: str | None = None) -> str:
    """``name`` if it is a known engine, else ``UnknownEngineError`` naming the known ones;
    with ``robot``, ``EngineRobotError`` if that engine cannot simulate it."""
    if name not in ENGINES:
        raise UnknownEngineError(f"unknown engine {name!r}; known: {', '.join(ENGINES)}")
    if robot is not None and name in NEEDS_URDF:
        desc = get_robot(robot)
        if desc.urdf_derived:
            raise EngineRobotError(f"robot {desc.name!r} is given as an MJCF alone ({desc.mjcf_path}): the {name} "
                                   f"engine simulates URDFs; use the mujoco engine")
    return name


def engine_module(name: str) -> str:
    """The module that holds engine ``name``'s world (what a worker imports ahead of its tasks)."""
    return ENGINES[check_engine(name)].partition(":")[0]


def engine_class(name: str) -> type:
    module, _, attr = ENGINES[check_engine(name)].partition(":")
    return getattr(importlib.import_module(module), attr)


def make_world(engine: str, robot: str, config: WorldConfig = WorldConfig(),
               effects: ActuatorEffects | None = None) -> World:
    """A new world of ``engine`` holding ``robot`` (a built-in name or a description file).

    effects: the actuator effects to simulate (default: the description's ``[actuators]``).
    """
    return engine_class(check_engine(engine, robot))(robot, config, effects=effects)


__all__ = ["DEFAULT_ENGINE", "ENGINES", "NEEDS_URDF", "EngineRobotError", "UnknownEngineError", "check_engine",
           "engine_class", "engine_module", "engine_names", "make_world"]
