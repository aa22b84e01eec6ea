"""Column and joint names: the one place these orders are defined.

Legs are ordered FR, FL, RR, RL; each leg has hip abduction ``hx``, hip flexion
``hy`` and knee ``kn``. The configuration ``q`` (18) is the 12 joint angles then
the base ``x, y, z`` (world, m) and ``roll, pitch, yaw`` (rad, ZYX Euler).
The input ``u`` (18) is the 12 joint torques (N m) then the CoM wrench: summed
ground-reaction force (N, world) and its moment about the CoM (N m, world).
"""

from __future__ import annotations

LEGS: tuple[str, ...] = ("fr", "fl", "rr", "rl")
LEG_JOINTS: tuple[str, ...] = ("hx", "hy", "kn")
JOINT_NAMES: tuple[str, ...] = tuple(f"{leg}_{j}" for leg in LEGS for j in LEG_JOINTS)
BASE_NAMES: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw")
Q_NAMES: tuple[str, ...] = JOINT_NAMES + BASE_NAMES
WRENCH_NAMES: tuple[str, ...] = ("fx", "fy", "fz", "mx", "my", "mz")
U_NAMES: tuple[str, ...] = tuple(f"tau_{n}" for n in JOINT_NAMES) + WRENCH_NAMES

# Gravitational acceleration, m/s^2 (downwards): the simulators' g, and the one every model,
# controller, planner, check and baseline uses.
GRAVITY = 9.81

# Phase names the motions share (``symrom.motions`` gives each motion's phases, in order).
STANCE_PHASE = "contact"  # every foot down
PARTIAL_PHASE = "partial"  # some feet down, before the first flight (froggy)
FLIGHT_PHASE = "flight"  # no foot down

N_JOINTS = len(JOINT_NAMES)  # 12
N_Q = len(Q_NAMES)  # 18
N_LEGS = len(LEGS)  # 4

# Slices into q / u.
JOINTS = slice(0, N_JOINTS)
BASE_POS = slice(N_JOINTS, N_JOINTS + 3)
BASE_RPY = slice(N_JOINTS + 3, N_Q)
WRENCH = slice(N_JOINTS, N_Q)

# Units per configuration component, for tables and plot labels.
Q_UNITS: dict[str, str] = {n: "rad" for n in JOINT_NAMES} | {
    "x": "m", "y": "m", "z": "m", "roll": "rad", "pitch": "rad", "yaw": "rad"}

# Components the paper's Table 2 reports: fl and rr joints, then the base pose.
TABLE2_COMPONENTS: tuple[str, ...] = (
    "fl_hx", "fl_hy", "fl_kn", "rr_hx", "rr_hy", "rr_kn",
    "x", "y", "z", "roll", "pitch", "yaw")

DEFAULT_DT = 0.002  # s, 500 Hz
SPLITS: tuple[str, ...] = ("train", "val", "test")


def leg_slice(leg: int) -> slice:
    """Slice of leg ``leg`` (0..3, FR FL RR RL) in the 12 joint columns."""
    return slice(3 * leg, 3 * leg + 3)
