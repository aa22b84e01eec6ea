"""Compiled (numba) arithmetic of the controllers' ticks: the froggy force distribution and
torques, the pronk's stance torques, the MPC's force clipping and its condensed QP.

A physics tick at 1 kHz leaves a few hundred microseconds for everything Python does
around it; NumPy's per-call overhead on 3-vectors would take most of that. These routines
do the same arithmetic as one compiled call each (their NumPy references are tested
against them). Compiled on first use and cached on disk (``warm_up`` compiles or loads
them ahead); import this module only where it runs (it imports numba).
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types

from symrom.names import GRAVITY
from symrom.robots.compiled import legs_one

njit = numba.njit(cache=True)

# numba's own entry points into SciPy's BLAS and LAPACK, the ones its ``@`` and
# ``np.linalg.pinv`` call. ``matvec``, ``matmul`` and ``pinv_apply`` call them with the
# arguments those do, so the results are the same to the bit (the generated datasets depend on
# it), and they compile in a fraction of the time of numba's generic implementations (which
# check, dispatch and copy for any layout and type): seconds of a cold start.
_F8 = types.CPointer(types.float64)
# (kind, transa, transb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc)
_gemm = types.ExternalFunction("numba_xxgemm", types.intc(
    types.char, types.char, types.char, types.intp, types.intp, types.intp, _F8, _F8, types.intp, _F8, types.intp,
    _F8, _F8, types.intp))
# (kind, trans, m, n, alpha, a, lda, x, beta, y)
_gemv = types.ExternalFunction("numba_xxgemv", types.intc(
    types.char, types.char, types.intp, types.intp, _F8, _F8, types.intp, _F8, _F8, _F8))
# (kind, jobz, m, n, a, lda, s, u, ldu, vt, ldvt)
_gesdd = types.ExternalFunction("numba_ez_gesdd", types.intc(
    types.char, types.char, types.intp, types.intp, _F8, types.intp, _F8, _F8, types.intp, _F8, types.intp))
_DOUBLE, _ECONOMY, _CONJ, _NOTRANS, _TRANS = ord("d"), ord("S"), ord("C"), ord("n"), ord("t")


@njit
def matvec(A, x):
    """A @ x as numba computes it: A (m, n), x (n,) float64 -> (m,)."""
    m, n = A.shape
    A = np.ascontiguousarray(A)
    x = np.ascontiguousarray(x)
    out = np.empty(m)
    one, zero = np.ones(1), np.zeros(1)
    # BLAS is column-major: a row-major A is its transpose there
    _gemv(_DOUBLE, _TRANS, n, m, one.ctypes, A.ctypes, n, x.ctypes, zero.ctypes, out.ctypes)
    return out


@njit
def matmul(A, B, transpose_a):
    """A @ B as numba computes it, or with ``transpose_a`` A.T @ B as numba computes
    ``A.T @ B``: A, B float64 matrices -> C-ordered (rows of A or A.T, columns of B)."""
    A = np.ascontiguousarray(A)
    B = np.ascontiguousarray(B)
    if transpose_a:
        k, m = A.shape
    else:
        m, k = A.shape
    n = B.shape[1]
    out = np.empty((m, n))
    one, zero = np.ones(1), np.zeros(1)
    # out^T = B^T A^T in BLAS's column-major view of the row-major arrays
    _gemm(_DOUBLE, _NOTRANS, _TRANS if transpose_a else _NOTRANS, n, m, k, one.ctypes, B.ctypes, n, A.ctypes,
          m if transpose_a else k, zero.ctypes, out.ctypes, n)
    return out


@njit
def pinv_apply(A, b):
    """np.linalg.pinv(A) @ b as numba computes it (rcond 1e-15): A (m, n), b (m,) float64 ->
    (n,). Raises ``np.linalg.LinAlgError`` for a non-finite A or an SVD that does not converge."""
    m, n = A.shape
    a = np.empty((n, m)).T  # column-major (m, n): LAPACK overwrites it, then holds the result
    for i in range(m):
        for j in range(n):
            v = A[i, j]
            if not np.isfinite(v):
                raise np.linalg.LinAlgError("Array must not contain infs or NaNs.")
            a[i, j] = v
    r = min(m, n)
    u, s, vt = np.empty((r, m)), np.empty(r), np.empty((n, r))
    if _gesdd(_DOUBLE, _ECONOMY, m, n, a.ctypes, m, s.ctypes, u.ctypes, m, vt.ctypes, r) != 0:
        raise np.linalg.LinAlgError("SVD did not converge.")
    # invert the singular values above the cut, scale the smaller factor by them, and multiply
    # over the kept ones only
    cut_at, cut = s[0] * 1e-15, 0
    for k in range(r):
        if s[k] > cut_at:
            s[k] = 1.0 / s[k]
            cut = k
    cut += 1
    if m >= n:
        for i in range(n):
            for j in range(cut):
                vt[i, j] = vt[i, j] * s[j]
    else:
        for i in range(cut):
            si = s[i]
            for j in range(r):
                u[i, j] = u[i, j] * si
    one, zero = np.ones(1), np.zeros(1)
    _gemm(_DOUBLE, _CONJ, _CONJ, n, m, cut, one.ctypes, vt.ctypes, r, u.ctypes, m, zero.ctypes, a.ctypes, n)
    out = np.empty(n)  # a: the pseudo-inverse (n, m), column-major
    _gemv(_DOUBLE, _NOTRANS, n, m, one.ctypes, a.ctypes, n, b.ctypes, zero.ctypes, out.ctypes)
    return out


@njit
def distribute(foot_pos, centre, legs, force, moment, mu, grf):
    """Ground reactions grf (4, 3) N (``symrom.sim.controllers.froggy.distribute``) of the feet
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
    for a in range(3):
        b[a], b[3 + a] = force[a], moment[a]
    sol = pinv_apply(A, b)
    grf[:, :] = 0.0
    for i in range(m):
        fx, fy, fz = sol[3 * i], sol[3 * i + 1], max(sol[3 * i + 2], 0.0)
        scale = min(1.0, mu * fz / max(np.sqrt(fx * fx + fy * fy), 1e-9))
        k = legs[i]
        grf[k, 0], grf[k, 1], grf[k, 2] = fx * scale, fy * scale, fz


