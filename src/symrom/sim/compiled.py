"""Compiled (numba) pieces of the per-tick work of a simulation: reading the base state.

A physics tick at 1 kHz leaves a few hundred microseconds for everything
Python does around it; NumPy's per-call overhead on 3-vectors would take most
of that. These routines do the same arithmetic as one compiled call each.
Compiled on first use and cached on disk; import this module only where it runs
(it imports numba).
"""

from __future__ import annotations

import numba
import numpy as np

njit = numba.njit(cache=True)

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
    rad/s (world) of the inertial frame; off_pos (3,), off_orn (4,): the inertial ->
    link frame transform. Writes q[12:18] = x, y, z, roll, pitch, yaw (ZYX),
    dq[12:18] = base velocity (m/s) and Euler-angle rates (rad/s), R (3, 3) base -> world.
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
def distribute(foot_pos, centre, legs, force, moment, mu, grf):
    """``symrom.sim.froggy.distribute`` compiled: ground reactions grf (4, 3) N of the feet
    ``legs`` (int array) giving the body wrench (force, moment), least norm, pulls
    dropped, horizontal parts clipped to the friction cone mu."""
    m = legs.shape[0]
    A = np.zeros((6, 3 * m))
    for i in range(m):
        k = legs[i]
        r0, r1, r2 = foot_pos[k, 0] - centre[0], foot_pos[k, 1] - centre[1], foot_pos[k, 2] - centre[2]
        for a in range(3):
            A[a, 3 * i + a] = 1.0
        A[3, 3 * i + 1], A[3, 3 * i + 2] = -r2, r1
        A[4, 3 * i + 0], A[4, 3 * i + 2] = r2, -r0
        A[5, 3 * i + 0], A[5, 3 * i + 1] = -r1, r0
    b = np.empty(6)
    b[:3], b[3:] = force, moment
    sol = np.linalg.pinv(A) @ b
    grf[:, :] = 0.0
    for i in range(m):
        fx, fy, fz = sol[3 * i], sol[3 * i + 1], max(sol[3 * i + 2], 0.0)
        scale = min(1.0, mu * fz / max(np.sqrt(fx * fx + fy * fy), 1e-9))
        k = legs[i]
        grf[k, 0], grf[k, 1], grf[k, 2] = fx * scale, fy * scale, fz
