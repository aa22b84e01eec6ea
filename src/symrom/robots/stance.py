"""Standing poses from a robot's description: leg inverse kinematics and the start pose.

One way to stand a robot, shared by every motion: feet level under the hips
(their positions at zero joint angles, fore and aft at the hip flexion axis), the base at a given height, joint
angles from damped Newton steps on the URDF kinematics that start at the
description's standing leg posture and keep the knees in its range.
Units: m, rad; base-frame feet (4, 3); joint angles (12,) in symrom's order.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_LEGS, N_Q
from symrom.robots import get_robot, leg_kinematics, robot_key
from symrom.robots.description import RobotDescription
from symrom.robots.kinematics import LegKinematics

# m the feet start inside the ground (as loaded foot pads would), so contact exists from t = 0
FOOT_PRELOAD = 5e-4


def leg_ik(robot: str, feet_base: np.ndarray, q_guess: np.ndarray | None = None,
           iters: int = 30) -> np.ndarray:
    """Joint angles (12,) rad putting the feet at ``feet_base`` (4, 3) m (base frame).

    Damped Newton iterations on the URDF kinematics from ``q_guess`` (default the
    description's standing posture); knees are kept in the description's range.
    """
    return solve_leg_ik(get_robot(robot), leg_kinematics(robot), feet_base, q_guess, iters)


def solve_leg_ik(desc: RobotDescription, kin: LegKinematics, feet_base: np.ndarray,
                 q_guess: np.ndarray | None = None, iters: int = 30) -> np.ndarray:
    """``leg_ik`` of a description and its kinematics given as objects (a description being
    written, not yet a robot by name)."""
    q = np.array(desc.stance_joints if q_guess is None else q_guess, dtype=float)
    for _ in range(iters):
        p, J = kin.foot_positions_and_jacobians(q[None])
        err = feet_base - p[0]
        if np.max(np.abs(err)) < 1e-7:
            break
        for k in range(N_LEGS):
            Jk = J[0, k]
            q[3 * k:3 * k + 3] += np.linalg.solve(Jk.T @ Jk + 1e-6 * np.eye(3), Jk.T @ err[k])
        q[2::3] = np.clip(q[2::3], *desc.knee_range)
    return q


def nominal_feet(robot: str) -> np.ndarray:
    """(4, 3) m: the feet under the hips, base frame: at zero joint angles (legs straight),
    moved fore and aft to the hip flexion axis where the straight leg is not plumb (the
    Laikago's feet sit 0.16 m behind its hips at zero angles: standing there would put
    four fifths of its weight on the front legs). Where it is plumb (A1, Go1) the two are
    the same numbers."""
    return feet_under_hips(leg_kinematics(robot))


def feet_under_hips(kin: LegKinematics) -> np.ndarray:
    """``nominal_feet`` of leg kinematics given as an object: (4, 3) m, base frame."""
    feet = kin.foot_positions(np.zeros((1, N_JOINTS)))[0]
    feet[:, 0] = kin.hip_positions()[:, 0]
    return feet


def standing_joints(robot: str, height: float | None = None, dx: float = 0.0) -> np.ndarray:
    """(12,) joint angles for the base at ``height`` m (default: the start height) above
    level ground, feet under the hips shifted ``dx`` m forward (base frame)."""
    return _standing(robot_key(robot), height, dx).copy()


@lru_cache(maxsize=256)
def _standing(key: str, height: float | None, dx: float) -> np.ndarray:
    # kept per process: every jump's controller stands its robot at the same heights
    return stand(get_robot(key), leg_kinematics(key), height, dx)


def stand(desc: RobotDescription, kin: LegKinematics, height: float | None = None, dx: float = 0.0) -> np.ndarray:
    """``standing_joints`` of a description and its kinematics given as objects: (12,) rad."""
    h = desc.start_height if height is None else height
    feet = feet_under_hips(kin).copy()
    feet[:, 0] += dx
    feet[:, 2] = -(h - desc.foot_radius)
    return solve_leg_ik(desc, kin, feet)


def start_pose(robot: str, height: float | None = None, yaw: float = 0.0) -> np.ndarray:
    """q (18,): standing at ``height`` m (default: the start height), base at x = y = 0,
    heading ``yaw`` rad. The legs reach ``FOOT_PRELOAD`` below the ground, so a
    collision pass right after the reset already finds the four contacts."""
    h = get_robot(robot).start_height if height is None else height
    q = np.zeros(N_Q)
    q[JOINTS] = standing_joints(robot, h + FOOT_PRELOAD)
    q[BASE_POS] = (0.0, 0.0, h)
    q[BASE_RPY] = (0.0, 0.0, yaw)
    return q


def leg_length(robot: str) -> float:
    """Mean over the legs of thigh plus calf length, m (hip flexion axis to foot centre)."""
    return float(leg_kinematics(robot).segment_lengths().sum(axis=1).mean())
