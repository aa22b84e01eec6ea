"""Compiled (numba) reads of the engines' state: the base pose and rates from an inertial
frame's (PyBullet's and MuJoCo's), MuJoCo's whole state and its feet's ground forces in one
call each; and what a hardware-like world (``symrom.sim.proxy``) adds on any engine every tick:
its sensors' readings and its motors' torque.

A physics tick at 1 kHz leaves a few hundred microseconds for everything Python does
around it; NumPy's per-call overhead on 3-vectors would take most of that. These routines
do the same arithmetic as one compiled call each. Compiled on first use and cached on disk
(``warm_up`` compiles or loads them ahead); import this module only where it runs (it
imports numba).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from symrom.robots.kinematics import zyx_rows

njit = numba.njit(cache=True)
_zyx = njit(zyx_rows)  # the one formula of the rotation from ZYX Euler angles, compiled

@njit
def quat_matrix(x, y, z, w, R):
    """R (3, 3) of the unit quaternion (x, y, z, w) (PyBullet's order)."""
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - z * w)
    R[0, 2] = 2.0 * (x * z + y * w)
    R[1, 0] = 2.0 * (x * y + z * w)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - x * w)
    R[2, 0] = 2.0 * (x * z - y * w)
    R[2, 1] = 2.0 * (y * z + x * w)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit
def base_state(com_pos, com_orn, v_com, omega, off_pos, off_orn, q, dq, R):
    """The base link's pose and rates from its inertial frame's.

    com_pos (3,) m, com_orn (4,) quaternion (x, y, z, w), v_com (3,) m/s, omega (3,)
    rad/s (world) of the inertial frame, arrays or tuples (as PyBullet gives them);
    off_pos (3,), off_orn (4,): the inertial -> link frame transform. Writes q[12:18] =
    x, y, z, roll, pitch, yaw (ZYX), dq[12:18] = base velocity (m/s) and Euler-angle rates
    (rad/s), R (3, 3) base -> world.
    """
    x1, y1, z1, w1 = com_orn[0], com_orn[1], com_orn[2], com_orn[3]
    x2, y2, z2, w2 = off_orn[0], off_orn[1], off_orn[2], off_orn[3]
    # orientation of the link frame: com_orn * off_orn
    x = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    y = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    z = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    w = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    Rc = np.empty((3, 3))
    quat_matrix(x1, y1, z1, w1, Rc)
    lever = np.empty(3)
    for a in range(3):
        lever[a] = Rc[a, 0] * off_pos[0] + Rc[a, 1] * off_pos[1] + Rc[a, 2] * off_pos[2]
        q[12 + a] = com_pos[a] + lever[a]
    quat_matrix(x, y, z, w, R)
    s = min(max(R[2, 0], -1.0), 1.0)
    roll, pitch, yaw = np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(s), np.arctan2(R[1, 0], R[0, 0])
    q[15], q[16], q[17] = roll, pitch, yaw
    # v_base = v_com + omega x (base - com)
    dq[12] = v_com[0] + omega[1] * lever[2] - omega[2] * lever[1]
    dq[13] = v_com[1] + omega[2] * lever[0] - omega[0] * lever[2]
    dq[14] = v_com[2] + omega[0] * lever[1] - omega[1] * lever[0]
    # omega = E d(rpy)/dt, E = [[cy cp, -sy, 0], [sy cp, cy, 0], [-sp, 0, 1]]: solved in closed form
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    droll = (cy * omega[0] + sy * omega[1]) / cp
    dpitch = -sy * omega[0] + cy * omega[1]
    dq[15], dq[16], dq[17] = droll, dpitch, omega[2] + sp * droll