@njit
def clip(x, lo, hi):
    """NumPy's ``np.clip`` of one number, to the bit: NaN stays NaN, ties keep x, else the bound."""
    t = x if x != x or x > lo else lo
    return t if t != t or t < hi else hi


@njit
def clip_forces(U, c, fz_min, fz_max, mu):
    """Forces U (h, 4, 3) N clipped in place into the MPC's exact bounds, in the order and
    arithmetic of the NumPy code (``np.clip``): f_z into [fz_min c, fz_max c] (c (h, 4) the
    planned contact flags), then f_x and f_y into [-mu f_z, mu f_z]."""
    for k in range(U.shape[0]):
        for j in range(U.shape[1]):
            fz = clip(U[k, j, 2], fz_min * c[k, j], fz_max * c[k, j])
            U[k, j, 2] = fz
            lim = mu * fz
            U[k, j, 0] = clip(U[k, j, 0], -lim, lim)
            U[k, j, 1] = clip(U[k, j, 1], -lim, lim)


@njit
def pronk_stance_torque(J, f_base, tau_g, land, p_b, p_land, contact, h_ref, k_land, d_land,
                        posture, qj, dqj, limit, tau):
    """Joint torques tau (12,) N m of the pronk controller on the ground
    (``PronkController.torque``): J_k^T f_k for the feet's forces f_base (4, 3) N (base
    frame) through the leg Jacobians J (4, 3, 3), plus the legs' weight tau_g (12,), plus
    with ``land`` the landing impedance (spring k_land N/m towards p_land (4, 3) m for legs
    in the air, p_b (4, 3) m the feet now, z towards -h_ref m; damping d_land N s/m of the
    feet's velocities relative to the base, J_k dq_k m/s; contact (4,)), plus the posture
    terms (posture (3, 12): kp, kd, q_stand) for qj, dqj (12,); clipped to +-limit (12,).
    Sums in the order of the NumPy expressions they replace, so the results are the same:
    the feet's velocities as ``np.einsum("kij,kj->ki", J, dq)`` sums them (its loop over
    contiguous rows of three adds the first and third products, then the second, then the
    output's zero)."""
    for k in range(4):
        for i in range(3):
            tau[3 * k + i] = J[k, 0, i] * f_base[k, 0] + J[k, 1, i] * f_base[k, 1] + J[k, 2, i] * f_base[k, 2]
    for j in range(12):
        tau[j] += tau_g[j]
    if land:
        F = np.empty((4, 3))
        for k in range(4):
            for a in range(3):
                target = -h_ref if a == 2 else p_b[k, a] if contact[k] != 0 else p_land[k, a]
                v = ((J[k, a, 0] * dqj[3 * k] + J[k, a, 2] * dqj[3 * k + 2]) + J[k, a, 1] * dqj[3 * k + 1]) + 0.0
                F[k, a] = k_land * (target - p_b[k, a]) - d_land * v
        for k in range(4):
            for i in range(3):
                tau[3 * k + i] += J[k, 0, i] * F[k, 0] + J[k, 1, i] * F[k, 1] + J[k, 2, i] * F[k, 2]
    for j in range(12):
        t = tau[j] + (posture[0, j] * (posture[2, j] - qj[j]) - posture[1, j] * dqj[j])
        if t < -limit[j]:  # comparisons rather than min/max: a NaN stays NaN
            t = -limit[j]
        elif t > limit[j]:
            t = limit[j]
        tau[j] = t


