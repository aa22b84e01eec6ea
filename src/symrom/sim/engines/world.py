"""What every engine's world shares, importing no engine: the ``World`` protocol, its settings
(``WorldConfig``), the state a controller sees (``RobotState``) and the helpers the engines
have in common (angles, the standing pose, the ground-contact check).

A world holds one quadruped on a flat plane and speaks symrom's coordinates. Controllers,
the proxy's perturbations, the episode loop and the renderer use nothing else of an engine,
so adding one is a module with a class meeting ``World`` and a line in
``symrom.sim.engines.registry.ENGINES``. Built in: ``pybullet``
(``symrom.sim.engines.bullet.BulletWorld``, the engine the paper's data came from) and
``mujoco`` (``symrom.sim.engines.mujoco.MujocoWorld``).

Use::

    world = make_world("mujoco", "go1", WorldConfig())   # symrom.sim.engines.registry
    world.reset(world.standing_q(q_joints))
    s = world.state()                     # RobotState
    applied = world.step(tau)             # (12,) N m, saturated at the limits
    world.contact_forces()                # (4, 3) N, engine's ground force on each foot, world
    world.close()

Coordinates (see ``symrom.names``): ``q`` (18,) = 12 joint angles (rad,
FR FL RR RL x hx hy kn), base x y z (m, world), roll pitch yaw (rad, ZYX) of the
URDF base link frame; ``dq`` (18,) = joint rates (rad/s), base linear velocity
(m/s, world), Euler angle rates (rad/s). Joint angles, rates and torques cross
this boundary in symrom's joint order and signs (symrom angle = sign x URDF
angle, from the robot's description).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from symrom.names import BASE_POS, BASE_RPY, GRAVITY, JOINTS, N_Q
from symrom.robots import ActuatorEffects, RobotDescription


@dataclass(frozen=True)
class WorldConfig:
    """Physics settings of a world, in one place.

    physics_hz: simulation tick rate (Hz); log_hz: rate at which runs log (Hz,
    must divide physics_hz); gravity: m/s^2 (downwards). Friction and
    restitution are the values of the foot/ground contact (Bullet multiplies
    the two bodies' lateral friction and restitution, so the feet get 1 and the
    plane these values; rolling/spinning friction is set on the plane only).
    contact_stiffness / contact_damping (N/m, N s/m): ground contact as a
    spring-damper; ``None`` keeps Bullet's rigid (ERP-based) contact.
    """

    physics_hz: int = 1000
    log_hz: int = 500
    gravity: float = GRAVITY
    lateral_friction: float = 0.8
    spinning_friction: float = 0.01
    rolling_friction: float = 0.0
    restitution: float = 0.0
    solver_iterations: int = 50
    contact_stiffness: float | None = None
    contact_damping: float | None = None
    self_collision: bool = False

    def __post_init__(self) -> None:
        if self.physics_hz <= 0 or self.log_hz <= 0 or self.physics_hz % self.log_hz:
            raise ValueError(f"log_hz ({self.log_hz}) must be a positive divisor of "
                             f"physics_hz ({self.physics_hz})")
        if (self.contact_stiffness is None) != (self.contact_damping is None):
            raise ValueError("give both contact_stiffness and contact_damping, or neither")

    @property
    def dt(self) -> float:
        """Physics tick, s."""
        return 1.0 / self.physics_hz

    @property
    def log_every(self) -> int:
        """Physics ticks per logged sample."""
        return self.physics_hz // self.log_hz

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class RobotState:
    """What a controller sees; world frame unless said.

    t: s since the last reset; q, dq: (18,) as in the module docstring;
    omega: (3,) base angular velocity (rad/s, world); R: (3, 3) base -> world;
    contact: (4,) uint8 foot-ground contact flags FR FL RR RL; foot_pos (4, 3) m
    and foot_vel (4, 3) m/s: feet (foot link frames) in the world.
    """

    t: float
    q: np.ndarray
    dq: np.ndarray
    omega: np.ndarray
    R: np.ndarray
    contact: np.ndarray
    foot_pos: np.ndarray
    foot_vel: np.ndarray


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

    def add_payload(self, mass: float) -> None:
        """Fix a load of ``mass`` kg to the base at its centre of mass (the base's mass grows, its
        inertia stays: a point mass there); ``mass`` (the attribute) stays the nominal one."""

    def set_ground_friction(self, mu: float) -> None:
        """Set the foot/ground lateral friction coefficient."""

    def set_ground_contact(self, stiffness: float, damping: float) -> None:
        """Make the ground contact a spring-damper of ``stiffness`` N/m and ``damping`` N s/m."""

    def set_actuator_effects(self, effects: ActuatorEffects) -> None:
        """Simulate joint damping, armature and friction loss ``effects`` from now on (an engine
        that cannot simulate one refuses it with a ValueError)."""

    def close(self) -> None:
        """Release the engine's resources (idempotent)."""


def euler_rate_matrix(rpy: np.ndarray) -> np.ndarray:
    """(3, 3) E with omega_world = E @ d(roll, pitch, yaw)/dt for ZYX Euler angles rpy (3,) rad."""
    _, pt, y = rpy
    cy, sy, cp, sp = np.cos(y), np.sin(y), np.cos(pt), np.sin(pt)
    return np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (3,) rad of a rotation R (3, 3) (inverse of ``rpy_to_matrix``)."""
    pitch = -np.arcsin(np.clip(R[2, 0], -1.0, 1.0))
    return np.array([np.arctan2(R[2, 1], R[2, 2]), pitch, np.arctan2(R[1, 0], R[0, 0])])


def check_ground_contact(stiffness: float, damping: float) -> None:
    """ValueError unless ``stiffness`` N/m > 0 and ``damping`` N s/m >= 0 are finite (``World.set_ground_contact``)."""
    if not (np.isfinite(stiffness) and stiffness > 0 and np.isfinite(damping) and damping >= 0):
        raise ValueError(f"ground contact needs stiffness > 0 and damping >= 0 (N/m, N s/m), "
                         f"got {stiffness!r}, {damping!r}")


def standing_configuration(spec: RobotDescription, foot_radius: float, q_joints: np.ndarray,
                           xy: tuple[float, float] = (0.0, 0.0),
                           rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
                           penetration: float = 5e-4) -> np.ndarray:
    """Configuration (18,) with joints ``q_joints`` (12,) rad whose lowest foot (a sphere of
    ``foot_radius`` m) touches the ground, lowered ``penetration`` m further so the contacts
    exist from the first tick."""
    q = np.zeros(N_Q)
    q[JOINTS] = q_joints
    q[BASE_RPY] = rpy
    q[BASE_POS] = (*xy, 0.0)
    from symrom.data.preprocess import foot_positions_world  # the one kinematics source

    lowest = foot_positions_world(spec.key, q[None])[0, :, 2].min()
    q[BASE_POS.start + 2] = foot_radius - lowest - penetration
    return q


__all__ = ["RobotState", "World", "WorldConfig", "check_ground_contact", "euler_rate_matrix", "matrix_to_rpy",
           "standing_configuration"]
