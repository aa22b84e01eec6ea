"""The compiled per-tick pieces of the simulation do the arithmetic of their NumPy references."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from symrom.robots import leg_kinematics
from symrom.robots.stance import start_pose
from symrom.sim.controllers import compiled
from symrom.sim.controllers.froggy import FroggyController, distribute, sample_params
from symrom.sim.controllers.mpc import ConvexMPC, continuous_dynamics, discretize
from symrom.sim.engines import bullet
from symrom.sim.engines.bullet import BulletWorld as World
from symrom.sim.engines.compiled import base_state
from symrom.sim.engines.world import euler_rate_matrix, matrix_to_rpy


@pytest.mark.parametrize("robot", ["go1", "a1", "laikago"])
def test_one_configuration_kinematics_match_the_vectorised(robot):
    kin = leg_kinematics(robot)
    q = np.random.default_rng(0).uniform(-2.0, 2.0, (20, 12))
    pos, J = kin.foot_positions_and_jacobians(q)
    for i in range(len(q)):
        p1, J1 = kin.one(q[i])
        np.testing.assert_allclose(p1, pos[i], rtol=0, atol=1e-13)
        np.testing.assert_allclose(J1, J[i], rtol=0, atol=1e-13)


def test_base_state_is_the_link_frame_of_the_inertial_frame():
    rng = np.random.default_rng(1)
    for _ in range(20):
        com_pos, v_com, omega, off_pos = rng.normal(size=(4, 3))
        com_orn, off_orn = Rotation.random(2, random_state=rng).as_quat()  # (x, y, z, w)
        q, dq, R = np.zeros(18), np.zeros(18), np.empty((3, 3))
        base_state(com_pos, com_orn, v_com, omega, off_pos, off_orn, q, dq, R)
        Rc = Rotation.from_quat(com_orn)
        R_ref = (Rc * Rotation.from_quat(off_orn)).as_matrix()
        pos = com_pos + Rc.apply(off_pos)
        np.testing.assert_allclose(R, R_ref, atol=1e-13)
        np.testing.assert_allclose(q[12:15], pos, atol=1e-13)
        np.testing.assert_allclose(q[15:], matrix_to_rpy(R_ref), atol=1e-12)
        np.testing.assert_allclose(dq[12:15], v_com + np.cross(omega, pos - com_pos), atol=1e-13)
        np.testing.assert_allclose(dq[15:], np.linalg.solve(euler_rate_matrix(q[15:]), omega), atol=1e-10)


def test_world_state_reads_what_was_reset():
    world = World("go1")
    try:
        q = start_pose("go1")
        q[12:15] += [0.1, -0.2, 0.05]
        q[15:] = [0.1, -0.2, 0.3]
        dq = np.r_[np.zeros(12), [0.3, -0.1, 0.2, 0.5, -0.4, 0.7]]
        world.reset(q, dq)
        s = world.state()
        np.testing.assert_allclose(s.q, q, atol=1e-6)  # PyBullet keeps the pose in its own precision
        np.testing.assert_allclose(s.dq, dq, atol=1e-6)
    finally:
        world.close()


def _distribute_numpy(foot_pos, centre, legs, force, moment, mu=0.6):
    """The NumPy reference: least norm by the pseudo-inverse, pulls dropped, friction cone."""
    A = np.zeros((6, 3 * len(legs)))
    for i, k in enumerate(legs):
        r = foot_pos[k] - centre
        A[:3, 3 * i:3 * i + 3] = np.eye(3)
        A[3:, 3 * i:3 * i + 3] = [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]
    sol = (np.linalg.pinv(A) @ np.r_[force, moment]).reshape(len(legs), 3)
    sol[:, 2] = np.maximum(sol[:, 2], 0.0)
    horiz = np.linalg.norm(sol[:, :2], axis=1)
    sol[:, :2] *= np.minimum(1.0, mu * sol[:, 2] / np.maximum(horiz, 1e-9))[:, None]
    grf = np.zeros((4, 3))
    grf[list(legs)] = sol
    return grf


@pytest.mark.parametrize("legs", [(0, 1, 2, 3), (0, 2, 3), (2, 3)])  # (2, 3): rank deficient
def test_force_distribution_matches_the_pseudo_inverse(legs):
    rng = np.random.default_rng(2)
    for _ in range(10):
        feet = np.array([[0.2, -0.13, 0.0], [0.2, 0.13, 0.0], [-0.2, -0.13, 0.0], [-0.2, 0.13, 0.0]])
        feet += rng.normal(0, 0.02, feet.shape)
        centre = np.array([0.0, 0.0, 0.27]) + rng.normal(0, 0.02, 3)
        force, moment = np.r_[rng.normal(0, 20, 2), 120.0], rng.normal(0, 5, 3)
        np.testing.assert_allclose(distribute(feet, centre, legs, force, moment),
                                   _distribute_numpy(feet, centre, legs, force, moment), atol=1e-9)


def test_the_froggy_products_are_numbas_own_to_the_bit():
    """``matvec``, ``matmul`` and ``pinv_apply`` call BLAS and LAPACK as numba's ``@`` and
    ``np.linalg.pinv`` do: the same bits, for every shape the force distribution gives (six rows,
    one to four legs' columns, rank deficient or nearly so) and for 3 x 3 products
    with either factor transposed."""
    import numba

    @numba.njit
    def generic(A, b, R, Y, x):
        return np.linalg.pinv(A) @ b, R.T @ Y, R @ Y, R @ x

    rng = np.random.default_rng(5)
    # (columns, the second leg's columns a multiple of the first's plus this much noise, or None)
    for n, near in ((3, None), (6, None), (9, None), (12, None), (6, 0.0), (6, 1e-13)):
        A = rng.normal(size=(6, n))
        if near is not None:  # rank 5, or a singular value between the cut and 1e-12 of the largest
            A[:, 3:] = A[:, :3] * 2.0 + near * rng.normal(size=(6, 3))
        b, R, Y, x = rng.normal(size=6), rng.normal(size=(3, 3)), rng.normal(size=(3, 3)), rng.normal(size=3)
        want = generic(A, b, R, Y, x)
        got = (compiled.pinv_apply(A, b), compiled.matmul(R, Y, True), compiled.matmul(R, Y, False),
               compiled.matvec(R, x))
        for w, g in zip(want, got):
            assert w.shape == g.shape and np.array_equal(w, g), (n, w, g)
    with pytest.raises(np.linalg.LinAlgError, match="infs or NaNs"):
        compiled.pinv_apply(np.full((6, 6), np.nan), np.ones(6))


@pytest.mark.slow
# a flight_pitch below the flight's pitch, so that the turned targets are compared too
# (and the flight's targets tracked, so that their velocities are compared too)
@pytest.mark.parametrize("landing, flight_pitch, track", [("body", None, False), ("low_plumb", 0.1, True)])
def test_compiled_froggy_torque_matches_numpy_through_a_jump(landing, flight_pitch, track):
    params = sample_params(np.random.default_rng(3))
    ctrl = FroggyController("a1", params, landing=landing, flight_pitch=flight_pitch, flight_track=track)
    world = World("a1")
    stages, turned = set(), False
    try:
        world.reset(ctrl.reset(world))
        for tick in range(int(2.2 * 1000)):
            s = world.state()
            if ctrl.done(s):
                break
            ref = copy.deepcopy(ctrl) if tick % 7 == 0 else None
            tau = ctrl.torque(s)
            if ref is not None:
                np.testing.assert_allclose(tau, ref.torque_numpy(s), rtol=1e-12, atol=1e-10)
                turned = turned or (ctrl.phase == "flight" and abs(s.q[16]) > ctrl.flight_pitch)
                assert ref.phase == ctrl.phase
                stages.add(ctrl.phase)
            world.step(tau, report=False)
    finally:
        world.close()
    assert {"settle", "crouch", "hold", "push_all", "push_rear", "flight", "land"} <= stages
    if flight_pitch is not None:
        assert turned, "the flight never pitched past flight_pitch: the turned targets went untested"


def test_step_without_report_steps_the_same():
    worlds = [World("a1"), World("a1")]
    try:
        for w in worlds:
            w.hold_joints([0, 3, 6, 9])
            w.reset(w.standing_q(np.tile([0.0, 0.8, -1.6], 4)))
        tau = np.random.default_rng(4).normal(0, 3, (40, 12))
        for t in tau:
            assert worlds[0].step(t, report=False) is None
            applied = worlds[1].step(t)
            assert applied.shape == (12,)
        a, b = worlds[0].state(), worlds[1].state()
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.dq, b.dq)
    finally:
        for w in worlds:
            w.close()


def test_mpc_model_kept_per_yaw_is_the_discretised_model():
    inertia = np.diag([0.06, 0.2, 0.22])
    mpc = ConvexMPC(13.1, inertia)
    rng = np.random.default_rng(5)
    for yaw in (0.0, 0.0, 0.4, 0.4, -1.0):
        r = rng.uniform(-0.3, 0.3, (4, 3))
        A, B = mpc.model(r, yaw)
        A_ref, B_ref = discretize(*continuous_dynamics(13.1, inertia, yaw, r), mpc.config.dt)
        np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-15)
        np.testing.assert_allclose(B, B_ref, rtol=1e-14, atol=1e-15)


def _stance_torque_numpy(J, f_base, tau_g, land, p_b, p_land, contact, h_ref, k_land, d_land,
                         posture, qj, dqj, limit):
    """The NumPy expressions ``PronkController.torque`` had before the compiled call."""
    v_rel = np.einsum("kij,kj->ki", J, dqj.reshape(4, 3))
    tau = np.einsum("kji,kj->ki", J, f_base).reshape(12)
    tau += tau_g
    if land:
        target = np.where(contact[:, None] != 0, p_b, p_land)
        target[:, 2] = -h_ref
        F = k_land * (target - p_b) - d_land * v_rel
        tau += np.einsum("kji,kj->ki", J, F).reshape(12)
    tau += posture[0] * (posture[2] - qj) - posture[1] * dqj
    return np.minimum(np.maximum(tau, -limit), limit)


@pytest.mark.parametrize("land", [False, True])
def test_pronk_stance_torque_is_the_numpy_arithmetic_exactly(land):
    rng = np.random.default_rng(3)
    limit = np.full(12, 30.0)
    for i in range(400):
        J, (f_base, p_b, p_land) = rng.normal(size=(4, 3, 3)), rng.normal(size=(3, 4, 3)) * 20.0
        tau_g, qj, dqj = rng.normal(size=(3, 12)) * 3.0
        if i % 4 == 0:  # exact zeros, signed, in the feet's velocities' products
            J[rng.random((4, 3, 3)) < 0.5] = -0.0
            dqj[rng.random(12) < 0.5] = 0.0
        posture = np.abs(rng.normal(size=(3, 12)))
        contact = rng.integers(0, 2, 4).astype(np.uint8)
        args = (J, f_base, tau_g, land, p_b, p_land, contact, 0.3, 400.0, 6.0, posture, qj, dqj, limit)
        tau = np.empty(12)
        compiled.pronk_stance_torque(*args, tau)
        np.testing.assert_array_equal(tau, _stance_torque_numpy(*args))
    tau_g[0] = np.nan
    compiled.pronk_stance_torque(*args[:2], tau_g, *args[3:], tau)
    assert np.isnan(tau[0])  # not clipped into the limits


def test_a_reused_client_simulates_as_a_fresh_one():
    def run():
        world = World("go1")
        try:
            world.reset(start_pose("go1"))
            for _ in range(200):
                world.step(np.full(12, 2.0))
            s = world.state()
            return world.client, np.concatenate([s.q, s.dq, s.foot_pos.ravel(), s.contact])
        finally:
            world.close()

    while bullet._SPARE:  # the first world on a new client
        bullet.p.disconnect(physicsClientId=bullet._SPARE.pop())
    c1, x1 = run()
    c2, x2 = run()
    assert c2 == c1  # the closed world's client, emptied
    np.testing.assert_array_equal(x2, x1)


def test_mpc_force_clipping_is_numpys_to_the_bit():
    rng = np.random.default_rng(4)
    for _i in range(300):
        U = rng.normal(size=(10, 4, 3)) * 200.0
        special = rng.random(U.shape) < 0.2
        U[special] = rng.choice([0.0, -0.0, 250.0, -250.0, np.inf, -np.inf, np.nan], special.sum())
        c = rng.integers(0, 2, (10, 4)).astype(float)
        ref = U.copy()
        ref[..., 2] = np.clip(ref[..., 2], 0.0 * c, 250.0 * c)
        lim = 0.6 * ref[..., 2]
        ref[..., 0] = np.clip(ref[..., 0], -lim, lim)
        ref[..., 1] = np.clip(ref[..., 1], -lim, lim)
        compiled.clip_forces(U, c, 0.0, 250.0, 0.6)
        np.testing.assert_array_equal(U.view(np.int64), ref.view(np.int64))  # signs of zeros too
