"""The MuJoCo world: one quadruped on a plane, compiled by MuJoCo from the robot's description.

The model is the description's URDF compiled by MuJoCo (``MjSpec.from_file``), with
a free joint added to the base link and its fixed links kept as bodies (the feet
must stay bodies of their own); an inertia that breaks the triangle inequality is
balanced (MuJoCo's ``balanceinertia``; PyBullet zeroes it); visual meshes are dropped, and collision meshes
whose files are missing too (the primitives remain; the feet are the URDF's
spheres). A description may name an MJCF model of the robot instead
(``mjcf = "..."``, e.g. a MuJoCo Menagerie model), simulated as published: its own
contact parameters (friction, condim, solref, solimp, priority; ``contact_stiffness``
/ ``contact_damping`` still override the solref), options (friction cone, impratio),
joint limits, visual geoms kept out of contacts; its actuators, keyframes and sensors
are replaced by symrom's torque actuators. Its joints and base are named as the
description's; its feet are found as the description's ``[feet]`` says (a body, a
geom, a site or a point in a body: ``robots.mjcf.foot_frames``), each given a massless
frame body at the foot's point, named as the foot link of the URDF symrom derives.
Then:

- every joint gets a torque actuator (a general actuator of gain 1); ``step``
  saturates the request at the description's torque limits;
- ``hold_joints`` turns chosen actuators into position servos (stiffness
  ``limit / HOLD_ERROR``, critically damped for ``HOLD_INERTIA``, force limited to
  the torque limit), as PyBullet's position motors hold them;
- joint damping, armature and friction loss come from ``ActuatorEffects`` (the
  description's ``[actuators]`` unless given), MuJoCo's own joint properties;
- robot geoms collide with the ground only (``WorldConfig.self_collision`` adds
  robot-robot contacts); foot/ground friction is ``lateral_friction`` (MuJoCo takes
  the larger of two geoms' values, so every geom of a URDF carries it; an MJCF's
  geoms keep theirs and the ground carries it); a URDF's contacts have three
  dimensions (no spinning or rolling friction); ``contact_stiffness`` /
  ``contact_damping`` become MuJoCo's direct ``solref = (-k, -d)``, else
  ``SOLREF`` (time constant s, damping ratio);
- the integrator is ``implicitfast`` (damping terms implicit) at ``WorldConfig.dt``.

The compiled model is kept per (robot, settings) in the process; each world works
on its own copy. Units and coordinates as in ``symrom.sim.engines.world``.
"""

from __future__ import annotations

import copy
from functools import cache

import mujoco
import numpy as np

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_LEGS, N_Q
from symrom.robots import ActuatorEffects, RobotDescription, get_robot, robot_key
from symrom.robots.kinematics import rpy_to_matrix
from symrom.robots.mjcf import drop_missing_meshes, foot_frames
from symrom.sim.engines.compiled import base_state, mujoco_foot_forces, mujoco_state, mujoco_torques, settle_mujoco
from symrom.sim.engines.world import (
    RobotState,
    WorldConfig,
    check_ground_contact,
    euler_rate_matrix,
    standing_configuration,
)

SOLREF = (0.005, 1.0)  # s, damping ratio: ground contact as stiff as a 1 kHz step resolves well
CONTACT_MARGIN = 0.001  # m: a foot this near the ground counts as touching it (no force before it does)
CONTACT_IMPEDANCE = 0.9  # MuJoCo's solimp d of a contact set by set_ground_contact (its lowest default)
HOLD_ERROR = 0.005  # rad: a held joint's servo gives its full torque limit at this error
HOLD_INERTIA = 0.02  # kg m^2: the inertia the held joints' servo damping is set for
_ROBOT, _GROUND = 2, 1  # contype / conaffinity bits
_ZERO3, _IDENTITY = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])  # no offset from the link frame


class ModelError(ValueError):
    """A robot description MuJoCo cannot compile; the message names the file."""


