"""Rigid-body facts of a robot for controllers: body mass and inertia, legs' own weight.

Both come from the robot's URDF through PyBullet (each in a private DIRECT
client), in symrom's joint order and signs. Units: kg, m, kg m^2, N m.
"""

from __future__ import annotations

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
    from symrom.sim.bullet import p

    desc = get_robot(robot)
    cid = p.connect(p.DIRECT)
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
        p.disconnect(cid)
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


class LegGravity:
    """Joint torques (12,) N m that hold the legs' own weight, for a given base orientation.

    A convex MPC treats the legs as massless, but a Go1's thighs and calves carry
    about a third of its mass; without this term the feet push with less than the
    planned force. Uses a private fixed-base PyBullet copy of the robot (its
    inverse dynamics at zero velocity and acceleration, gravity turned into the
    base frame).
    """

    def __init__(self, robot: str):
        from symrom.sim.bullet import p

        desc = get_robot(robot)
        self._p = p
        self._signs = desc.signs
        self.cid = p.connect(p.DIRECT)
        self.rob = p.loadURDF(str(desc.urdf_path), useFixedBase=True,
                              flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=self.cid)
        names = {p.getJointInfo(self.rob, i, physicsClientId=self.cid)[1].decode(): i
                 for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))}
        movable = [i for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))
                   if p.getJointInfo(self.rob, i, physicsClientId=self.cid)[2] != p.JOINT_FIXED]
        # inverse dynamics orders the movable joints by index; map to symrom's order
        self._order = [movable.index(names[n]) for n in desc.joint_names]
        self._inv = np.argsort(self._order)
        self._zeros = [0.0] * len(movable)

    def torques(self, q_joints: np.ndarray, R: np.ndarray) -> np.ndarray:
        """(12,) N m for joint angles (12,) rad and base orientation R (3, 3) base -> world."""
        p = self._p
        g_base = -GRAVITY * R[2]  # R^T (0, 0, -g)
        p.setGravity(*g_base.tolist(), physicsClientId=self.cid)
        q = (np.asarray(q_joints, dtype=float) * self._signs)[self._inv]
        tau = p.calculateInverseDynamics(self.rob, q.tolist(), self._zeros, self._zeros,
                                         physicsClientId=self.cid)
        return np.asarray(tau)[self._order] * self._signs

    def close(self) -> None:
        if self.cid >= 0:
            try:
                self._p.disconnect(self.cid)
            except self._p.error:
                pass
            self.cid = -1

    def __del__(self) -> None:
        self.close()
