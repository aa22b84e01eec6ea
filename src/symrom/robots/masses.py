"""The robot's mass distribution read from its URDF: the whole body's centre of mass and the
joint torques that hold the legs' own weight, as functions of the joint angles.

Every link with an ``<inertial>`` block counts, wherever it hangs: the trunk and what is
fixed to it (a rotor, an IMU) and every link of the legs, placed by the URDF's joint tree at
the 12 joint angles (symrom's signs, as ``kinematics.LegKinematics``). Links' rotational
inertias are not used: the centre of mass and the gravity torques need masses and positions
only. Vectorised over samples: joint angles (N, 12) rad give centres of mass (N, 3) m and
torques (N, 12) N m, in the base frame (or for a given base orientation).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.names import N_JOINTS
from symrom.robots.kinematics import _axis_angle, rpy_to_matrix


def _vector(elem: ET.Element | None, key: str) -> np.ndarray:
    text = elem.get(key, "0 0 0") if elem is not None else "0 0 0"
    return np.array([float(v) for v in text.split()])


@dataclass(frozen=True)
class _Node:
    """One link of the tree: its parent's index (-1: the base), the fixed transform of the
    joint into it, its axis (child frame, signed) and its column in the 12 angles (-1: fixed)."""
    name: str
    parent: int
    xyz: np.ndarray
    rot: np.ndarray
    axis: np.ndarray | None
    col: int


class MassModel:
    """The links' masses and centres of mass of one URDF, on its joint tree.

    joint_names: the 12 URDF joint names in symrom's order; signs (12,): symrom angle =
    sign x URDF angle. ``mass`` kg (every link's), ``masses`` (L,) per link.
    """

    def __init__(self, urdf: str | Path, base_link: str, joint_names: list[str], signs: tuple[float, ...]):
        root = ET.parse(urdf).getroot()
        children: dict[str, list] = {}
        for j in root.findall("joint"):
            origin = j.find("origin")
            col = joint_names.index(j.get("name")) if j.get("name") in joint_names else -1
            axis = None
            if col >= 0:
                axis = _vector(j.find("axis"), "xyz") if j.find("axis") is not None else np.array([1.0, 0, 0])
                axis = axis / np.linalg.norm(axis) * signs[col]
            children.setdefault(j.find("parent").get("link"), []).append(
                (j.find("child").get("link"), _vector(origin, "xyz"), rpy_to_matrix(_vector(origin, "rpy"))[0],
                 axis, col))
        inertial = {}
        for link in root.findall("link"):
            m = link.find("inertial/mass")
            if m is not None and m.get("value") is not None:
                inertial[link.get("name")] = (float(m.get("value")), _vector(link.find("inertial/origin"), "xyz"))
        nodes: list[_Node] = []
        stack = [(base_link, -1, np.zeros(3), np.eye(3), None, -1)]
        while stack:  # depth first: every parent before its children
            name, parent, xyz, rot, axis, col = stack.pop()
            nodes.append(_Node(name, parent, xyz, rot, axis, col))
            me = len(nodes) - 1
            for child, cx, cr, ca, cc in reversed(children.get(name, [])):
                stack.append((child, me, cx, cr, ca, cc))
        cols = sorted(n.col for n in nodes if n.col >= 0)
        if cols != list(range(N_JOINTS)):
            raise ValueError(f"{urdf}: the joint tree from {base_link!r} does not hold the 12 joints {joint_names}")
        self.nodes = nodes
        self.masses = np.array([inertial.get(n.name, (0.0, None))[0] for n in nodes])
        self.local_com = np.array([inertial[n.name][1] if n.name in inertial else np.zeros(3) for n in nodes])
        self.mass = float(self.masses.sum())
        # below[c]: the links a joint c carries (those with c on their path to the base)
        below = np.zeros((N_JOINTS, len(nodes)), bool)
        for i, _n in enumerate(nodes):
            k = i
            while k >= 0:
                if nodes[k].col >= 0:
                    below[nodes[k].col, i] = True
                k = nodes[k].parent
        self._below = below

    def _frames(self, qj: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Link centres of mass (N, L, 3), joint axes (N, 12, 3) and joint origins (N, 12, 3),
        base frame."""
        n = qj.shape[0]
        Rs, ps = [], []
        com = np.empty((n, len(self.nodes), 3))
        axes, origins = np.empty((n, N_JOINTS, 3)), np.empty((n, N_JOINTS, 3))
        for i, node in enumerate(self.nodes):
            if node.parent < 0:
                R, p = np.broadcast_to(np.eye(3), (n, 3, 3)), np.zeros((n, 3))
            else:
                Rp, pp = Rs[node.parent], ps[node.parent]
                p = pp + Rp @ node.xyz
                R = Rp @ node.rot
                if node.axis is not None:
                    axes[:, node.col] = R @ node.axis
                    origins[:, node.col] = p
                    R = R @ _axis_angle(node.axis, qj[:, node.col])
            Rs.append(R)
            ps.append(p)
            com[:, i] = p + R @ self.local_com[i]
        return com, axes, origins

    def _com(self, com: np.ndarray) -> np.ndarray:
        """The whole body's centre of mass (N, 3) m from the links' (N, L, 3) m."""
        return np.einsum("l,nlj->nj", self.masses, com) / self.mass

    def _hold(self, frames: tuple[np.ndarray, np.ndarray, np.ndarray], rpy: np.ndarray,
              gravity: float) -> np.ndarray:
        """``hold_torques`` (N, 12) N m from ``_frames``' links and joints at the angles."""
        com, axes, origins = frames
        g_base = -gravity * rpy_to_matrix(np.atleast_2d(rpy))[:, 2, :]  # R^T (0, 0, -g)
        out = np.empty((com.shape[0], N_JOINTS))
        for c in range(N_JOINTS):
            links = self._below[c]
            lever = com[:, links] - origins[:, c, None]  # (N, l, 3)
            moment = np.cross(lever, self.masses[links, None] * g_base[:, None]).sum(axis=1)
            out[:, c] = -np.einsum("ni,ni->n", axes[:, c], moment)
        return out

    def com_base(self, q_joints: np.ndarray) -> np.ndarray:
        """The whole body's centre of mass in the base frame: (N, 12) rad -> (N, 3) m."""
        qj = np.atleast_2d(np.asarray(q_joints, dtype=float))
        return self._com(self._frames(qj)[0])

    def com_base_rate(self, q_joints: np.ndarray, dq_joints: np.ndarray, eps: float = 1e-6) -> np.ndarray:
        """Its rate in the base frame: joint angles and rates (N, 12) -> (N, 3) m/s (central
        difference along the joint rates)."""
        qj = np.atleast_2d(np.asarray(q_joints, dtype=float))
        dqj = np.atleast_2d(np.asarray(dq_joints, dtype=float))
        return (self.com_base(qj + eps * dqj) - self.com_base(qj - eps * dqj)) / (2 * eps)

    def hold_torques(self, q_joints: np.ndarray, rpy: np.ndarray, gravity: float) -> np.ndarray:
        """Joint torques (N, 12) N m that hold the legs' own weight, standing still: joint
        angles (N, 12) rad, base orientation (N, 3) rad (ZYX), gravity m/s^2. The torque a
        joint's motor gives about its axis to carry the links below it; a foot's ground force
        F adds -J^T F (``preprocess.ground_reaction_forces``)."""
        qj = np.atleast_2d(np.asarray(q_joints, dtype=float))
        return self._hold(self._frames(qj), rpy, gravity)

    def com_and_hold(self, q_joints: np.ndarray, rpy: np.ndarray, gravity: float) -> tuple[np.ndarray, np.ndarray]:
        """``com_base`` (N, 3) m and ``hold_torques`` (N, 12) N m at the same joint angles
        (N, 12) rad (rpy, gravity as ``hold_torques``'), from one placement of the links: the
        same numbers as the two apart."""
        qj = np.atleast_2d(np.asarray(q_joints, dtype=float))
        frames = self._frames(qj)
        return self._com(frames[0]), self._hold(frames, rpy, gravity)
