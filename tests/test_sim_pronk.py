"""Go1 forward pronking in PyBullet under the MPC controller, nominal and proxy."""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pytest

from symrom.names import BASE_POS, BASE_RPY, JOINTS
from symrom.robots import get_robot
from symrom.robots.stance import FOOT_PRELOAD, start_pose
from symrom.sim import proxy
from symrom.sim.controllers import pronk
from symrom.sim.engines.bullet import BulletWorld as World
from symrom.sim.engines.world import WorldConfig

SPEC = get_robot("go1")
LIMIT = np.asarray(SPEC.torque_limit)


def _jump(params: pronk.PronkParams) -> dict:
    """Run one jump to ``done``; per-tick true base pose, contacts and applied torques."""
    world = World("go1", WorldConfig())
    if params.proxy is not None:
        world = proxy.ProxyWorld(world, params.proxy)
    ctrl = pronk.PronkController("go1", params)
    world.reset(ctrl.reset(world))
    pos, rpy, contact, tau = [], [], [], []
    try:
        for _ in range(int(params.max_time * world.config.physics_hz) + 1):
            seen = world.state()
            if ctrl.done(seen):
                break
            truth = world.true_state() if params.proxy is not None else seen
            pos.append(truth.q[BASE_POS])
            rpy.append(truth.q[BASE_RPY])
            contact.append(truth.contact)
            tau.append(world.step(ctrl.torque(seen)))
    finally:
        world.close()
    return dict(pos=np.array(pos), rpy=np.array(rpy), contact=np.array(contact),
                tau=np.array(tau), t_end=len(pos) * world.config.dt, ctrl=ctrl)


def _longest_flight(contact: np.ndarray, dt: float) -> float:
    best = run = 0
    for airborne in contact.sum(axis=1) == 0:
        run = run + 1 if airborne else 0
        best = max(best, run)
    return best * dt


@pytest.mark.slow
@pytest.mark.parametrize("distance", [0.15, 0.35])
def test_pronk_jump_meets_the_checks(distance):
    params = pronk.PronkParams(distance=distance, apex_height=0.43)
    r = _jump(params)
    assert r["t_end"] < params.max_time  # settled, did not time out
    assert _longest_flight(r["contact"], 1e-3) >= 0.12
    assert r["pos"][:, 2].max() - r["pos"][0, 2] >= 0.05
    travel = r["pos"][-1, 0] - r["pos"][0, 0]
    assert travel >= 0.1
    assert abs(travel - distance) < 0.1  # the command is roughly realised
    assert np.abs(r["rpy"][:, :2]).max() < 0.8
    assert r["pos"][-1, 2] > 0.15
    assert np.all(np.abs(r["tau"]) <= LIMIT + 1e-9)
    assert len(r["ctrl"].mpc_solve_times) > 50
    assert np.median(r["ctrl"].mpc_solve_times) < 0.05


@pytest.mark.slow
def test_proxy_jump_completes():
    params = pronk.sample_params(np.random.default_rng(3), proxy=True)
    assert params.proxy is not None
    json.dumps(asdict(params))  # recordable in the file's generator attribute
    r = _jump(params)
    assert r["t_end"] < params.max_time
    assert _longest_flight(r["contact"], 1e-3) >= 0.1
    assert np.abs(r["rpy"][:, :2]).max() < 0.8 and r["pos"][-1, 2] > 0.15
    assert np.all(np.abs(r["tau"]) <= LIMIT + 1e-9)


def test_sample_params_ranges():
    rng = np.random.default_rng(0)
    ps = [pronk.sample_params(rng) for _ in range(200)]
    d = np.array([p.distance for p in ps])
    assert d.min() >= 0.1 and d.max() <= 0.4 and d.max() - d.min() > 0.25
    assert all(p.proxy is None for p in ps)
    plan = pronk.plan_jump(ps[0], brake_time=0.12)
    assert plan.vz > 1.0 and 0.0 < plan.vx < 1.5 and 0.1 < plan.push_time < 0.3


def test_initial_state_stands_on_the_feet():
    q = start_pose("go1")
    assert q[BASE_POS][2] == pytest.approx(SPEC.start_height)
    world = World("go1")
    try:
        world.reset(q)
        s = world.state()
        np.testing.assert_allclose(s.foot_pos[:, 2], 0.02 - FOOT_PRELOAD, atol=1e-6)  # r = 2 cm
        np.testing.assert_allclose(s.q[JOINTS][1::3], s.q[JOINTS][1], atol=1e-9)
    finally:
        world.close()


def test_proxy_motor_model():
    cfg = proxy.ProxyConfig(latency=0.003, no_load_speed=(30.0, 30.0, 20.0), knee_speed_frac=0.5)
    ch = proxy.TorqueChannel(cfg, np.full(12, 20.0), dt=0.001)
    out = [ch.apply(np.full(12, 10.0), np.zeros(12)) for _ in range(5)]
    assert np.all(out[2] == 0.0) and np.all(out[3] == 10.0)  # 3 ticks late
    # driving at 3/4 of the no-load speed: half the torque is left; braking keeps all
    lim = ch.available(np.full(12, 1.0), np.tile([22.5, 22.5, 15.0], 4))
    np.testing.assert_allclose(lim, 10.0)
    lim = ch.available(np.full(12, -1.0), np.tile([22.5, 22.5, 15.0], 4))
    np.testing.assert_allclose(lim, 20.0)


def test_proxy_world_perturbs_the_robot():
    import pybullet as p

    cfg = proxy.ProxyConfig(trunk_mass_scale=1.1, leg_mass_scale=0.9, friction=0.6, noise_q=0.002)
    world = proxy.ProxyWorld(World("go1"), cfg)
    try:
        c, rob = world.client, world.robot
        assert p.getDynamicsInfo(rob, -1, physicsClientId=c)[0] == pytest.approx(5.204 * 1.1)
        assert p.getDynamicsInfo(world.plane, -1, physicsClientId=c)[1] == pytest.approx(0.6)
        world.reset(start_pose("go1"))
        seen, truth = world.state(), world.true_state()
        assert seen.q.shape == truth.q.shape == (18,)
        assert 0 < np.abs(seen.q - truth.q).max() < 0.05  # noisy, but close
    finally:
        world.close()