@njit
def mujoco_state(qpos, qvel, xmat, xpos, cvel, subtree_com, body_root, base, feet, qadr, vadr, signs,
                 con_geom, leg_of_geom, ground, quat, q, dq, R, omega, foot_pos, foot_vel, contact):
    """The robot's state from MuJoCo's arrays, in one call (``MujocoWorld.state``).

    qpos, qvel, xmat (nbody, 9), xpos (nbody, 3), cvel (nbody, 6), subtree_com (nbody, 3)
    and body_root (nbody,): MuJoCo's, after a forward pass; base: the base body (its free
    joint at qpos[0:7], qvel[0:6], angular velocity in the body frame); feet (4,) bodies;
    qadr, vadr (12,): the joints' addresses; signs (12,); con_geom (ncon, 2) the contacts'
    geoms, leg_of_geom (ngeom,) the leg of a foot geom or -1, ground the ground geom; quat
    (4,) scratch. Writes q, dq (18,), R (3, 3), omega (3,) rad/s world, foot_pos and
    foot_vel (4, 3) (m, m/s, the foot bodies' frames, world) and contact (4,) (1 where a
    foot geom touches the ground geom). foot_vel is ``mj_objectVelocity``'s linear part:
    the body's com-based velocity moved from its root's subtree centre of mass to xpos."""
    w = qvel[3:6]
    for a in range(3):  # qvel holds the angular velocity in the body frame
        omega[a] = xmat[base, 3 * a] * w[0] + xmat[base, 3 * a + 1] * w[1] + xmat[base, 3 * a + 2] * w[2]
    quat[0], quat[1], quat[2], quat[3] = qpos[4], qpos[5], qpos[6], qpos[3]  # (w, x, y, z) as (x, y, z, w)
    zero, unit = np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])  # the free joint sits at the link frame
    base_state(qpos[0:3], quat, qvel[0:3], omega, zero, unit, q, dq, R)
    for j in range(12):
        q[j] = qpos[qadr[j]] * signs[j]
        dq[j] = qvel[vadr[j]] * signs[j]
    for k in range(4):
        b = feet[k]
        c = subtree_com[body_root[b]]
        r0, r1, r2 = xpos[b, 0] - c[0], xpos[b, 1] - c[1], xpos[b, 2] - c[2]
        w0, w1, w2 = cvel[b, 0], cvel[b, 1], cvel[b, 2]
        foot_vel[k, 0] = cvel[b, 3] + (w1 * r2 - w2 * r1)
        foot_vel[k, 1] = cvel[b, 4] + (w2 * r0 - w0 * r2)
        foot_vel[k, 2] = cvel[b, 5] + (w0 * r1 - w1 * r0)
        foot_pos[k, 0], foot_pos[k, 1], foot_pos[k, 2] = xpos[b, 0], xpos[b, 1], xpos[b, 2]
        contact[k] = 0
    for i in range(con_geom.shape[0]):
        g1, g2 = con_geom[i, 0], con_geom[i, 1]
        if g1 == ground and leg_of_geom[g2] >= 0:
            contact[leg_of_geom[g2]] = 1
        elif g2 == ground and leg_of_geom[g1] >= 0:
            contact[leg_of_geom[g1]] = 1


@njit
def mujoco_torques(tau, neg_limit, limit, signs, clipped, ctrl):
    """A MuJoCo tick's torques: tau (12,) N m saturated at +-limit into clipped (as NumPy's
    ``minimum(maximum(tau, neg_limit), limit)``), and, if all of them are finite, clipped x signs
    written to ctrl (MuJoCo's, URDF signs). Returns whether they were finite; ctrl is left as it
    was if not."""
    finite = True
    for j in range(tau.shape[0]):
        t = tau[j]
        if t < neg_limit[j]:  # comparisons: a NaN stays NaN, as in NumPy's
            t = neg_limit[j]
        if t > limit[j]:
            t = limit[j]
        clipped[j] = t
        if not math.isfinite(t):
            finite = False
    if finite:
        for j in range(tau.shape[0]):
            ctrl[j] = clipped[j] * signs[j]
    return finite


@njit
def mujoco_foot_forces(con_geom, con_frame, con_friction, con_dim, con_efc, efc_force, leg_of_geom, ground, f):
    """The ground's force f (4, 3) N on each foot, world, from MuJoCo's contacts (pyramidal
    friction cones): per foot/ground contact with constraint rows (efc address >= 0), the
    force ``mj_contactForce`` decodes (normal: the sum of the pyramid's edge forces; tangent
    i: (edge 2i - edge 2i+1) mu_i) turned from the contact frame (con_frame rows: normal,
    tangents) into the world, signed for the foot (MuJoCo's acts from geom1 on geom2).
    con_*: the contacts' geom (n, 2), frame (n, 9), friction (n, 5), dim (n,), efc_address
    (n,); efc_force: MuJoCo's; leg_of_geom, ground as in ``mujoco_state``."""
    f[:, :] = 0.0
    for i in range(con_geom.shape[0]):
        g1, g2 = con_geom[i, 0], con_geom[i, 1]
        if g1 == ground and leg_of_geom[g2] >= 0:
            k, sign = leg_of_geom[g2], 1.0
        elif g2 == ground and leg_of_geom[g1] >= 0:
            k, sign = leg_of_geom[g1], -1.0
        else:
            continue
        a = con_efc[i]
        if a < 0:  # within the margin, not touching: no force
            continue
        dim = con_dim[i]
        local = np.zeros(3)
        if dim == 1:
            local[0] = efc_force[a]
        else:
            for e in range(2 * (dim - 1)):
                local[0] += efc_force[a + e]
            for t in range(min(dim - 1, 2)):
                local[t + 1] = (efc_force[a + 2 * t] - efc_force[a + 2 * t + 1]) * con_friction[i, t]
        for r in range(3):
            f[k, r] += sign * (con_frame[i, r] * local[0] + con_frame[i, 3 + r] * local[1]
                               + con_frame[i, 6 + r] * local[2])


