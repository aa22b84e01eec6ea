"""Compiled (numba) leg kinematics of one configuration, for controllers running every tick.

``LegKinematics`` evaluates many samples at once in NumPy, which suits data
processing; a controller asks for one configuration a thousand times per
simulated second, where NumPy's per-call overhead dominates. ``legs_one``
walks the same chains (fixed origin transforms, revolute joints by Rodrigues'
formula) as one compiled loop. Compiled on first use and cached on disk; this
module imports numba, so it is imported only where it runs.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def legs_one(qj, n_el, xyz, rot, axis, col, pos, J):
    """Feet pos (4, 3) m and Jacobians J (4, 3, 3) m/rad in the base frame for joint
    angles qj (12,) rad. Per leg k and chain element e: xyz[k, e] (3,), rot[k, e]
    (3, 3) origin transform, axis[k, e] (3,) unit axis, col[k, e] the joint's column
    in qj (-1: fixed); n_el[k] elements."""
    R = np.empty((3, 3))
    T = np.empty((3, 3))
    p = np.empty(3)
    ax = np.empty((3, 3))  # joint axes (world of the base), by joint of the leg
    org = np.empty((3, 3))  # joint origins
    for k in range(n_el.shape[0]):
        for a in range(3):
            p[a] = 0.0
            for b in range(3):
                R[a, b] = 1.0 if a == b else 0.0
        for e in range(n_el[k]):
            for a in range(3):
                p[a] += R[a, 0] * xyz[k, e, 0] + R[a, 1] * xyz[k, e, 1] + R[a, 2] * xyz[k, e, 2]
            for a in range(3):
                for b in range(3):
                    T[a, b] = R[a, 0] * rot[k, e, 0, b] + R[a, 1] * rot[k, e, 1, b] + R[a, 2] * rot[k, e, 2, b]
            for a in range(3):  # R = T (loops: numba's array copy compiles seconds of error checks)
                for b in range(3):
                    R[a, b] = T[a, b]
            c = col[k, e]
            if c < 0:
                continue
            j = c - 3 * k
            u0, u1, u2 = axis[k, e, 0], axis[k, e, 1], axis[k, e, 2]
            for a in range(3):
                ax[j, a] = R[a, 0] * u0 + R[a, 1] * u1 + R[a, 2] * u2
                org[j, a] = p[a]
            s, cq = np.sin(qj[c]), np.cos(qj[c])
            v = 1.0 - cq
            # Rodrigues: I + s K + (1 - c) K K, K the cross-product matrix of the axis
            G00, G01, G02 = cq + v * u0 * u0, v * u0 * u1 - s * u2, v * u0 * u2 + s * u1
            G10, G11, G12 = v * u1 * u0 + s * u2, cq + v * u1 * u1, v * u1 * u2 - s * u0
            G20, G21, G22 = v * u2 * u0 - s * u1, v * u2 * u1 + s * u0, cq + v * u2 * u2
            for a in range(3):
                r0, r1, r2 = R[a, 0], R[a, 1], R[a, 2]
                T[a, 0] = r0 * G00 + r1 * G10 + r2 * G20
                T[a, 1] = r0 * G01 + r1 * G11 + r2 * G21
                T[a, 2] = r0 * G02 + r1 * G12 + r2 * G22
            for a in range(3):
                for b in range(3):
                    R[a, b] = T[a, b]
        for a in range(3):
            pos[k, a] = p[a]
        for j in range(3):
            d0, d1, d2 = p[0] - org[j, 0], p[1] - org[j, 1], p[2] - org[j, 2]
            J[k, 0, j] = ax[j, 1] * d2 - ax[j, 2] * d1
            J[k, 1, j] = ax[j, 2] * d0 - ax[j, 0] * d2
            J[k, 2, j] = ax[j, 0] * d1 - ax[j, 1] * d0
