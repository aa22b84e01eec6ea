"""Leg kinematics read from a robot's URDF: foot positions and leg Jacobians.

The URDF is the one source of robot geometry. Each leg is the chain of joints
from the trunk to the foot link; its three revolute joints are the leg's
``hx, hy, kn``. Fixed joints along the way are folded into the transforms.
Everything is vectorised over samples: joint angles (N, 12) in rad give
foot positions (N, 4, 3) in m and Jacobians (N, 4, 3, 3) in m/rad, both in
the trunk (base) frame.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.names import N_JOINTS, N_LEGS


def _axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations about unit ``axis`` (3,) by ``angle`` (N,) rad (Rodrigues)."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1 - c) * (k @ k)


@dataclass(frozen=True)
class _Link:
    """One joint of a leg chain: fixed origin transform, then a rotation (if revolute)."""
    xyz: np.ndarray  # (3,) m, in the parent frame
    rot: np.ndarray  # (3, 3), origin rotation
    axis: np.ndarray | None  # (3,) unit axis in the child frame; None for fixed


class LegKinematics:
    """Forward kinematics and Jacobians of the four legs of one URDF.

    joint_names: the 12 URDF joint names in symrom's order (FR FL RR RL x hx hy kn).
    foot_links: the 4 URDF foot link names. signs (12,): +1 or -1 per joint,
    symrom angle = sign x URDF angle (a -1 turns the joint's axis around).
    """

    def __init__(self, urdf: str | Path, base_link: str, joint_names: list[str],
                 foot_links: list[str], signs: tuple[float, ...] | None = None):
        if len(joint_names) != N_JOINTS or len(foot_links) != N_LEGS:
            raise ValueError("need 12 joint names and 4 foot links")
        root = ET.parse(urdf).getroot()
        by_child = {}
        for j in root.findall("joint"):  # top level only; <transmission> has <joint> too
            by_child[j.find("child").get("link")] = j
        self.chains: list[list[_Link]] = []
        self.chain_joint_index: list[list[int]] = []  # per chain element: column in q_joints or -1
        for leg, foot in enumerate(foot_links):
            elems, cols = [], []
            link = foot
            while link != base_link:
                j = by_child.get(link)
                if j is None:
                    raise ValueError(f"{urdf}: no joint chain from {base_link!r} to {foot!r}")
                origin = j.find("origin")
                xyz = np.array([float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None
                                                   else "0 0 0").split()])
                rpy = np.array([float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None
                                                   else "0 0 0").split()])
                axis = None
                col = -1
                if j.get("type") in ("revolute", "continuous"):
                    ax = j.find("axis")
                    axis = np.array([float(v) for v in (ax.get("xyz") if ax is not None else "1 0 0").split()])
                    axis = axis / np.linalg.norm(axis)
                    name = j.get("name")
                    if name not in joint_names[3 * leg:3 * leg + 3]:
                        raise ValueError(f"{urdf}: joint {name!r} on the chain to {foot!r} is not one "
                                         f"of that leg's joints {joint_names[3 * leg:3 * leg + 3]}")
                    col = joint_names.index(name)
                    if signs is not None:
                        axis = axis * signs[col]
                elems.append(_Link(xyz, rpy_to_matrix(rpy)[0], axis))
                cols.append(col)
                link = j.find("parent").get("link")
            elems.reverse()
            cols.reverse()
            if sorted(c for c in cols if c >= 0) != list(range(3 * leg, 3 * leg + 3)):
                raise ValueError(f"{urdf}: the chain to {foot!r} does not hold exactly its 3 joints")
            self.chains.append(elems)
            self.chain_joint_index.append(cols)
        self._stacked = self._stack_chains()
        self._flat: tuple | None = None  # the chains as arrays (``chain_arrays``)

    def _stack_chains(self) -> tuple | None:
        """The four chains as arrays over legs, when they share one structure (the usual
        case): all legs are then evaluated at once, one NumPy call per link instead of four."""
        shape = [[el.axis is None for el in ch] for ch in self.chains]
        if any(s != shape[0] for s in shape):
            return None
        steps = []
        for e, fixed in enumerate(shape[0]):
            xyz = np.stack([ch[e].xyz for ch in self.chains])  # (4, 3)
            rot = np.stack([ch[e].rot for ch in self.chains])  # (4, 3, 3)
            if fixed:
                steps.append((xyz, rot, None, None, None))
                continue
            axis = np.stack([ch[e].axis for ch in self.chains])  # (4, 3)
            K = np.zeros((N_LEGS, 3, 3))
            K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
            K -= np.swapaxes(K, 1, 2)
            cols = np.array([cj[e] for cj in self.chain_joint_index])  # (4,)
            steps.append((xyz, rot, axis, K, cols))
        return tuple(steps)

    def _all_legs(self, qj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Feet (N, 4, 3) and Jacobians (N, 4, 3, 3), all legs at once (base frame)."""
        n = qj.shape[0]
        R = np.broadcast_to(np.eye(3), (n, N_LEGS, 3, 3)).copy()
        p = np.zeros((n, N_LEGS, 3))
        axes, origins = [], []
        for xyz, rot, axis, K, cols in self._stacked:
            p = p + np.einsum("nkij,kj->nki", R, xyz)
            R = R @ rot
            if axis is None:
                continue
            axes.append(np.einsum("nkij,kj->nki", R, axis))
            origins.append(p.copy())
            angle = qj[:, cols]  # (N, 4)
            s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
            R = R @ (np.eye(3) + s * K + (1 - c) * (K @ K))
        order = np.argsort([cols[0] for *_, cols in self._stacked if cols is not None])
        J = np.stack([np.cross(axes[i], p - origins[i]) for i in order], axis=-1)
        return p, J

    def _leg(self, leg: int, qj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Foot position (N, 3) and Jacobian (N, 3, 3) of one leg, base frame."""
        n = qj.shape[0]
        R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
        p = np.zeros((n, 3))
        axes, origins = {}, {}
        for el, col in zip(self.chains[leg], self.chain_joint_index[leg]):
            p = p + R @ el.xyz
            R = R @ el.rot
            if el.axis is not None:
                axes[col] = R @ el.axis
                origins[col] = p.copy()
                R = R @ _axis_angle(el.axis, qj[:, col])
        J = np.empty((n, 3, 3))
        for k, col in enumerate(range(3 * leg, 3 * leg + 3)):
            J[:, :, k] = np.cross(axes[col], p - origins[col])
        return p, J

    def segment_lengths(self) -> np.ndarray:
        """(4, 2) m: per leg, hip flexion (hy) to knee and knee to foot, at zero angles."""
        out = np.empty((N_LEGS, 2))
        for leg in range(N_LEGS):
            R, p, at = np.eye(3), np.zeros(3), {}
            for el, col in zip(self.chains[leg], self.chain_joint_index[leg]):
                p = p + R @ el.xyz
                R = R @ el.rot
                if col >= 0:
                    at[col % 3] = p
            out[leg] = np.linalg.norm(at[2] - at[1]), np.linalg.norm(p - at[2])
        return out

    def hip_positions(self) -> np.ndarray:
        """(4, 3) m: per leg, the origin of the hip flexion (hy) joint, base frame."""
        out = np.empty((N_LEGS, 3))
        for leg in range(N_LEGS):
            R, p = np.eye(3), np.zeros(3)
            for el, col in zip(self.chains[leg], self.chain_joint_index[leg]):
                p = p + R @ el.xyz
                R = R @ el.rot
                if col == 3 * leg + 1:
                    out[leg] = p
                    break
        return out

    def foot_positions(self, q_joints: np.ndarray) -> np.ndarray:
        """Feet in the base frame: q_joints (N, 12) rad -> (N, 4, 3) m."""
        return self.foot_positions_and_jacobians(q_joints)[0]

    def jacobians(self, q_joints: np.ndarray) -> np.ndarray:
        """Leg Jacobians d p_foot / d q_leg in the base frame: (N, 12) -> (N, 4, 3, 3)."""
        return self.foot_positions_and_jacobians(q_joints)[1]

    def chain_arrays(self) -> tuple[np.ndarray, ...]:
        """The leg chains as arrays, as ``symrom.robots.compiled.legs_one`` takes them:
        n_el (4,) elements per chain, xyz (4, E, 3), rot (4, E, 3, 3), axis (4, E, 3),
        col (4, E) (the joint's column in the 12 angles, -1 for a fixed joint)."""
        if self._flat is None:
            n = max(len(ch) for ch in self.chains)
            xyz, rot = np.zeros((N_LEGS, n, 3)), np.zeros((N_LEGS, n, 3, 3))
            axis, col = np.zeros((N_LEGS, n, 3)), np.full((N_LEGS, n), -1, dtype=np.int64)
            for k, (ch, cols) in enumerate(zip(self.chains, self.chain_joint_index)):
                for e, (el, c) in enumerate(zip(ch, cols)):
                    xyz[k, e], rot[k, e], col[k, e] = el.xyz, el.rot, c
                    if el.axis is not None:
                        axis[k, e] = el.axis
            n_el = np.array([len(ch) for ch in self.chains], dtype=np.int64)
            self._flat = (n_el, xyz, rot, axis, col)
        return self._flat

    def one(self, q_joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Feet (4, 3) m and Jacobians (4, 3, 3) m/rad of one configuration (12,) rad,
        base frame: the compiled path for controllers (``symrom.robots.compiled``)."""
        from symrom.robots.compiled import legs_one

        pos, J = np.empty((N_LEGS, 3)), np.empty((N_LEGS, 3, 3))
        legs_one(np.ascontiguousarray(q_joints, dtype=float), *self.chain_arrays(), pos, J)
        return pos, J

    def foot_positions_and_jacobians(self, q_joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Both at once: (N, 12) rad -> (N, 4, 3) m and (N, 4, 3, 3) m/rad."""
        qj = np.atleast_2d(np.asarray(q_joints, dtype=float))
        if self._stacked is not None:
            return self._all_legs(qj)
        out = [self._leg(k, qj) for k in range(N_LEGS)]
        return np.stack([o[0] for o in out], axis=1), np.stack([o[1] for o in out], axis=1)


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Base orientation from ZYX Euler angles: rpy (N, 3) rad -> R (N, 3, 3), base to world."""
    rpy = np.atleast_2d(rpy)
    r, p, y = rpy[:, 0], rpy[:, 1], rpy[:, 2]
    rows = zyx_rows(np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y))
    R = np.empty((rpy.shape[0], 3, 3))
    for i, row in enumerate(rows):
        for j, v in enumerate(row):
            R[:, i, j] = v
    return R


def zyx_rows(cr, sr, cp, sp, cy, sy) -> tuple:
    """The rows of R from the cosines and sines of roll, pitch and yaw (floats or arrays; also
    compiled, by ``symrom.sim.engines.compiled`` for the proxy's readings of one state)."""
    return ((cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
            (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
            (-sp, cp * sr, cp * cr))
