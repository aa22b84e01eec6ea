"""Rigid-body facts of a robot for controllers: body mass and inertia, legs' own weight.

Both come from the robot's URDF through PyBullet (each in a private DIRECT
client), in symrom's joint order and signs. Units: kg, m, kg m^2, N m.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cache

import numpy as np

from symrom.robots import get_robot, robot_key
from symrom.robots.stance import standing_joints

GRAVITY = 9.81


@dataclass(frozen=True)
class BodyModel:
    """Rigid-body summary of the robot in its standing pose.

    mass kg; com_base (3,) m, CoM in the base frame; inertia (3, 3) kg m^2
    about the CoM, base frame, of the whole robot; inertia_upper (3, 3) the same
    for the links that turn with the trunk while the feet are planted (trunk,
    hips, rotors up to the hip-flexion joints), the inertia the body shows in
    stance; foot_radius m.
    """

    mass: float
    com_base: np.ndarray
    inertia: np.ndarray
    inertia_upper: np.ndarray
    foot_radius: float


def body_model(robot: str) -> BodyModel:
    """Mass, CoM and composite inertia of ``robot`` standing, from its URDF (via PyBullet)."""
    return _body_model(robot_key(robot))


@cache
def _body_model(robot: str) -> BodyModel:
    from symrom.sim.bullet import client, p, release

    desc = get_robot(robot)
    cid = client()
    try:
        rob = p.loadURDF(str(desc.urdf_path), flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        names = {p.getJointInfo(rob, i, physicsClientId=cid)[1].decode(): i
                 for i in range(p.getNumJoints(rob, physicsClientId=cid))}
        q = standing_joints(robot) * desc.signs  # URDF angles
        for k, n in enumerate(desc.joint_names):
            p.resetJointState(rob, names[n], q[k], physicsClientId=cid)
        p.resetBasePositionAndOrientation(rob, [0, 0, 0], [0, 0, 0, 1], physicsClientId=cid)
        dyn0 = p.getDynamicsInfo(rob, -1, physicsClientId=cid)
        base_in = np.asarray(dyn0[3])
        ms, coms, inertias = [dyn0[0]], [base_in], [
            (np.asarray(p.getMatrixFromQuaternion(dyn0[4])).reshape(3, 3), np.asarray(dyn0[2]))]
        # The reset put the base's inertial frame at the origin, so the base link frame sits at
        # -base_in: shift link CoMs by +base_in to express them in the base link frame.
        upper = [True]
        lower_joints = {names[n] for k, n in enumerate(desc.joint_names) if k % 3 != 0}
        for i in range(p.getNumJoints(rob, physicsClientId=cid)):
            parent = p.getJointInfo(rob, i, physicsClientId=cid)[16]
            upper.append(i not in lower_joints and upper[parent + 1])
            d = p.getDynamicsInfo(rob, i, physicsClientId=cid)
            ls = p.getLinkState(rob, i, computeForwardKinematics=1, physicsClientId=cid)
            ms.append(d[0])
            coms.append(np.asarray(ls[0]) + base_in)
            inertias.append((np.asarray(p.getMatrixFromQuaternion(ls[1])).reshape(3, 3),
                             np.asarray(d[2])))
    finally:
        release(cid)
    ms_a, coms_a = np.asarray(ms), np.asarray(coms)
    mass = float(ms_a.sum())
    com = (ms_a[:, None] * coms_a).sum(0) / mass
    inertia, inertia_upper = np.zeros((3, 3)), np.zeros((3, 3))
    for m, c, (Rl, Id), up in zip(ms_a, coms_a, inertias, upper):
        r = c - com
        term = Rl @ np.diag(Id) @ Rl.T + m * (r @ r * np.eye(3) - np.outer(r, r))
        inertia += term
        if up:
            inertia_upper += term
    return BodyModel(mass=mass, com_base=com, inertia=inertia, inertia_upper=inertia_upper,
                     foot_radius=desc.foot_radius)


class _FixedBaseCopy:
    """A private fixed-base PyBullet copy of a robot for inverse dynamics, shared by the
    ``LegGravity`` of that robot in this process: a jump's controller would otherwise connect
    a client and load the URDF anew (tens of ms). A lock keeps a gravity setting and the
    inverse dynamics that use it together when threads share the copy."""

    def __init__(self, robot: str):
        from symrom.sim.bullet import client, p

        desc = get_robot(robot)
        self.p = p
        self.cid = client()
        self.rob = p.loadURDF(str(desc.urdf_path), useFixedBase=True,
                              flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=self.cid)
        names = {p.getJointInfo(self.rob, i, physicsClientId=self.cid)[1].decode(): i
                 for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))}
        movable = [i for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))
                   if p.getJointInfo(self.rob, i, physicsClientId=self.cid)[2] != p.JOINT_FIXED]
        # inverse dynamics orders the movable joints by index; map to symrom's order
        self.order = np.array([movable.index(names[n]) for n in desc.joint_names])
        self.inv = np.argsort(self.order)
        self.zeros = [0.0] * len(movable)
        self.lock = threading.Lock()

    def __del__(self) -> None:
        try:
            self.p.disconnect(self.cid)
        except Exception:  # already gone at interpreter exit
            pass


@cache
def _fixed_base_copy(robot: str) -> _FixedBaseCopy:
    return _FixedBaseCopy(robot)


class LegGravity:
    """Joint torques (12,) N m that hold the legs' own weight, for a given base orientation.

    A convex MPC treats the legs as massless, but a Go1's thighs and calves carry
    about a third of its mass; without this term the feet push with less than the
    planned force. Uses a private fixed-base PyBullet copy of the robot (its
    inverse dynamics at zero velocity and acceleration, gravity turned into the
    base frame), one per robot and process.
    """

    def __init__(self, robot: str):
        self._copy = _fixed_base_copy(robot_key(robot))
        signs = np.asarray(get_robot(robot).signs, dtype=float)
        self._signs_in = signs[self._copy.inv]  # signs in inverse-dynamics order
        self._signs_out = signs

    def torques(self, q_joints: np.ndarray, R: np.ndarray) -> np.ndarray:
        """(12,) N m for joint angles (12,) rad and base orientation R (3, 3) base -> world."""
        c = self._copy
        gx, gy, gz = (-GRAVITY * R[2]).tolist()  # R^T (0, 0, -g)
        q = np.asarray(q_joints, dtype=float)[c.inv] * self._signs_in
        with c.lock:
            c.p.setGravity(gx, gy, gz, physicsClientId=c.cid)
            tau = c.p.calculateInverseDynamics(c.rob, q.tolist(), c.zeros, c.zeros, physicsClientId=c.cid)
        return np.array(tau)[c.order] * self._signs_out