# Froggy stages (``symrom.sim.controllers.froggy``), by index.
SETTLE, CROUCH, HOLD, PUSH_ALL, PUSH_REAR, FLIGHT, LAND = range(7)
# Positions of the froggy parameters in the vector ``froggy_torque`` takes.
FROGGY_PARAMS = ("stand_height", "crouch_height", "crouch_shift", "crouch_pitch", "push_speed", "push_rise",
                 "t_settle", "t_crouch", "force_all", "force_rear", "angle", "raibert", "kp_stance",
                 "kd_stance", "kp_push", "kd_push", "kp_swing", "kd_swing", "kp_land", "kd_land", "xy_ratio",
                 "k_att", "d_att")
(_STAND, _CROUCH_H, _SHIFT, _PITCH, _SPEED, _RISE, _T_SETTLE, _T_CROUCH, _F_ALL, _F_REAR, _ANGLE, _RAIBERT,
 _KP_ST, _KD_ST, _KP_PUSH, _KD_PUSH, _KP_SW, _KD_SW, _KP_LAND, _KD_LAND, _XY, _K_ATT, _D_ATT) = range(23)


@njit
def condensed_qp(W4, VA, V, Bm, x0, x_ref, alpha, H, g):
    """The condensed MPC's H (12 h, 12 h) and g (12 h,) (``mpc.CondensedForm``), in place.

    W4 (h, m, h, m), VA (m h, 13), V (m h, 13 h): the yaw's parts; Bm (m, 12) the input map's
    moving rows; x0 (13,); x_ref (h * 13,); alpha 1/N^2. H = 2 (D^T W D + alpha I),
    g = 2 D^T (VA x0 - V x_ref), D = blkdiag(Bm): only the blocks on and above the diagonal
    are computed, the rest mirrored.
    """
    h, m, nu = W4.shape[0], W4.shape[1], Bm.shape[1]
    # Each sum is taken in a row of accumulators (the same terms in the same order, from +0) and
    # stored once: stores into H and T inside the sums would make every step a memory round trip.
    T, acc = np.empty((m, nu)), np.empty(nu)
    for j in range(h):
        for k in range(j, h):
            for a in range(m):  # T = W_jk Bm, rows at a time (the inner loops run along rows)
                for c in range(nu):
                    acc[c] = 0.0
                for b in range(m):
                    w = W4[j, a, k, b]
                    for c in range(nu):
                        acc[c] += w * Bm[b, c]
                for c in range(nu):
                    T[a, c] = acc[c]
            for r in range(nu):  # H_jk = Bm^T T
                row = j * nu + r
                for c in range(nu):
                    acc[c] = 0.0
                for a in range(m):
                    w = 2.0 * Bm[a, r]
                    for c in range(nu):
                        acc[c] += w * T[a, c]
                # the block and its mirror below the diagonal; on the diagonal, its upper triangle
                for c in range(r if k == j else 0, nu):
                    H[row, k * nu + c] = acc[c]
                    H[k * nu + c, row] = acc[c]
    for i in range(h * nu):
        H[i, i] += 2.0 * alpha
    v = np.empty(h * m)
    for i in range(h * m):
        acc = 0.0
        for c in range(VA.shape[1]):
            acc += VA[i, c] * x0[c]
        for c in range(x_ref.shape[0]):
            acc -= V[i, c] * x_ref[c]
        v[i] = acc
    for j in range(h):
        for c in range(nu):
            acc = 0.0
            for a in range(m):
                acc += Bm[a, c] * v[j * m + a]
            g[j * nu + c] = 2.0 * acc


