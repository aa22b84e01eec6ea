"""From a planned ground force to a learned model's input, as the data define it.

A model's input is nu = pinv(W_e^T) u with u = [tau, wrench] (``names.U_NAMES``),
the wrench derived from the joint torques through the massless-leg Jacobians
(``data.preprocess.input_from_torques``, the one definition of u). A planned
summed force F = (F_x, F_z) N is executed as per-foot forces (F / 4 when the
trunk is level; ``plan.execute`` adds only a moment-free redistribution) and
joint torques tau = -J^T R^T f; ``u(F)`` is built from those torques by the
same map as a logged sample's u, so nu = B F with

    B (l, 2) = [nu(e_x), nu(e_z)]

at the configuration the push starts from (u is linear in F at a fixed
configuration). The leg Jacobians change during the push; the wrench part of u
does not depend on them (it is F itself), only the torque part does, which a
model whose latents read the base alone does not use.
"""

from __future__ import annotations

import numpy as np

from symrom.data.preprocess import input_from_torques
from symrom.model.hybrid import HybridModel
from symrom.names import BASE_RPY, JOINTS, LEGS, N_LEGS, N_Q, U_NAMES
from symrom.robots import leg_kinematics
from symrom.robots.kinematics import rpy_to_matrix

ALL_LEGS = tuple(range(N_LEGS))


def stance_input(robot: str, q: np.ndarray, F: np.ndarray, legs: tuple[int, ...] = ALL_LEGS) -> np.ndarray:
    """u (18,) = [tau (12) N m, wrench (6)] of the summed world force F (3,) N shared equally by
    the feet ``legs`` (default all four; a froggy's rear-only push: (2, 3)) at configuration q
    (18,): tau_k = -J_k^T R^T F / len(legs) for those legs, 0 for the others, the wrench from
    tau as the data derive it (those feet down)."""
    q = np.asarray(q, dtype=float).reshape(N_Q)
    J = leg_kinematics(robot).jacobians(q[None, JOINTS])[0]  # (4, 3, 3), base frame
    R = rpy_to_matrix(q[None, BASE_RPY])[0]
    f_base = R.T @ (np.asarray(F, dtype=float) / len(legs))
    tau = np.concatenate([-J[k].T @ f_base if k in legs else np.zeros(3) for k in range(N_LEGS)])
    contact = np.array([[1.0 if k in legs else 0.0 for k in range(N_LEGS)]])
    return input_from_torques(robot, q[None], tau[None], contact)[0]


def force_input_map(model: HybridModel, robot: str, q: np.ndarray, legs: tuple[int, ...] = ALL_LEGS) -> np.ndarray:
    """B (l, 2): the model's input nu = B (F_x, F_z) for a summed ground force on the feet
    ``legs`` at configuration q (18,) (module docstring)."""
    cols = [model.autoencoder.encode_input(stance_input(robot, q, e, legs)[None])[0]
            for e in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))]
    return np.stack(cols, axis=1)


def torque_map(robot: str, qs: list[np.ndarray], limits: np.ndarray, share: float = 0.9,
               legs: tuple[int, ...] = ALL_LEGS) -> tuple[np.ndarray, np.ndarray]:
    """(A (m, 2), bounds (m,)): the joint torques A F (N m) that a summed force F = (F_x, F_z) N
    shared equally by the feet ``legs`` asks of every joint at each configuration of ``qs``
    (each (18,)), and ``share`` of the joint's torque limit (``limits`` (12,) N m) as its
    bound, the rest left to the execution's joint PD and attitude moment. Rows that bound the
    same torque (mirrored legs) appear once."""
    rows, bounds = [], []
    for q in qs:
        cols = [stance_input(robot, q, e, legs)[:12] for e in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))]
        rows.append(np.stack(cols, axis=1))
        bounds.append(share * np.asarray(limits, dtype=float))
    A, b = np.concatenate(rows), np.concatenate(bounds)
    # the bounds are symmetric: keep one of the rows equal up to sign (mirrored legs), and none
    # that no force can load
    key = np.round(np.column_stack([np.abs(A) / b[:, None], np.sign(A[:, 0] * A[:, 1])]), 12)
    keep = np.sort(np.unique(key, axis=0, return_index=True)[1])
    keep = keep[np.abs(A[keep]).sum(axis=1) > 0]
    return A[keep], b[keep]


def holds_pitch(legs: tuple[int, ...]) -> bool:
    """Whether feet ``legs`` (indices into ``names.LEGS``) can give the trunk a pitching moment
    of their own: a front and a rear foot down. Feet side by side (a froggy's rear pair)
    cannot: the moment their summed force makes is set by that force."""
    ends = {LEGS[k][0] for k in legs}  # "f" or "r"
    return ends == {"f", "r"}


def pitch_moment_map(robot: str, qs: list[np.ndarray], legs: tuple[int, ...]) -> np.ndarray:
    """A (len(qs), 2): the pitching moment (N m; the input's ``my``, about the base, as the data
    derive it) that a summed force F = (F_x, F_z) N shared equally by the feet ``legs`` makes,
    A F, at each configuration of ``qs`` (each (18,))."""
    my = U_NAMES.index("my")
    return np.array([[stance_input(robot, q, e, legs)[my] for e in (np.array([1.0, 0.0, 0.0]),
                                                                      np.array([0.0, 0.0, 1.0]))] for q in qs])
