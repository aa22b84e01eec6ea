"""The PyBullet engine: ``BulletWorld``, and PyBullet imported without its banner.

``BulletWorld`` (a ``symrom.sim.engines.world.World``) owns its own PyBullet client in
DIRECT mode (no GUI), so several worlds can live in one process and worker processes
never share state. The robot's base pose is reported for the URDF base link frame (the
frame the leg kinematics use), not PyBullet's inertial frame. Joint order, signs, foot
links and torque limits come from the robot's description (``symrom.robots``).

PyBullet's C extension prints ``pybullet build time: ...`` when it is first
imported, once in every worker process too, so a command with workers shows
it several times in the middle of its own output. It is silenced here by
pointing the standard output and error descriptors (1, 2) at the null device
while the module loads (C's buffers flushed before they are pointed back).
Every module of symrom imports PyBullet as ``from symrom.sim.engines.bullet import p``.

``client()`` and ``release(cid)`` hand out and take back DIRECT clients: a
released client is emptied (``resetSimulation``) and kept for the next request
of the process: connecting anew costs a noticeable share of a jump's simulation (the
allocator gives Bullet's memory back to the system at each disconnect; docs/benchmarks.md).
"""

from __future__ import annotations

import ctypes
import os
import sys

import numpy as np
import pybullet_data  # PyBullet's data folder (the plane); imports no PyBullet

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_LEGS, N_Q
from symrom.robots import ActuatorEffects, RobotDescription, get_robot
from symrom.robots.kinematics import rpy_to_matrix
from symrom.sim.engines.compiled import base_state
from symrom.sim.engines.world import (
    RobotState,
    WorldConfig,
    check_ground_contact,
    euler_rate_matrix,
    standing_configuration,
)


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