@njit
def smooth(s):
    """Cosine blend 0 -> 1 on s in [0, 1] (clipped), zero slope at both ends."""
    s = min(max(s, 0.0), 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


@njit
def froggy_torque(stage, t, prm, t_push, t_land, mass, q, dq, R, omega, contact, foot_pos, feet0,
                  feet_w, b0, limit, plumb_land, flight_pitch, flight_track, n_el, xyz, rot, axis, col):
    """Joint torques (12,) N m of the froggy controller (``FroggyController.torque``) in
    ``stage`` at time t s; prm: the parameters in ``FROGGY_PARAMS`` order; t_push: start of
    the push, s; t_land: touch-down time, s; mass kg; the state q, dq (18,), R (3, 3),
    omega (3,), contact (4,), foot_pos (4, 3) m; feet0 (4, 3) level-frame feet; feet_w
    (4, 3), b0 (3,): feet and base in the world when the push began; limit (12,) N m;
    plumb_land: 1 to hold the pair of legs at the trunk's lower end (the front pair while it is
    pitched nose down, else the rear) at level-frame (plumb) targets in the landing, 0 to keep
    every landing target body-fixed; flight_pitch rad: past this pitch the flight's leg targets
    turn with the trunk by the excess, each foot kept at its level target's height below the base
    (inf: level at any pitch); flight_track: 1 to give the flight's PD its targets' own velocity in
    the base frame (the trunk turns under them) while no foot is down, 0 to damp the feet to rest
    in it; the leg chains as
    ``symrom.robots.compiled.legs_one`` takes them."""
    pos, J = np.empty((4, 3)), np.empty((4, 3, 3))
    legs_one(q[:12], n_el, xyz, rot, axis, col, pos, J)
    vel = np.zeros((4, 3))
    for k in range(4):
        for a in range(3):
            vel[k, a] = J[k, a, 0] * dq[3 * k] + J[k, a, 1] * dq[3 * k + 1] + J[k, a, 2] * dq[3 * k + 2]
    # Arrays are filled element by element rather than by np.array, np.eye, np.full, np.arange or
    # slice copies: the same numbers, and numba compiles a cold cache seconds faster.
    cyaw, syaw = np.cos(q[17]), np.sin(q[17])
    Y = np.zeros((3, 3))
    Y[0, 0], Y[0, 1], Y[1, 0], Y[1, 1], Y[2, 2] = cyaw, -syaw, syaw, cyaw, 1.0
    to_base = np.zeros((3, 3))
    to_base[0, 0], to_base[1, 1], to_base[2, 2] = 1.0, 1.0, 1.0
    plumb = to_base  # level frame to base frame, where a leg is held plumb
    if stage == FLIGHT or (stage == LAND and plumb_land != 0):
        plumb = matmul(R, Y, True)
    if stage == FLIGHT:  # legs hang plumb (level frame) for the landing
        to_base = plumb
    plumb_lo, plumb_hi = 0, 0  # the legs k with plumb_lo <= k < plumb_hi are held plumb
    if stage == LAND and plumb_land != 0:
        if q[16] > 0.0:
            plumb_hi = 2
        else:
            plumb_lo, plumb_hi = 2, 4
    weight = mass * GRAVITY
    shift = 0.0
    kp, kd, z_leg = np.empty(4), np.empty(4), np.empty(4)
    for k in range(4):
        kp[k], kd[k], z_leg[k] = prm[_KP_ST], prm[_KD_ST], -prm[_STAND]
    grf = np.zeros((4, 3))
    x_off = np.zeros(4)
    v_d = np.zeros((4, 3))
    xy = prm[_XY]
    base = q[12:15].copy()
    pitch_ref = 0.0
    if stage == CROUCH or stage == HOLD or stage == PUSH_ALL:
        pitch_ref = prm[_PITCH] * smooth((t - prm[_T_SETTLE]) / prm[_T_CROUCH])
    err = np.zeros(3)
    err[0], err[1] = q[15], q[16] - pitch_ref
    tilt = matvec(R, err)
    level = np.empty(3)
    for a in range(3):
        level[a] = -prm[_K_ATT] * tilt[a]
    level[0] -= prm[_D_ATT] * omega[0]
    level[1] -= prm[_D_ATT] * omega[1]
    all_legs = np.empty(4, dtype=np.int64)
    for k in range(4):
        all_legs[k] = k
    p_stroke = np.zeros((4, 3))
    excess, ce, se = 0.0, 1.0, 0.0  # rad: the flight's pitch past flight_pitch, its cosine and sine
    if stage <= HOLD:
        if stage != SETTLE:
            a = smooth((t - prm[_T_SETTLE]) / prm[_T_CROUCH])
            for k in range(4):
                z_leg[k] = -(prm[_STAND] + a * (prm[_CROUCH_H] - prm[_STAND])) + a * prm[_PITCH] * feet0[k, 0]
            shift = a * prm[_SHIFT]
        distribute(foot_pos, base, all_legs, np.array([0.0, 0.0, weight]), level, 0.6, grf)
    elif stage == PUSH_ALL or stage == PUSH_REAR:
        sa, ca = np.sin(prm[_ANGLE]), np.cos(prm[_ANGLE])
        along = np.zeros(3)
        along[0], along[2] = sa, ca
        direction = matvec(Y, along)
        travel = prm[_SPEED] * (t - t_push)
        b_d, thrust = np.empty(3), np.empty(3)
        for a in range(3):
            b_d[a] = b0[a] + travel * direction[a]
            thrust[a] = prm[_F_ALL] * direction[a]
        b_d[2] = min(b_d[2], b0[2] + prm[_RISE])
        stroke = np.empty((4, 3))
        for k in range(4):
            for a in range(3):
                stroke[k, a] = feet_w[k, a] - b_d[a]
        p_stroke = matmul(stroke, Y, False)
        for k in range(4):
            v_d[k, 0], v_d[k, 1], v_d[k, 2] = -prm[_SPEED] * sa, 0.0, -prm[_SPEED] * ca
        for k in range(4):
            kp[k], kd[k] = prm[_KP_PUSH], prm[_KD_PUSH]
        xy = 1.0
        if stage == PUSH_ALL:
            distribute(foot_pos, base, all_legs, thrust, level, 0.6, grf)
        else:
            rear = np.empty(2, dtype=np.int64)
            rear[0], rear[1] = 2, 3
            share = prm[_F_REAR] / prm[_F_ALL]
            for a in range(3):
                thrust[a] = share * thrust[a]
            distribute(foot_pos, base, rear, thrust, level, 0.6, grf)
            for k in range(2):  # front feet tuck up and forward
                z_leg[k], x_off[k] = -prm[_CROUCH_H] + 0.04, 0.04
                kp[k], kd[k] = prm[_KP_SW], prm[_KD_SW]
                v_d[k, 0], v_d[k, 1], v_d[k, 2] = 0.0, 0.0, 0.0
    elif stage == FLIGHT:
        for k in range(4):
            kp[k], kd[k], x_off[k] = prm[_KP_SW], prm[_KD_SW], prm[_RAIBERT] * dq[12]
        if q[16] > flight_pitch:
            excess = q[16] - flight_pitch
        elif q[16] < -flight_pitch:
            excess = q[16] + flight_pitch
        if excess != 0.0:  # the targets' frame pitched by the excess, the feet at the same depth
            ce, se = np.cos(excess), np.sin(excess)
            P = np.zeros((3, 3))
            P[0, 0], P[0, 2], P[1, 1], P[2, 0], P[2, 2] = ce, se, 1.0, -se, ce
            to_base = matmul(to_base, P, False)
            for k in range(4):
                z_leg[k] = (feet0[k, 2] - prm[_STAND] + (feet0[k, 0] + x_off[k]) * se) / ce - feet0[k, 2]
    else:  # land
        for k in range(4):
            kp[k], kd[k] = prm[_KP_LAND], prm[_KD_LAND]
        a = smooth((t - t_land) / 0.3)  # the weight support ramps in over 0.3 s
        n_down = 0
        for k in range(4):
            if contact[k] != 0:
                n_down += 1
        if n_down:
            down = np.empty(n_down, dtype=np.int64)  # the feet down, in order (np.flatnonzero)
            n_down = 0
            for k in range(4):
                if contact[k] != 0:
                    down[n_down] = k
                    n_down += 1
            up = np.zeros(3)
            up[2] = weight
            distribute(foot_pos, base, down, up, level, 0.6, grf)
            for k in range(4):
                for c in range(3):
                    grf[k, c] *= a
    p_d = np.empty((4, 3))
    lv = np.empty(3)
    for k in range(4):
        lv[0], lv[1], lv[2] = feet0[k, 0] + x_off[k] + shift, feet0[k, 1], feet0[k, 2] + z_leg[k]
        r = matvec(plumb if plumb_lo <= k < plumb_hi else to_base, lv)
        for a in range(3):
            p_d[k, a] = r[a]
    if stage == PUSH_ALL or stage == PUSH_REAR:
        for k in range(2 if stage == PUSH_REAR else 0, 4):
            for a in range(3):
                p_d[k, a] = p_stroke[k, a]
    if stage == FLIGHT and flight_track != 0 and contact[0] == 0 and contact[1] == 0 and contact[2] == 0 \
            and contact[3] == 0:
        # in the base frame a target moves at (w_T - omega) x p_d, w_T its frame's turning: the yaw
        # (taken as omega's z), and the pitch past flight_pitch; so -omega's roll part, and its pitch
        # part below the limit, from the yaw frame back to the world, then to the base frame (R^T)
        w_pitch = -syaw * omega[0] + cyaw * omega[1]  # omega's roll and pitch parts in the yaw frame
        wx = -(cyaw * omega[0] + syaw * omega[1])
        wy = 0.0 if excess != 0.0 else -w_pitch
        rw = np.zeros(3)
        rw[0], rw[1] = cyaw * wx - syaw * wy, syaw * wx + cyaw * wy
        rel = np.empty(3)
        for a in range(3):
            rel[a] = R[0, a] * rw[0] + R[1, a] * rw[1]
        for k in range(4):
            v_d[k, 0] = rel[1] * p_d[k, 2] - rel[2] * p_d[k, 1]
            v_d[k, 1] = rel[2] * p_d[k, 0] - rel[0] * p_d[k, 2]
            v_d[k, 2] = rel[0] * p_d[k, 1] - rel[1] * p_d[k, 0]
        if excess != 0.0:  # past flight_pitch each target also reaches down as the excess grows
            for k in range(4):
                dz = w_pitch * (feet0[k, 0] + x_off[k] + (feet0[k, 2] - prm[_STAND]) * se) / (ce * ce)
                for a in range(3):
                    v_d[k, a] += to_base[a, 2] * dz
    tau = np.empty(12)
    for k in range(4):
        f = np.empty(3)
        for a in range(3):
            ax = 1.0 if a == 2 else xy
            f_ff = -(grf[k, 0] * R[0, a] + grf[k, 1] * R[1, a] + grf[k, 2] * R[2, a])
            f[a] = kp[k] * ax * (p_d[k, a] - pos[k, a]) + kd[k] * ax * (v_d[k, a] - vel[k, a]) + f_ff
        over = 1.0
        for j in range(3):
            tj = J[k, 0, j] * f[0] + J[k, 1, j] * f[1] + J[k, 2, j] * f[2]
            tau[3 * k + j] = tj
            over = max(over, abs(tj) / limit[3 * k + j])
        for j in range(3):  # the leg's torques scaled together into the limits
            tau[3 * k + j] /= over
    return tau


# The routines each built-in motion's controller calls every tick (``warm_up``).
MOTION_ROUTINES = {"pronk": ("legs_one", "pronk_stance_torque", "clip_forces", "condensed_qp"),
                   "froggy": ("legs_one", "froggy_torque")}


# Of those, what a second process can compile beside the one that compiles the motion's routines
# (``symrom.sim.generation.warm.prepare``): the froggy force distribution, which
# ``froggy_torque``'s typing reaches only after the leg kinematics and the products, by when the
# other process has put it in the disk cache (else it is compiled where it is reached, as alone).
BESIDE_ROUTINES = {"froggy": ("distribute",)}
# Feet (4, 3) m of a stance, for compiling the froggy routines with the types a tick passes them
_WARM_FEET = np.array([[0.2, -0.1, 0.0], [0.2, 0.1, 0.0], [-0.2, -0.1, 0.0], [-0.2, 0.1, 0.0]])


def routines(motion: str) -> list:
    """The compiled routines (numba dispatchers) a controller of ``motion`` calls; none for a
    motion that is not built in."""
    return [legs_one if name == "legs_one" else globals()[name] for name in MOTION_ROUTINES.get(motion, ())]


def routines_beside(motion: str) -> list:
    """The routines of ``motion`` a second process can compile (``BESIDE_ROUTINES``)."""
    return [globals()[name] for name in BESIDE_ROUTINES.get(motion, ())]


def warm_beside(motions: tuple[str, ...] = ("froggy",)) -> None:
    """Compile (or load) ``routines_beside`` of ``motions`` for the argument types their
    controller passes them."""
    if "froggy" in motions:
        feet = _WARM_FEET.copy()
        distribute(feet, np.zeros(3), np.arange(4), np.ones(3), np.zeros(3), 0.6, np.empty((4, 3)))


def warm_up(motions: tuple[str, ...] = ("pronk", "froggy")) -> None:
    """Compile (or load from the disk cache) the routines the controllers of ``motions`` call,
    now, as their first tick would: the one-configuration leg kinematics, the pronk controller's
    and the MPC's, the froggy controller's."""
    from symrom.robots import leg_kinematics

    kin = leg_kinematics("go1")
    kin.one(np.zeros(12))
    if "pronk" in motions:
        J, f4, t12 = np.zeros((4, 3, 3)), np.zeros((4, 3)), np.zeros(12)
        pronk_stance_torque(J, f4, t12, True, f4, f4, np.ones(4, dtype=np.uint8), 0.3, 1.0, 1.0,
                            np.zeros((3, 12)), t12, t12, np.ones(12), np.empty(12))
        clip_forces(np.zeros((2, 4, 3)), np.ones((2, 4)), 0.0, 1.0, 0.6)
        h, m = 2, 6
        condensed_qp(np.zeros((h, m, h, m)), np.zeros((h * m, 13)), np.zeros((h * m, 13 * h)), np.zeros((m, 12)),
                     np.zeros(13), np.zeros(13 * h), 1.0, np.empty((12 * h, 12 * h)), np.empty(12 * h))
    if "froggy" in motions:
        feet = _WARM_FEET.copy()
        q, dq = np.zeros(18), np.zeros(18)
        q[14] = 0.3
        froggy_torque(SETTLE, 0.0, np.ones(len(FROGGY_PARAMS)), 1.0, 0.0, 12.0, q, dq, np.eye(3), np.zeros(3),
                      np.ones(4, dtype=np.uint8), feet, feet, feet, np.zeros(3), np.ones(12), 0, np.inf, 0,
                      *kin.chain_arrays())