@njit
def proxy_readings(q, dq, omega, foot_pos, foot_vel, e, drift_x, drift_y, drift_yaw, drift_dq, q_out, dq_out,
                   omega_out, R, foot_pos_out, foot_vel_out):
    """A proxy's readings of a state, in one call (``symrom.sim.proxy.SensorModel.corrupt``).

    q, dq (18,), omega (3,), foot_pos, foot_vel (4, 3): the state's; e (63,): the tick's noise
    in ``proxy.NOISE_DRAWS``' order (joints' angles 12 and rates 12, base position 3, Euler
    angles 3, base velocity 3, Euler rates 3, omega 3, feet's positions 12 and velocities 12);
    drift_x, drift_y m and drift_yaw rad: the estimator's drift by now; drift_dq (3,) m/s its
    rate. Writes q_out, dq_out, omega_out, R (3, 3) of the noisy Euler angles, foot_pos_out and
    foot_vel_out, each sum in the order NumPy's expressions of the reference take it."""
    for j in range(12):
        q_out[j] = q[j] + e[j]
        dq_out[j] = dq[j] + e[12 + j]
    drift = (drift_x, drift_y, 0.0)
    angle = (0.0, 0.0, drift_yaw)
    for a in range(3):
        q_out[12 + a] = q[12 + a] + (drift[a] + e[24 + a])
        q_out[15 + a] = q[15 + a] + (e[27 + a] + angle[a])
        dq_out[12 + a] = dq[12 + a] + (e[30 + a] + drift_dq[a])
        dq_out[15 + a] = dq[15 + a] + e[33 + a]
        omega_out[a] = omega[a] + e[36 + a]
        for k in range(4):
            foot_pos_out[k, a] = foot_pos[k, a] + drift[a] + e[39 + 3 * k + a]
            foot_vel_out[k, a] = foot_vel[k, a] + e[51 + 3 * k + a]
    roll, pitch, yaw = q_out[15], q_out[16], q_out[17]
    rows = _zyx(math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch), math.cos(yaw), math.sin(yaw))
    for i in range(3):
        for j in range(3):
            R[i, j] = rows[i][j]


@njit
def proxy_motors(tau, joint_vel, w0, span, limit, out):
    """The torque (12,) N m a proxy's motors deliver for ``tau`` (12,) at joint speeds
    ``joint_vel`` (12,) rad/s, into out (``symrom.sim.proxy.TorqueChannel``): while a motor
    drives (torque and speed of one sign), its limit falls from ``limit`` at w0 - span to zero
    at the no-load speed w0 (12,); braking keeps the whole limit. NumPy's numbers, written out:
    ``minimum(maximum(x, 0), 1)``, ``sign(a) == sign(b)`` and ``clip`` as its loops take them
    (NaN passed on)."""
    for j in range(tau.shape[0]):
        x = (w0[j] - abs(joint_vel[j])) / span[j]
        x = x if (x >= 0.0 or x != x) else 0.0
        frac = x if (x <= 1.0 or x != x) else 1.0
        lim = limit[j] * frac if _sign(tau[j]) == _sign(joint_vel[j]) else limit[j]
        t = tau[j]
        if t == t:
            t = t if t > -lim else -lim
        if t == t:
            t = t if t < lim else lim
        out[j] = t


@njit
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else (0.0 if x == 0.0 else x))


# The arguments of the MuJoCo reads that are MuJoCo's contact fields: strided views of its
# contact structs, contiguous when there is one contact or none.
STATE_CONTACTS = (12,)
FORCE_CONTACTS = (0, 1, 2, 3, 4)


