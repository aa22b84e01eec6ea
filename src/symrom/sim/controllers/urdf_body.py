"""The ``urdf`` body source: the robot's URDF read with PyBullet's parser and inverse dynamics.

``UrdfBody(robot)`` (a ``symrom.sim.controllers.body.BodySource``) loads the URDF into a
private DIRECT PyBullet client to read its links in the standing pose, and keeps a fixed-base
copy of the robot for the legs' gravity torques, shared by every controller of that robot in
the process (``body.body_source`` keeps one source per robot): a jump's controller would
otherwise connect a client and load the URDF anew (tens of ms). A lock keeps a gravity
setting and the inverse dynamics that use it together when threads share the copy.
Units: kg, m, kg m^2, N m; joints in symrom's order and signs.
"""

from __future__ import annotations

import threading

import numpy as np

from symrom.robots import get_robot
from symrom.robots.stance import standing_joints
from symrom.sim.controllers.body import RigidLinks
from symrom.sim.engines.bullet import client, p, release

# Only the links' masses, inertias and joints are read: without its meshes a mesh robot's URDF
# loads in milliseconds instead of up to a second or more, and its dynamics are the same to the bit.
_FLAGS = p.URDF_USE_INERTIA_FROM_FILE | p.URDF_IGNORE_VISUAL_SHAPES | p.URDF_IGNORE_COLLISION_SHAPES


class UrdfBody:
    """The body source of robot ``robot`` (its key) from its URDF (see the module docstring)."""

    def __init__(self, robot: str):
        self.robot = robot
        desc = get_robot(robot)
        self.cid = client()
        self.rob = p.loadURDF(str(desc.urdf_path), useFixedBase=True, flags=_FLAGS, physicsClientId=self.cid)
        names = {p.getJointInfo(self.rob, i, physicsClientId=self.cid)[1].decode(): i
                 for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))}
        movable = [i for i in range(p.getNumJoints(self.rob, physicsClientId=self.cid))
                   if p.getJointInfo(self.rob, i, physicsClientId=self.cid)[2] != p.JOINT_FIXED]
        # inverse dynamics orders the movable joints by index; map to symrom's order
        self.order = np.array([movable.index(names[n]) for n in desc.joint_names])
        self.inv = np.argsort(self.order)
        self.zeros = [0.0] * len(movable)
        signs = np.asarray(desc.signs, dtype=float).tolist()
        # (index, sign) pairs as Python numbers: a tick's twelve products cost less in a list than
        # in NumPy's calls, and are the same IEEE products
        self._into = [(int(i), signs[i]) for i in self.inv]  # symrom's order -> inverse dynamics'
        self._out = [(int(i), s) for i, s in zip(self.order, signs)]  # and back
        # the same joints in the same order and signs (the built-in robots): nothing to map, and a
        # product with 1.0 is the number itself
        self._plain = self.order.tolist() == list(range(len(signs))) and all(s == 1.0 for s in signs)
        self.lock = threading.Lock()

    def standing_links(self) -> RigidLinks:
        """The URDF's links (base first, then by joint index) in the standing pose, from a
        floating-base copy loaded into a private client for the purpose."""
        desc = get_robot(self.robot)
        cid = client()
        try:
            rob = p.loadURDF(str(desc.urdf_path), flags=_FLAGS, physicsClientId=cid)
            names = {p.getJointInfo(rob, i, physicsClientId=cid)[1].decode(): i
                     for i in range(p.getNumJoints(rob, physicsClientId=cid))}
            q = standing_joints(self.robot) * desc.signs  # URDF angles
            for k, n in enumerate(desc.joint_names):
                p.resetJointState(rob, names[n], q[k], physicsClientId=cid)
            p.resetBasePositionAndOrientation(rob, [0, 0, 0], [0, 0, 0, 1], physicsClientId=cid)
            dyn0 = p.getDynamicsInfo(rob, -1, physicsClientId=cid)
            base_in = np.asarray(dyn0[3])
            ms, coms, inertias = [dyn0[0]], [base_in], [_rotated(p.getMatrixFromQuaternion(dyn0[4]), dyn0[2])]
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
                inertias.append(_rotated(p.getMatrixFromQuaternion(ls[1]), d[2]))
        finally:
            release(cid)
        return RigidLinks(mass=np.asarray(ms), com=np.asarray(coms), inertia=np.asarray(inertias),
                          trunk=np.asarray(upper))

    def gravity_torques(self, q_joints: np.ndarray, gravity_base: np.ndarray) -> np.ndarray:
        """(12,) N m holding the legs at q_joints (12,) rad, base fixed, under gravity_base (3,)
        m/s^2 (base frame; an array or a sequence of numbers): PyBullet's inverse dynamics at zero
        velocity and acceleration."""
        g = gravity_base
        gx, gy, gz = g.tolist() if isinstance(g, np.ndarray) else g
        q = np.asarray(q_joints, dtype=float).tolist()
        plain = self._plain
        if not plain:
            q = [q[i] * s for i, s in self._into]
        with self.lock:
            p.setGravity(gx, gy, gz, physicsClientId=self.cid)
            tau = p.calculateInverseDynamics(self.rob, q, self.zeros, self.zeros, physicsClientId=self.cid)
        return np.array(tau if plain else [tau[i] * s for i, s in self._out])

    def __del__(self) -> None:
        try:
            p.disconnect(self.cid)
        except Exception:  # already gone at interpreter exit
            pass


def _rotated(quat_matrix: tuple, diagonal: tuple) -> np.ndarray:
    """(3, 3) R diag(d) R^T: a link's principal inertia d (3,) turned by R (PyBullet's 9-tuple)."""
    Rl = np.asarray(quat_matrix).reshape(3, 3)
    return Rl @ np.diag(np.asarray(diagonal)) @ Rl.T
