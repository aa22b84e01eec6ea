"""The motions' feed-forward for the actuator effects a robot's description states.

A description may state joint damping, armature and friction loss (``[actuators]``,
``robots.description.ActuatorEffects``): between a motor and its joint they take
``losses = damping x dq + friction_loss x s(dq) + armature x ddq`` N m. The motions were
tuned on ideal motors, what the built-in robots state; on a robot that states losses they
command the torque they mean the joints to get plus the losses at the measured joint speeds
(and, where a motion plans its joints' accelerations, the armature's share of them), within
the motors' limits. Only the description's effects are made up for: the proxy's perturbed
damping, armature and friction loss are hardware the controller does not know.

A robot whose description states none (``Compensation.active`` false) gets the motions'
torques untouched, bit for bit.
"""

from __future__ import annotations

import numpy as np

from symrom.names import N_LEGS
from symrom.robots import get_robot


class Compensation:
    """The stated actuator effects of ``robot`` and how a motion's torques make up for them.

    active: whether the description states any effect; effects: its ``ActuatorEffects``.
    Arrays are (12,) in symrom's joint order and signs, N m, rad/s, rad/s^2.
    """

    def __init__(self, robot: str):
        self.effects = get_robot(robot).actuators
        self.active = not self.effects.ideal

    def losses(self, dq: np.ndarray, ddq: np.ndarray | None = None) -> np.ndarray:
        """(12,) N m the effects take at joint speeds dq (12,) and accelerations ddq (12,) or None."""
        return self.effects.losses(dq, ddq)

    def clipped(self, tau: np.ndarray, dq: np.ndarray, limit: np.ndarray,
                ddq: np.ndarray | None = None) -> np.ndarray:
        """Motor torques (12,) N m: ``tau`` (12,), what the joints should get, plus the losses,
        each joint clipped to +-limit (12,) on its own (as the pronk clips)."""
        return np.clip(tau + self.losses(dq, ddq), -limit, limit)

    def scaled_legs(self, tau: np.ndarray, dq: np.ndarray, limit: np.ndarray,
                    ddq: np.ndarray | None = None) -> np.ndarray:
        """Motor torques (12,) N m: the losses (each within +-limit) plus ``tau`` (12,), what the
        joints should get, scaled per leg by the largest factor in [0, 1] that keeps every
        joint of the leg within +-limit (12,) (as froggy scales): a leg's joint torques keep
        their ratios, so its foot force keeps its direction, whatever the losses take."""
        loss = np.clip(self.losses(dq, ddq), -limit, limit)
        tau = np.asarray(tau, dtype=float)
        room = np.where(tau > 0, limit - loss, -limit - loss)  # what each joint has left, signed as tau
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(tau != 0, room / tau, np.inf)
        s = np.minimum(np.min(ratio.reshape(N_LEGS, 3), axis=1), 1.0)
        return loss + tau * np.repeat(np.maximum(s, 0.0), 3)


def stance_acceleration(kin, qj: np.ndarray, v_feet: np.ndarray, legs,
                        a_feet: np.ndarray | None = None) -> np.ndarray:
    """Joint accelerations (12,) rad/s^2 of ``legs`` whose feet move at v_feet (4, 3) m/s and
    accelerate at a_feet (4, 3) m/s^2 (None: 0) relative to the base (base frame), from joint
    angles qj (12,) rad; zero for the other legs. Per leg dq = J^-1 v and J ddq + (d/dt J) dq
    = a, where (d/dt J) dq is the second derivative of the foot's position along dq (a central
    difference of ``kin``'s foot positions, a ``LegKinematics``): at a constant foot speed the
    joints still speed up as the leg straightens. With the feet's motion a motion plans, what
    it plans its joints' accelerations to be: the armature's share of the torque."""
    p_zero, J = kin.one(qj)
    dq = np.zeros(12)
    for k in legs:
        dq[3 * k:3 * k + 3] = np.linalg.solve(J[k], v_feet[k])
    h = 1e-3 / max(float(np.max(np.abs(dq))), 1e-3)  # s: a step of at most 1 mrad a joint
    p_plus, p_minus = kin.one(qj + h * dq)[0], kin.one(qj - h * dq)[0]
    ddq = np.zeros(12)
    for k in legs:
        curve = (p_plus[k] - 2.0 * p_zero[k] + p_minus[k]) / (h * h)  # (d/dt J) dq, m/s^2
        a = np.zeros(3) if a_feet is None else a_feet[k]
        ddq[3 * k:3 * k + 3] = np.linalg.solve(J[k], a - curve)
    return ddq