def _spec(desc: RobotDescription) -> mujoco.MjSpec:
    """The robot's spec: the MJCF named by the description, else its URDF with a free base."""
    if desc.mjcf_path is not None:
        spec = mujoco.MjSpec.from_file(str(desc.mjcf_path))
        src = desc.mjcf_path
        # symrom drives the joints by torque through actuators of its own: the model's go, and with
        # them its keyframes (sized by them) and sensors (which may read them)
        for el in (*spec.actuators, *spec.keys, *spec.sensors):
            spec.delete(el)
    else:
        spec = mujoco.MjSpec.from_file(str(desc.urdf_path))
        src = desc.urdf_path
        spec.compiler.fusestatic = False  # the foot links must stay bodies
        spec.compiler.discardvisual = True
        spec.compiler.balanceinertia = True  # URDFs with impossible inertias exist (Bullet zeroes them)
    base = spec.body(desc.base_link)
    if base is None:
        raise ModelError(f"robot {desc.name!r}: {src} has no body {desc.base_link!r} (base_link)")
    if not any(j.type == mujoco.mjtJoint.mjJNT_FREE for j in base.joints):
        base.add_freejoint()
    # collision meshes whose files are missing: keep the primitives
    drop_missing_meshes(spec, (desc.mjcf_path or desc.urdf_path).parent)
    return spec


@cache
def _compiled(key: str, config: WorldConfig, effects: ActuatorEffects) -> tuple[mujoco.MjModel, dict]:
    """The compiled model of robot ``key`` and the ids a world needs (shared; worlds copy it)."""
    desc = get_robot(key)
    spec = _spec(desc)
    opt = spec.option
    opt.timestep = config.dt
    opt.gravity = [0.0, 0.0, -config.gravity]
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    friction = [config.lateral_friction, config.spinning_friction, config.rolling_friction]
    solref = ([-config.contact_stiffness, -config.contact_damping] if config.contact_stiffness is not None
              else list(SOLREF))
    published = desc.mjcf_path is not None  # an MJCF keeps its own contact parameters and visual geoms
    for g in spec.geoms:
        if published and not (g.contype or g.conaffinity):
            continue
        g.contype, g.conaffinity = _ROBOT, (_ROBOT if config.self_collision else 0)
        if not published:
            g.condim, g.friction = 3, friction
        if not published or config.contact_stiffness is not None:
            g.solref = solref
        g.margin = g.gap = CONTACT_MARGIN
    if desc.feet is not None and desc.feet.kind != "link":  # feet named as geoms, sites or points in bodies
        try:
            at = foot_frames(spec.compile(), desc.feet)
        except ValueError as e:
            raise ModelError(f"robot {desc.name!r}: {desc.mjcf_path}: {e}") from None
        for name, f in zip(desc.foot_links, at):  # a massless frame body at each foot, named as the URDF's foot link
            spec.body(f.body_name).add_body(name=name, pos=f.point.tolist())
    spec.worldbody.add_geom(name="ground", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1],
                            contype=_GROUND, conaffinity=_ROBOT, condim=3, friction=friction, solref=solref,
                            margin=CONTACT_MARGIN, gap=CONTACT_MARGIN)
    for k, name in enumerate(desc.joint_names):
        j = spec.joint(name)
        if j is None:
            raise ModelError(f"robot {desc.name!r}: the model has no joint {name!r}")
        j.damping = [effects.damping[k], 0.0, 0.0]  # linear damping (MuJoCo 4 takes a polynomial)
        j.armature, j.frictionloss = effects.armature[k], effects.friction_loss[k]
        spec.add_actuator(name=f"tau_{name}", trntype=mujoco.mjtTrn.mjTRN_JOINT, target=name,
                          gainprm=[1.0] + [0.0] * 9, biasprm=[0.0] * 10,
                          biastype=mujoco.mjtBias.mjBIAS_AFFINE)  # zero bias until held
    try:
        model = spec.compile()
    except ValueError as e:
        raise ModelError(f"robot {desc.name!r}: MuJoCo cannot compile {desc.mjcf_path or desc.urdf_path}: "
                         f"{e}") from None
    bid = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in (desc.base_link, *desc.foot_links)}
    for n, i in bid.items():
        if i < 0:
            raise ModelError(f"robot {desc.name!r}: the model has no body {n!r}")
    jids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in desc.joint_names]
    feet = [bid[n] for n in desc.foot_links]
    if desc.feet is not None and desc.feet.kind != "link":
        frames = foot_frames(model, desc.feet)
        foot_geoms, radius = [list(f.geoms) for f in frames], frames[0].radius
    else:
        foot_geoms = [[g for g in range(model.ngeom) if model.geom_bodyid[g] == b] for b in feet]
        radius = next((float(model.geom_size[g, 0]) for g in foot_geoms[0]
                       if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE), 0.0)
    ids = {"base": bid[desc.base_link], "feet": feet, "qadr": model.jnt_qposadr[jids].copy(),
           "vadr": model.jnt_dofadr[jids].copy(), "foot_radius": radius, "foot_geoms": foot_geoms,
           "ground": mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "ground")}
    return model, ids


