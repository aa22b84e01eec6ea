"""The PyBullet world: coordinates round-trip, contacts, torque saturation, pushes."""

from __future__ import annotations

import numpy as np
import pytest

from symrom.data.preprocess import foot_positions_world
from symrom.robots import get_robot
from symrom.robots.kinematics import rpy_to_matrix
from symrom.sim.engines.bullet import BulletWorld as World
from symrom.sim.engines.world import WorldConfig, euler_rate_matrix, matrix_to_rpy

STAND = np.tile([0.0, 0.8, -1.6], 4)


@pytest.fixture()
def world():
    w = World("a1")
    yield w
    w.close()


def test_reset_state_round_trip(world):
    rng = np.random.default_rng(0)
    q = np.zeros(18)
    q[:12] = STAND + rng.normal(0, 0.05, 12)
    q[12:15] = [0.1, -0.2, 0.5]
    q[15:] = [0.1, -0.2, 0.3]
    dq = rng.normal(0, 1.0, 18)
    world.reset(q, dq)
    s = world.state()
    assert s.t == 0.0
    np.testing.assert_allclose(s.q, q, atol=1e-6)
    np.testing.assert_allclose(s.dq, dq, atol=1e-6)
    np.testing.assert_allclose(s.R, rpy_to_matrix(q[15:])[0], atol=1e-6)
    np.testing.assert_allclose(s.omega, euler_rate_matrix(q[15:]) @ dq[15:], atol=1e-6)
    # Feet agree with the URDF kinematics (one source of geometry).
    np.testing.assert_allclose(s.foot_pos, foot_positions_world("a1", q[None])[0], atol=1e-6)
    assert s.contact.dtype == np.uint8 and not s.contact.any()  # base at 0.5 m: feet in the air


def test_foot_velocity_matches_kinematics(world):
    q = np.zeros(18)
    q[:12] = STAND
    q[12:15] = [0, 0, 0.6]
    q[15:] = [0.05, -0.1, 0.2]
    dq = np.random.default_rng(1).normal(0, 1.0, 18)
    world.reset(q, dq)
    v = world.state().foot_vel
    eps = 1e-6
    fd = (foot_positions_world("a1", (q + eps * dq)[None])[0]
          - foot_positions_world("a1", (q - eps * dq)[None])[0]) / (2 * eps)
    np.testing.assert_allclose(v, fd, atol=1e-4)


def test_rpy_helpers_invert_each_other():
    rpy = np.array([0.3, -0.4, 2.0])
    np.testing.assert_allclose(matrix_to_rpy(rpy_to_matrix(rpy)[0]), rpy, atol=1e-12)


def test_standing_contacts_and_saturation(world):
    q = world.standing_q(STAND)
    world.reset(q)
    s = world.state()
    assert s.contact.tolist() == [1, 1, 1, 1]  # valid before the first tick
    applied = world.step(np.full(12, 1e3))
    np.testing.assert_allclose(applied, get_robot("a1").torque_limit)
    assert world.t == pytest.approx(world.config.dt)


def test_unpowered_robot_falls_and_stays_finite(world):
    world.reset(world.standing_q(STAND))
    for _ in range(300):
        world.step(np.zeros(12))
    s = world.state()
    assert np.all(np.isfinite(s.q)) and s.q[14] < 0.2  # legs fold: the base sinks
    assert s.contact.sum() >= 2


def test_base_force_pushes_for_one_tick(world):
    q = np.zeros(18)
    q[:12] = STAND
    q[14] = 2.0  # high above the ground: free fall plus push
    world.reset(q)
    world.apply_base_force(np.array([world.mass * 100.0, 0, 0]))
    world.step(np.zeros(12))
    vx1 = world.state().dq[12]
    world.step(np.zeros(12))
    vx2 = world.state().dq[12]
    assert vx1 == pytest.approx(100.0 * world.config.dt, rel=0.15)  # base CoM, not the whole robot's
    assert vx2 == pytest.approx(vx1, abs=1e-3)  # no force on the next tick


def test_config_validation_and_separate_clients():
    with pytest.raises(ValueError):
        WorldConfig(physics_hz=1000, log_hz=300)
    a, b = World("a1"), World("a1")
    try:
        assert a.client != b.client
        a.reset(a.standing_q(STAND))
        b.reset(b.standing_q(STAND))
        for _ in range(50):
            a.step(np.zeros(12))
        assert b.state().q[14] == pytest.approx(b.standing_q(STAND)[14], abs=1e-6)
    finally:
        a.close()
        b.close()
    a.close()  # idempotent
