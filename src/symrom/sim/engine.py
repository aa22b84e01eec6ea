"""The seam between symrom and a physics engine: the ``World`` protocol and the engine registry.

A world holds one quadruped on a flat plane and speaks symrom's coordinates
(``symrom.sim.world``: ``RobotState``, q and dq (18,), torques (12,) in symrom's
joint order and signs). Controllers, the proxy's perturbations and the runner
use nothing else of an engine, so adding one is a class with these methods and
a line in ``ENGINES``. Built in: ``pybullet`` (``BulletWorld``, the engine the
paper's data came from) and ``mujoco`` (``MujocoWorld``).

Use::

    world = make_world("mujoco", "go1", WorldConfig())
    world.reset(world.standing_q(q_joints))
    s = world.state()                     # RobotState
    applied = world.step(tau)             # (12,) N m, saturated at the limits
    world.contact_forces()                # (4, 3) N, engine's ground force on each foot, world
    world.close()
"""

from __future__ import annotations

import importlib
from typing import Protocol, runtime_checkable

import numpy as np

from symrom.robots import ActuatorEffects, RobotDescription, get_robot
from symrom.sim.world import RobotState, WorldConfig

# name -> "module:class"; imported only when asked for
ENGINES: dict[str, str] = {
    "pybullet": "symrom.sim.world:BulletWorld",
    "mujoco": "symrom.sim.mujoco_world:MujocoWorld",
}
DEFAULT_ENGINE = "pybullet"
NEEDS_URDF = ("pybullet",)  # engines that simulate a URDF: not a robot given as an MJCF alone


class UnknownEngineError(ValueError):
    """No engine of that name in ``ENGINES``."""


class EngineRobotError(ValueError):
    """A robot an engine cannot simulate (PyBullet: a robot given as an MJCF alone)."""


@runtime_checkable
class World(Protocol):
    """One robot on a plane in one engine (see the module docstring).

    Attributes: spec (``RobotDescription``), config (``WorldConfig``), engine (its
    name in ``ENGINES``), torque_limit (12,) N m, mass kg (the whole robot, as
    simulated), foot_radius m, t s since the last reset, held (joint indices held
    by ``hold_joints``).
    """

    spec: RobotDescription
    config: WorldConfig
    engine: str
    torque_limit: np.ndarray
    mass: float
    foot_radius: float
    t: float

    def reset(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Place the robot at q (18,) with velocity dq (18,) (default rest); t = 0."""

    def standing_q(self, q_joints: np.ndarray, xy: tuple[float, float] = (0.0, 0.0),
                   rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   penetration: float = 5e-4) -> np.ndarray:
        """Configuration (18,) with joints q_joints (12,) whose lowest foot touches the ground."""

    def state(self) -> RobotState:
        """The robot's current state."""

    def contact_flags(self) -> np.ndarray:
        """(4,) uint8: 1 where a foot touches the ground."""

    def contact_forces(self) -> np.ndarray:
        """(4, 3) N: the engine's ground reaction force on each foot (world frame) at the
        last tick, 0 for a foot in the air."""

    def joint_velocities(self) -> np.ndarray:
        """(12,) rad/s, symrom's signs (cheaper than a whole ``state``)."""

    def step(self, tau: np.ndarray, report: bool = True) -> np.ndarray | None:
        """Apply joint torques tau (12,) N m (saturated at the limits) for one tick; the
        torques applied (held joints: what held them), or None with ``report=False``."""

    def hold_joints(self, joints: list[int]) -> None:
        """Hold joints (indices into the 12) at their angles of each ``reset``, by position
        servos within the torque limits; ``step`` ignores their torques."""

    def apply_base_force(self, force_world: np.ndarray) -> None:
        """Push the base's centre of mass with force_world (3,) N during the next tick."""

    def scale_inertia(self, trunk_mass: float, leg_mass: float, inertia: float) -> None:
        """Scale the trunk's and the other links' masses (and inertias, times ``inertia``)."""

    def set_ground_friction(self, mu: float) -> None:
        """Set the foot/ground lateral friction coefficient."""

    def set_ground_contact(self, stiffness: float, damping: float) -> None:
        """Make the ground contact a spring-damper of ``stiffness`` N/m and ``damping`` N s/m."""

    def set_actuator_effects(self, effects: ActuatorEffects) -> None:
        """Simulate joint damping, armature and friction loss ``effects`` from now on (an engine
        that cannot simulate one refuses it with a ValueError)."""

    def close(self) -> None:
        """Release the engine's resources (idempotent)."""


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


def engine_class(name: str) -> type:
    module, _, attr = ENGINES[check_engine(name)].partition(":")
    return getattr(importlib.import_module(module), attr)


def make_world(engine: str, robot: str, config: WorldConfig = WorldConfig(),
               effects: ActuatorEffects | None = None) -> World:
    """A new world of ``engine`` holding ``robot`` (a built-in name or a description file).

    effects: the actuator effects to simulate (default: the description's ``[actuators]``).
    """
    return engine_class(check_engine(engine, robot))(robot, config, effects=effects)


__all__ = ["DEFAULT_ENGINE", "ENGINES", "NEEDS_URDF", "EngineRobotError", "UnknownEngineError", "World",
           "check_engine", "engine_class", "engine_names", "make_world"]