class BulletWorld:
    """One robot on a plane in its own DIRECT PyBullet client (a ``symrom.sim.engines.world.World``).

    robot: a built-in name or a description file (``symrom.robots.get_robot``).
    The joints' default velocity motors are disabled, so ``step`` drives the
    robot purely by torque; ``hold_joints`` locks chosen joints instead.
    effects (default: the description's): joint damping is Bullet's joint damping,
    friction loss a velocity motor towards rest with that much torque; Bullet has no
    armature, so a non-zero one is refused.
    """

    engine = "pybullet"

    def __init__(self, robot: str, config: WorldConfig = WorldConfig(), effects: ActuatorEffects | None = None):
        self.spec: RobotDescription = get_robot(robot)
        self.config = config
        self.effects = self.spec.actuators if effects is None else effects
        if any(self.effects.armature):
            raise ValueError(f"robot {self.spec.name!r}: the pybullet engine has no armature "
                             f"(actuator effect armature {self.effects.armature[:3]}); use engine='mujoco'")
        self.torque_limit = np.asarray(self.spec.torque_limit, dtype=float)
        self._neg_limit = -self.torque_limit
        self._dt = config.dt  # s, physics tick
        self.signs = self.spec.signs  # (12,) symrom angle = sign x URDF angle
        self.held: np.ndarray = np.zeros(0, dtype=int)  # joints held at their reset angle
        self._driven = np.arange(N_JOINTS)  # joints driven by torque: all but the held ones
        self._held_ids: list[int] = []
        self.client = client()
        self.t = 0.0
        self._pending_force: np.ndarray | None = None
        try:
            self._build()
        except Exception:
            self.close()
            raise

    # ----------------------------------------------------------------- set-up
    def _build(self) -> None:
        c, cfg = self.client, self.config
        p.setPhysicsEngineParameter(fixedTimeStep=cfg.dt, numSolverIterations=cfg.solver_iterations,
                                    physicsClientId=c)
        p.setGravity(0, 0, -cfg.gravity, physicsClientId=c)
        self.plane = p.loadURDF(str(pybullet_data.getDataPath() + "/plane.urdf"), physicsClientId=c)
        urdf = self.spec.urdf_path
        if not urdf.is_file():
            raise FileNotFoundError(f"robot {self.spec.name!r}: URDF {urdf} not found")
        flags = p.URDF_USE_INERTIA_FROM_FILE  # Bullet otherwise recomputes inertia from collision shapes
        if cfg.self_collision:
            flags |= p.URDF_USE_SELF_COLLISION
        self.robot = p.loadURDF(str(urdf), [0, 0, self.spec.start_height], flags=flags,
                                physicsClientId=c)
        joints, links = {}, {}
        for i in range(p.getNumJoints(self.robot, physicsClientId=c)):
            info = p.getJointInfo(self.robot, i, physicsClientId=c)
            joints[info[1].decode()] = i
            links[info[12].decode()] = i
        try:
            self.joint_ids = [joints[n] for n in self.spec.joint_names]
            self.foot_ids = [links[n] for n in self.spec.foot_links]
        except KeyError as e:
            raise ValueError(f"robot {self.spec.name!r}: URDF {urdf} has no joint/link {e}") from None
        self._foot_leg = {fid: k for k, fid in enumerate(self.foot_ids)}
        self._driven_ids = list(self.joint_ids)
        # Default velocity motors would fight the torques: switch them off (or, with friction
        # loss, leave them as much torque as the friction towards rest).
        p.setJointMotorControlArray(self.robot, self.joint_ids, p.VELOCITY_CONTROL,
                                    forces=list(self.effects.friction_loss), physicsClientId=c)
        if any(self.effects.damping):
            for jid, d in zip(self.joint_ids, self.effects.damping):
                p.changeDynamics(self.robot, jid, jointDamping=d, physicsClientId=c)
        ground = dict(lateralFriction=cfg.lateral_friction, spinningFriction=cfg.spinning_friction,
                      rollingFriction=cfg.rolling_friction, restitution=cfg.restitution)
        if cfg.contact_stiffness is not None:
            ground.update(contactStiffness=cfg.contact_stiffness, contactDamping=cfg.contact_damping)
        p.changeDynamics(self.plane, -1, physicsClientId=c, **ground)
        for fid in self.foot_ids:
            # Bullet combines rolling/spinning friction as roll_A * friction_B + roll_B *
            # friction_A, so the feet carry none of their own: the plane's values apply.
            p.changeDynamics(self.robot, fid, lateralFriction=1.0, spinningFriction=0.0,
                             rollingFriction=0.0, restitution=1.0, physicsClientId=c)
        # PyBullet reports the base's inertial frame; keep the offset to get the link frame.
        dyn = p.getDynamicsInfo(self.robot, -1, physicsClientId=c)
        self._inertial = (tuple(dyn[3]), tuple(dyn[4]))  # link frame -> inertial frame
        # inertial frame -> link frame, as ``state`` applies it
        self._off_pos, self._off_orn = (np.array(v, dtype=float) for v in p.invertTransform(*self._inertial))
        self.mass = sum(p.getDynamicsInfo(self.robot, i, physicsClientId=c)[0]
                        for i in range(-1, p.getNumJoints(self.robot, physicsClientId=c)))  # kg
        shapes = p.getCollisionShapeData(self.robot, self.foot_ids[0], physicsClientId=c)
        # Radius of the foot's contact sphere (0 if the foot is not a sphere), m.
        self.foot_radius = float(shapes[0][3][0]) if shapes and shapes[0][2] == p.GEOM_SPHERE else 0.0

    # ------------------------------------------------------------------ state
    def reset(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Place the robot at configuration ``q`` (18,) with velocity ``dq`` (18,) (default rest)."""
        q = np.asarray(q, dtype=float)
        dq = np.zeros(N_Q) if dq is None else np.asarray(dq, dtype=float)
        if q.shape != (N_Q,) or dq.shape != (N_Q,):
            raise ValueError(f"q and dq must have shape ({N_Q},), got {q.shape} and {dq.shape}")
        c = self.client
        qj, dqj = q[JOINTS] * self.signs, dq[JOINTS] * self.signs
        for k, jid in enumerate(self.joint_ids):
            p.resetJointState(self.robot, jid, qj[k], dqj[k], physicsClientId=c)
        if self.held.size:
            p.setJointMotorControlArray(self.robot, [self.joint_ids[k] for k in self.held],
                                        p.POSITION_CONTROL, targetPositions=qj[self.held].tolist(),
                                        targetVelocities=[0.0] * self.held.size,
                                        positionGains=[1.0] * self.held.size,
                                        forces=self.torque_limit[self.held].tolist(), physicsClientId=c)
        rpy = q[BASE_RPY]
        R = rpy_to_matrix(rpy)[0]
        orn = p.getQuaternionFromEuler(rpy.tolist())
        com_pos, com_orn = p.multiplyTransforms(q[BASE_POS].tolist(), orn, *self._inertial)
        omega = euler_rate_matrix(rpy) @ dq[BASE_RPY]
        lever = R @ np.asarray(self._inertial[0])
        v_com = dq[BASE_POS] + np.cross(omega, lever)
        p.resetBasePositionAndOrientation(self.robot, com_pos, com_orn, physicsClientId=c)
        p.resetBaseVelocity(self.robot, v_com.tolist(), omega.tolist(), physicsClientId=c)
        p.performCollisionDetection(physicsClientId=c)  # contact flags valid before the first tick
        self.t = 0.0
        self._pending_force = None

    def standing_q(self, q_joints: np.ndarray, xy: tuple[float, float] = (0.0, 0.0),
                   rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   penetration: float = 5e-4) -> np.ndarray:
        """Configuration (18,) with joints ``q_joints`` (12,) rad whose lowest foot touches the ground.

        The base is lowered ``penetration`` m further so the contacts exist from the first tick.
        """
        return standing_configuration(self.spec, self.foot_radius, q_joints, xy, rpy, penetration)

    def state(self) -> RobotState:
        """The current state of the robot (see ``RobotState``)."""
        c, rob = self.client, self.robot
        com_pos, com_orn = p.getBasePositionAndOrientation(rob, physicsClientId=c)
        v_com, omega = p.getBaseVelocity(rob, physicsClientId=c)
        angles, rates, _, _ = zip(*p.getJointStates(rob, self.joint_ids, physicsClientId=c))
        q = np.empty(N_Q)
        dq = np.empty(N_Q)
        R = np.empty((3, 3))
        # the link frame's pose and rates from the inertial frame's (PyBullet's tuples as they come)
        base_state(com_pos, com_orn, v_com, omega, self._off_pos, self._off_orn, q, dq, R)
        np.multiply(angles, self.signs, out=q[JOINTS])
        np.multiply(rates, self.signs, out=dq[JOINTS])
        links = tuple(zip(*p.getLinkStates(rob, self.foot_ids, computeLinkVelocity=1,
                                           computeForwardKinematics=1, physicsClientId=c)))
        # Toe links carry their inertial frame at the link origin, so links[6] is the foot velocity.
        return RobotState(t=self.t, q=q, dq=dq, omega=np.array(omega), R=R, contact=self.contact_flags(),
                          foot_pos=np.array(links[4]), foot_vel=np.array(links[6]))

    def contact_flags(self) -> np.ndarray:
        """(4,) uint8: 1 where the foot link touches the ground plane (either side of the pair)."""
        flags = np.zeros(N_LEGS, dtype=np.uint8)
        rob, leg = self.robot, self._foot_leg
        for cp in p.getContactPoints(rob, self.plane, physicsClientId=self.client):
            # cp[1], cp[2]: bodies A, B; cp[3], cp[4]: their links.
            k = leg.get(cp[3] if cp[1] == rob else cp[4] if cp[2] == rob else None)
            if k is not None:
                flags[k] = 1
        return flags

    def contact_forces(self) -> np.ndarray:
        """(4, 3) N: the ground's force on each foot (world) at the last tick: the solver's
        normal and friction impulses of every foot/plane contact point, per foot summed."""
        f = np.zeros((N_LEGS, 3))
        rob, leg = self.robot, self._foot_leg
        for cp in p.getContactPoints(rob, self.plane, physicsClientId=self.client):
            on_a = cp[1] == rob
            k = leg.get(cp[3] if on_a else cp[4])
            if k is None:
                continue
            # the normal force cp[9] along cp[7] (B to A) acts on A; the friction forces cp[10],
            # cp[12] along cp[11], cp[13] act on B (checked by a steady push on the base)
            force = (cp[9] * np.asarray(cp[7]) - cp[10] * np.asarray(cp[11])
                     - cp[12] * np.asarray(cp[13]))
            f[k] += force if on_a else -force
        return f

    def joint_velocities(self) -> np.ndarray:
        """(12,) rad/s in symrom's signs."""
        js = p.getJointStates(self.robot, self.joint_ids, physicsClientId=self.client)
        return np.array([s[1] for s in js]) * self.signs

    def scale_inertia(self, trunk_mass: float, leg_mass: float, inertia: float) -> None:
        """Scale the base link's mass by ``trunk_mass``, every other link's by ``leg_mass``, and
        each link's inertia with its mass and by ``inertia``. ``mass`` stays the nominal one
        (what a controller may know of the robot)."""
        c, rob = self.client, self.robot
        for link in range(-1, p.getNumJoints(rob, physicsClientId=c)):
            mass, _, diag = p.getDynamicsInfo(rob, link, physicsClientId=c)[:3]
            s = trunk_mass if link == -1 else leg_mass
            p.changeDynamics(rob, link, mass=mass * s, localInertiaDiagonal=[v * s * inertia for v in diag],
                             physicsClientId=c)

    def add_payload(self, mass: float) -> None:
        """A point load of ``mass`` kg at the base link's centre of mass (its inertia kept);
        ``mass`` stays the nominal one."""
        if not (np.isfinite(mass) and mass >= 0):
            raise ValueError(f"payload must be a mass >= 0 kg, got {mass}")
        c, rob = self.client, self.robot
        m0, _, diag = p.getDynamicsInfo(rob, -1, physicsClientId=c)[:3]
        p.changeDynamics(rob, -1, mass=m0 + mass, localInertiaDiagonal=list(diag), physicsClientId=c)

    def set_ground_friction(self, mu: float) -> None:
        """Lateral friction of the ground (the feet carry 1; Bullet multiplies the two)."""
        p.changeDynamics(self.plane, -1, lateralFriction=mu, physicsClientId=self.client)

    def set_ground_contact(self, stiffness: float, damping: float) -> None:
        """The ground contact as a spring-damper: ``stiffness`` N/m, ``damping`` N s/m (Bullet's
        contactStiffness / contactDamping of the plane)."""
        check_ground_contact(stiffness, damping)
        p.changeDynamics(self.plane, -1, contactStiffness=stiffness, contactDamping=damping,
                         physicsClientId=self.client)

    def set_actuator_effects(self, effects: ActuatorEffects) -> None:
        """Joint damping and friction loss from now on, as at construction (Bullet's joint damping;
        a velocity motor towards rest with the friction loss as its force, on the joints not
        held). Bullet has no armature: a non-zero one is refused (ValueError)."""
        if any(effects.armature):
            raise ValueError(f"robot {self.spec.name!r}: the pybullet engine has no armature "
                             f"(actuator effect armature {effects.armature[:3]}); use engine='mujoco'")
        c = self.client
        for jid, d in zip(self.joint_ids, effects.damping):
            p.changeDynamics(self.robot, jid, jointDamping=d, physicsClientId=c)
        p.setJointMotorControlArray(self.robot, self._driven_ids, p.VELOCITY_CONTROL,
                                    forces=[effects.friction_loss[k] for k in self._driven], physicsClientId=c)
        self.effects = effects

    # ---------------------------------------------------------------- driving
    def step(self, tau: np.ndarray, report: bool = True) -> np.ndarray | None:
        """Apply joint torques ``tau`` (12,) N m for one physics tick; return the applied (12,).

        Requests beyond the robot's torque limits are saturated. ``report=False`` returns
        None instead: what held joints' motors applied then need not be read back (a
        caller logging every other tick asks only on those).
        """
        tau = np.minimum(np.maximum(np.asarray(tau, dtype=float), self._neg_limit), self.torque_limit)
        if tau.shape != (N_JOINTS,) or not np.isfinite(tau).all():
            raise ValueError(f"tau must be {N_JOINTS} finite torques, got {tau!r}")
        c = self.client
        forces = tau * self.signs
        if self.held.size:
            forces = forces[self._driven]
        p.setJointMotorControlArray(self.robot, self._driven_ids, p.TORQUE_CONTROL,
                                    forces=forces.tolist(), physicsClientId=c)
        if self._pending_force is not None:
            com_pos, _ = p.getBasePositionAndOrientation(self.robot, physicsClientId=c)
            p.applyExternalForce(self.robot, -1, self._pending_force.tolist(), com_pos,
                                 p.WORLD_FRAME, physicsClientId=c)
            self._pending_force = None
        p.stepSimulation(physicsClientId=c)
        self.t += self._dt
        if not report:
            return None
        if self.held.size:  # what the solver's motors applied to hold them
            js = p.getJointStates(self.robot, self._held_ids, physicsClientId=c)
            tau = tau.copy()
            tau[self.held] = np.array([s[3] for s in js]) * self.signs[self.held]
        return tau

    def hold_joints(self, joints: list[int]) -> None:
        """Hold the joints ``joints`` (indices into the 12, symrom order) at the angles of each
        ``reset``: PyBullet's position motors lock them within the torque limits, the torques
        given to ``step`` for them are ignored, and ``step`` returns the torques that held them."""
        self.held = np.asarray(sorted(set(int(k) for k in joints)), dtype=int)
        self._driven = np.array([k for k in range(N_JOINTS) if k not in set(self.held.tolist())], dtype=int)
        self._driven_ids = [self.joint_ids[k] for k in self._driven]
        self._held_ids = [self.joint_ids[k] for k in self.held]

    def apply_base_force(self, force_world: np.ndarray) -> None:
        """Push the base's centre of mass with ``force_world`` (3,) N during the next tick only."""
        f = np.asarray(force_world, dtype=float)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise ValueError(f"force must be 3 finite numbers, got {force_world!r}")
        self._pending_force = f

    def close(self) -> None:
        """Give the client up (idempotent): emptied for the next world, or disconnected."""
        if getattr(self, "client", None) is not None and self.client >= 0:
            try:
                release(self.client)
            except p.error:
                pass
            self.client = -1

    def __enter__(self) -> BulletWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()


__all__ = ["BulletWorld", "client", "p", "release"]