def settle(dispatcher, args: tuple, loose: tuple[int, ...]) -> None:
    """Give ``dispatcher`` a build for ``args`` (compiled, or loaded from the disk cache, now),
    the arrays at the positions ``loose`` typed as of any layout, and let it compile nothing on
    its own from then on: a call converts its arrays to a settled build's types. MuJoCo's
    contact fields come contiguous or strided by the number of contacts, and numba would
    otherwise compile a build for each (a second or so each on a cold cache, and a load each
    on a warm one). A call of types no settled build takes raises numba's TypeError."""
    from numba import typeof

    sig = tuple(typeof(a).copy(layout="A") if i in loose else typeof(a) for i, a in enumerate(args))
    if sig not in dispatcher.overloads:
        dispatcher.disable_compile(False)
        dispatcher.compile(sig)
    dispatcher.disable_compile(True)


# The reads each engine calls every tick, and what a hardware-like world adds on any engine
# (``warm_up``).
ENGINE_ROUTINES = {"pybullet": ("base_state",), "mujoco": ("mujoco_state", "mujoco_foot_forces", "mujoco_torques"),
                   "proxy": ("proxy_readings", "proxy_motors")}


def routines(engine: str) -> list:
    """The compiled reads (numba dispatchers) a world of ``engine`` calls."""
    return [globals()[name] for name in ENGINE_ROUTINES.get(engine, ())]


def warm_up(engines: tuple[str, ...] = ("pybullet", "mujoco")) -> None:
    """Compile (or load from the disk cache) the reads ``engines`` use now, as their first tick
    would, for the argument types each engine hands them."""
    q, dq, R = np.zeros(18), np.zeros(18), np.empty((3, 3))
    unit = np.array([0.0, 0.0, 0.0, 1.0])
    if "pybullet" in engines:
        zero = (0.0, 0.0, 0.0)  # as BulletWorld.state passes PyBullet's tuples
        base_state(zero, (0.0, 0.0, 0.0, 1.0), zero, zero, np.zeros(3), unit, q, dq, R)
    if "mujoco" in engines:
        settle_mujoco(*mujoco_arguments())
        v12 = np.ones(12)
        mujoco_torques(v12, -v12, v12, v12, np.empty(12), np.empty(12))
    if "proxy" in engines:
        v3, v4, v12 = np.zeros(3), np.zeros((4, 3)), np.zeros(12)
        proxy_readings(q, dq, v3, v4, v4, np.zeros(63), 0.0, 0.0, 0.0, v3, np.empty(18), np.empty(18), np.empty(3),
                       np.empty((3, 3)), np.empty((4, 3)), np.empty((4, 3)))
        proxy_motors(v12, v12, np.ones(12), np.ones(12), np.ones(12), np.empty(12))


def mujoco_arguments(nbody: int = 6, ngeom: int = 8, ncon: int = 2) -> tuple[tuple, tuple]:
    """Arguments of ``mujoco_state`` and ``mujoco_foot_forces`` of the types a MuJoCo world
    passes (MuJoCo's int32 and float64 fields, the world's int64 and uint8 arrays), the contact
    fields strided views as MuJoCo hands them: for warming them up without a model."""
    i32, i64 = np.int32, np.int64
    legs = np.full(ngeom, -1, dtype=i64)
    legs[2:6] = np.arange(4)
    qpos = np.zeros(19)
    qpos[3] = 1.0  # a unit quaternion
    rows = np.zeros((ncon, 12), dtype=i32)
    geom, dim, efc = rows[:, :2], rows[:, 2], rows[:, 3]
    frame, friction = np.zeros((ncon, 20))[:, :9], np.zeros((ncon, 8))[:, :5]
    state = (qpos, np.zeros(18), np.tile(np.eye(3).ravel(), (nbody, 1)), np.zeros((nbody, 3)),
             np.zeros((nbody, 6)), np.zeros((nbody, 3)), np.zeros(nbody, dtype=i64), 1, np.arange(2, 6, dtype=i64),
             np.arange(7, 19, dtype=i32), np.arange(6, 18, dtype=i32), np.ones(12), geom, legs, 0,
             np.empty(4), np.empty(18), np.empty(18), np.empty((3, 3)), np.empty(3), np.empty((4, 3)),
             np.empty((4, 3)), np.empty(4, dtype=np.uint8))
    forces = (geom, frame, friction, dim, efc, np.zeros(4 * ncon), legs, 0, np.zeros((4, 3)))
    return state, forces


def settle_mujoco(state: tuple, forces: tuple) -> None:
    """``settle`` the two MuJoCo reads for these arguments (``mujoco_arguments``' order)."""
    settle(mujoco_state, state, STATE_CONTACTS)
    settle(mujoco_foot_forces, forces, FORCE_CONTACTS)