class MujocoWorld:
    """One robot on a plane in MuJoCo (a ``symrom.sim.engines.world.World``; see the module docstring).

    robot: a built-in name or a description file; config: physics settings;
    effects: actuator effects (default: the description's ``[actuators]``).
    """

    engine = "mujoco"

    def __init__(self, robot: str, config: WorldConfig = WorldConfig(), effects: ActuatorEffects | None = None):
        self.spec: RobotDescription = get_robot(robot)
        self.config = config
        self.effects = self.spec.actuators if effects is None else effects
        shared, ids = _compiled(robot_key(robot), config, self.effects)
        self.model = copy.deepcopy(shared)  # scale_inertia and hold_joints edit it
        self.data = mujoco.MjData(self.model)
        self.torque_limit = np.asarray(self.spec.torque_limit, dtype=float)
        self._neg_limit = -self.torque_limit
        self.signs = self.spec.signs
        self._base, self._feet = ids["base"], ids["feet"]
        self._qadr, self._vadr = ids["qadr"], ids["vadr"]
        self._ground = ids["ground"]
        self._leg_of_geom = np.full(self.model.ngeom, -1)  # geom -> leg of its foot, or -1
        for k, geoms in enumerate(ids["foot_geoms"]):
            self._leg_of_geom[geoms] = k
        self._leg_list = self._leg_of_geom.tolist()
        # the arrays ``mujoco_state`` takes, typed once
        self._body_root = self.model.body_rootid.astype(np.int64)
        self._feet_arr = np.asarray(self._feet, dtype=np.int64)
        self._signs_arr = np.asarray(self.signs, dtype=float)
        d = self.data  # views of MjData's fixed-size arrays (each attribute read makes a new one)
        self._views = (d.qpos, d.qvel, d.xmat, d.xpos, d.cvel, d.subtree_com)
        self._ctrl = d.ctrl
        self._dt = self.model.opt.timestep  # s, a float (each read of ``opt`` makes a new wrapper)
        self._pyramidal = self.model.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
        self._pushed = False  # a base force is set for the next tick
        self._quat = np.empty(4)
        self.foot_radius = ids["foot_radius"]
        self.mass = float(self.model.body_subtreemass[self._base])  # kg
        self.held: np.ndarray = np.zeros(0, dtype=int)
        self.t = 0.0
        self._forces = np.zeros((N_LEGS, 3))
        self._vel = np.zeros(6)
        self._res = np.zeros(6)
        d, con = self.data, self.data.contact
        settle_mujoco((*self._views, self._body_root, self._base, self._feet_arr, self._qadr, self._vadr,
                       self._signs_arr, con.geom, self._leg_of_geom, self._ground, self._quat, np.empty(N_Q),
                       np.empty(N_Q), np.empty((3, 3)), np.empty(3), np.empty((N_LEGS, 3)), np.empty((N_LEGS, 3)),
                       np.empty(N_LEGS, np.uint8)),
                      (con.geom, con.frame, con.friction, con.dim, con.efc_address, d.efc_force, self._leg_of_geom,
                       self._ground, self._forces))

    # ------------------------------------------------------------------ state
    def reset(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        """Place the robot at ``q`` (18,) with velocity ``dq`` (18,) (default rest)."""
        q = np.asarray(q, dtype=float)
        dq = np.zeros(N_Q) if dq is None else np.asarray(dq, dtype=float)
        if q.shape != (N_Q,) or dq.shape != (N_Q,):
            raise ValueError(f"q and dq must have shape ({N_Q},), got {q.shape} and {dq.shape}")
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)  # clears a pending base push too
        self._pushed = False
        R = rpy_to_matrix(q[BASE_RPY])[0]
        quat = np.empty(4)
        mujoco.mju_mat2Quat(quat, R.reshape(-1))
        d.qpos[0:3], d.qpos[3:7] = q[BASE_POS], quat
        d.qvel[0:3] = dq[BASE_POS]
        d.qvel[3:6] = R.T @ (euler_rate_matrix(q[BASE_RPY]) @ dq[BASE_RPY])  # body-frame angular velocity
        d.qpos[self._qadr] = q[JOINTS] * self.signs
        d.qvel[self._vadr] = dq[JOINTS] * self.signs
        if self.held.size:
            d.ctrl[self.held] = q[JOINTS][self.held] * self.signs[self.held]  # servo targets, URDF angles
        mujoco.mj_forward(m, d)
        self.t = 0.0
        self._forces[:] = 0.0

    def standing_q(self, q_joints: np.ndarray, xy: tuple[float, float] = (0.0, 0.0),
                   rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   penetration: float = 5e-4) -> np.ndarray:
        """Configuration (18,) with joints ``q_joints`` (12,) rad whose lowest foot touches the ground."""
        return standing_configuration(self.spec, self.foot_radius, q_joints, xy, rpy, penetration)

    def state(self) -> RobotState:
        """The current state of the robot (see ``RobotState``): MuJoCo's arrays read in one
        compiled call (``symrom.sim.engines.compiled.mujoco_state``; ``state_reference`` is the same
        through MuJoCo's own functions)."""
        q, dq, R, omega = np.empty(N_Q), np.empty(N_Q), np.empty((3, 3)), np.empty(3)
        foot_pos, foot_vel, contact = np.empty((N_LEGS, 3)), np.empty((N_LEGS, 3)), np.empty(N_LEGS, np.uint8)
        mujoco_state(*self._views, self._body_root, self._base, self._feet_arr, self._qadr, self._vadr,
                     self._signs_arr, self.data.contact.geom, self._leg_of_geom, self._ground, self._quat,
                     q, dq, R, omega, foot_pos, foot_vel, contact)
        return RobotState(t=self.t, q=q, dq=dq, omega=omega, R=R, contact=contact, foot_pos=foot_pos,
                          foot_vel=foot_vel)

    def state_reference(self) -> RobotState:
        """``state`` through NumPy and MuJoCo's functions (``mj_objectVelocity``): the reference
        the compiled read is tested against."""
        m, d = self.model, self.data
        q, dq, R = np.empty(N_Q), np.empty(N_Q), np.empty((3, 3))
        qp, qv = d.qpos, d.qvel
        self._quat[:3], self._quat[3] = qp[4:7], qp[3]  # MuJoCo's (w, x, y, z) as (x, y, z, w)
        omega = d.xmat[self._base].reshape(3, 3) @ qv[3:6]  # qvel holds it in the body frame
        # the free joint sits at the base link frame: the pose and rates are the link frame's
        base_state(qp[0:3], self._quat, qv[0:3], omega, _ZERO3, _IDENTITY, q, dq, R)
        np.multiply(qp[self._qadr], self.signs, out=q[JOINTS])
        np.multiply(qv[self._vadr], self.signs, out=dq[JOINTS])
        foot_vel = np.empty((N_LEGS, 3))
        for k, b in enumerate(self._feet):
            mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, b, self._vel, 0)
            foot_vel[k] = self._vel[3:]
        return RobotState(t=self.t, q=q, dq=dq, omega=omega, R=R, contact=self.contact_flags(),
                          foot_pos=d.xpos[self._feet], foot_vel=foot_vel)

    def _foot_contacts(self) -> list[tuple[int, int, float]]:
        """(contact index, leg, sign) of every foot/ground contact; sign +1 where the foot is
        geom2 (MuJoCo's force acts from geom1 on geom2). A plain loop: there are a dozen."""
        ground, leg = self._ground, self._leg_list
        out = []
        for i, (g1, g2) in enumerate(self.data.contact.geom.tolist()):
            if g1 == ground and leg[g2] >= 0:
                out.append((i, leg[g2], 1.0))
            elif g2 == ground and leg[g1] >= 0:
                out.append((i, leg[g1], -1.0))
        return out

    def contact_flags(self) -> np.ndarray:
        """(4,) uint8: 1 where a foot body touches the ground (within ``CONTACT_MARGIN``)."""
        flags = np.zeros(N_LEGS, dtype=np.uint8)
        for _, k, _ in self._foot_contacts():
            flags[k] = 1
        return flags

    def contact_forces(self) -> np.ndarray:
        """(4, 3) N: the ground's force on each foot (world) in the last tick's solution."""
        return self._forces.copy()

    def _solve_forces(self) -> None:
        if self._pyramidal:
            d = self.data
            con = d.contact
            mujoco_foot_forces(con.geom, con.frame, con.friction, con.dim, con.efc_address, d.efc_force,
                               self._leg_of_geom, self._ground, self._forces)
        else:
            self._solve_forces_reference()

    def _solve_forces_reference(self) -> None:
        """``_solve_forces`` through ``mj_contactForce`` (any friction cone)."""
        f = self._forces
        f[:] = 0.0
        d = self.data
        con = d.contact
        frames, efc = con.frame, con.efc_address
        for i, k, sign in self._foot_contacts():
            if efc[i] < 0:  # within the margin, not touching: no force
                continue
            mujoco.mj_contactForce(self.model, d, i, self._res)  # contact frame, normal first
            f[k] += sign * (frames[i].reshape(3, 3).T @ self._res[:3])

    def joint_velocities(self) -> np.ndarray:
        """(12,) rad/s in symrom's signs."""
        return self.data.qvel[self._vadr] * self.signs

    # ---------------------------------------------------------------- driving
    def step(self, tau: np.ndarray, report: bool = True) -> np.ndarray | None:
        """Apply joint torques ``tau`` (12,) N m for one tick; return the applied (12,) (held
        joints: their servos' torques), or None with ``report=False``."""
        tau = np.ascontiguousarray(tau, dtype=float)
        m, d = self.model, self.data
        if self.held.size or tau.shape != (N_JOINTS,):
            tau = np.minimum(np.maximum(tau, self._neg_limit), self.torque_limit)
            if tau.shape != (N_JOINTS,) or np.count_nonzero(np.isfinite(tau)) != N_JOINTS:
                raise ValueError(f"tau must be {N_JOINTS} finite torques, got {tau!r}")
            ctrl = tau * self.signs
            ctrl[self.held] = d.ctrl[self.held]  # the servos' targets stay
            d.ctrl[:] = ctrl
        else:  # saturate, check and set the actuators in one compiled call
            clipped = np.empty(N_JOINTS)
            if not mujoco_torques(tau, self._neg_limit, self.torque_limit, self._signs_arr, clipped, self._ctrl):
                raise ValueError(f"tau must be {N_JOINTS} finite torques, got {clipped!r}")
            tau = clipped
        # step2 then step1: after a step the positions, contacts and velocities of the new state
        # are computed, so ``state`` reads them without a second forward pass.
        mujoco.mj_step2(m, d)
        if report:
            self._solve_forces()  # the forces of this tick's contacts, before they are recomputed
            applied = tau
            if self.held.size:
                applied = tau.copy()
                applied[self.held] = d.actuator_force[self.held] * self.signs[self.held]
        if self._pushed:  # the push lasts one tick
            d.xfrc_applied[self._base, :3] = 0.0
            self._pushed = False
        mujoco.mj_step1(m, d)
        self.t += self._dt
        return applied if report else None

    def hold_joints(self, joints: list[int]) -> None:
        """Hold the joints ``joints`` (indices into the 12) at the angles of each ``reset`` by
        position servos within the torque limits; ``step`` ignores their torques."""
        self.held = np.asarray(sorted(set(int(k) for k in joints)), dtype=int)
        m = self.model
        for k in range(N_JOINTS):
            if k in set(self.held.tolist()):
                kp = self.torque_limit[k] / HOLD_ERROR
                kv = 2.0 * np.sqrt(kp * HOLD_INERTIA)
                m.actuator_gainprm[k, 0], m.actuator_biasprm[k, :3] = kp, (0.0, -kp, -kv)
                m.actuator_forcelimited[k] = 1
                m.actuator_forcerange[k] = (-self.torque_limit[k], self.torque_limit[k])
            else:
                m.actuator_gainprm[k, 0], m.actuator_biasprm[k, :3] = 1.0, (0.0, 0.0, 0.0)
                m.actuator_forcelimited[k] = 0

    def apply_base_force(self, force_world: np.ndarray) -> None:
        """Push the base's centre of mass with ``force_world`` (3,) N during the next tick only."""
        f = np.asarray(force_world, dtype=float)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise ValueError(f"force must be 3 finite numbers, got {force_world!r}")
        self.data.xfrc_applied[self._base, :3] = f
        self._pushed = True

    def scale_inertia(self, trunk_mass: float, leg_mass: float, inertia: float) -> None:
        """Scale the base's mass by ``trunk_mass``, the other robot bodies' by ``leg_mass``, and
        inertias with the mass and by ``inertia``; ``mass`` stays the nominal one."""
        m = self.model
        for b in range(1, m.nbody):
            s = trunk_mass if b == self._base else leg_mass
            m.body_mass[b] *= s
            m.body_inertia[b] *= s * inertia
        mujoco.mj_setConst(m, self.data)
        mujoco.mj_forward(m, self.data)

    def add_payload(self, mass: float) -> None:
        """A point load of ``mass`` kg at the base's centre of mass; ``mass`` stays the nominal one."""
        if not (np.isfinite(mass) and mass >= 0):
            raise ValueError(f"payload must be a mass >= 0 kg, got {mass}")
        m = self.model
        m.body_mass[self._base] += mass
        mujoco.mj_setConst(m, self.data)
        mujoco.mj_forward(m, self.data)

    def set_ground_friction(self, mu: float) -> None:
        """Foot/ground sliding friction (every geom carries it: MuJoCo takes the larger)."""
        self.model.geom_friction[:, 0] = mu

    def set_ground_contact(self, stiffness: float, damping: float) -> None:
        """The ground contact as a spring-damper: ``stiffness`` N/m, ``damping`` N s/m per foot.

        MuJoCo's soft contact is not a spring in newtons: with impedance d and direct
        ``solref = (-k, -b)`` its force solves (A + R) f = aref - a0, aref = -b v - k r,
        R = (1 - d) / d x A's diagonal (the foot's inverse weight w, ``body_invweight0``). At
        rest that gives r = (1 - d) / d x w x load / k: with d held constant
        (``CONTACT_IMPEDANCE``) and k, b = (1 - d) / d x w x (stiffness, damping) a foot sinks
        by load / stiffness, as on PyBullet's contactStiffness."""
        check_ground_contact(stiffness, damping)
        d = CONTACT_IMPEDANCE
        w = float(np.mean(self.model.body_invweight0[self._feet, 0]))  # 1/kg, along a contact normal
        scale = (1.0 - d) / d * w
        self.model.geom_solref[:] = (-stiffness * scale, -damping * scale)
        self.model.geom_solimp[:, :2] = d

    def set_actuator_effects(self, effects: ActuatorEffects) -> None:
        """Joint damping, armature and friction loss from now on (MuJoCo's dof properties)."""
        m = self.model
        m.dof_damping[self._vadr] = effects.damping
        m.dof_armature[self._vadr] = effects.armature
        m.dof_frictionloss[self._vadr] = effects.friction_loss
        mujoco.mj_setConst(m, self.data)  # armature enters the constants of the constraint solver
        mujoco.mj_forward(m, self.data)
        self.effects = effects

    def close(self) -> None:
        """Nothing to give back (the model and data are freed with the world)."""

    def __enter__(self) -> MujocoWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
