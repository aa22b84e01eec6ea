"""The MuJoCo world's compiled reads (state, the feet's ground forces) equal the reference path
through NumPy and MuJoCo's own functions, tick by tick through a jump: crouch, push, flight,
touchdown and a sideways push on the base."""

from __future__ import annotations

import numpy as np
import pytest

from symrom.sim.controllers.pronk import PronkController, PronkParams
from symrom.sim.engines.mujoco import MujocoWorld

FIELDS = ("q", "dq", "omega", "R", "foot_pos", "foot_vel")


@pytest.fixture(scope="module")
def jump():
    """Per tick of a Go1 pronk in MuJoCo: (compiled state, reference state, compiled forces,
    reference forces)."""
    world = MujocoWorld("go1")
    ctrl = PronkController("go1", PronkParams(distance=0.3))
    solve = world._solve_forces
    forces = []

    def both() -> None:  # inside step, between MuJoCo's two halves: the tick's contacts
        solve()
        fast = world._forces.copy()
        world._solve_forces_reference()
        forces.append((fast, world._forces.copy()))

    world._solve_forces = both
    world.reset(ctrl.reset(world))
    ticks = []
    for tick in range(1400):
        s, ref = world.state(), world.state_reference()
        ticks.append((s, ref))
        if 300 <= tick < 320:
            world.apply_base_force(np.array([0.0, 40.0, 0.0]))
        world.step(ctrl.torque(s), report=tick % 2 == 0)
    return ticks, forces, ctrl


def test_compiled_state_equals_the_reference(jump):
    ticks, _, ctrl = jump
    assert ctrl.phase == "land"  # the run went through the flight
    flags = np.array([s.contact for s, _ in ticks])
    assert (flags.sum(axis=1) == 0).any() and flags.all(axis=1).any()  # flight and stance
    for s, ref in ticks:
        for f in FIELDS:
            np.testing.assert_allclose(getattr(s, f), getattr(ref, f), rtol=0, atol=1e-12, err_msg=f)
        assert s.contact.dtype == ref.contact.dtype and np.array_equal(s.contact, ref.contact)
        assert s.t == ref.t


def test_compiled_foot_forces_equal_mj_contact_force(jump):
    _, forces, _ = jump
    fast, ref = (np.array(x) for x in zip(*forces))
    assert np.abs(ref[:, :, 2]).max() > 50.0 and (ref == 0).all(axis=(1, 2)).any()  # loaded and airborne
    np.testing.assert_allclose(fast, ref, rtol=0, atol=1e-9)


def test_the_base_push_lasts_one_tick():
    with MujocoWorld("go1") as w:
        w.reset(np.r_[np.tile([0.0, 0.8, -1.6], 4), 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # in the air
        w.apply_base_force(np.array([0.0, 0.0, 100.0]))
        w.step(np.zeros(12))
        pushed = w.state().dq[14]
        w.step(np.zeros(12))
        after = w.state().dq[14]
        assert pushed > -9.81 * w.config.dt + 1e-3  # the push held it up against gravity
        assert after - pushed == pytest.approx(-9.81 * w.config.dt, rel=1e-3)  # then free fall


def test_compiled_torques_are_numpys_saturation_and_leave_ctrl_on_a_nan():
    from symrom.sim.engines.compiled import mujoco_torques

    rng = np.random.default_rng(4)
    limit = np.abs(rng.normal(size=12)) * 20.0 + 1.0
    signs = np.where(rng.random(12) < 0.5, -1.0, 1.0)
    for _ in range(200):
        tau = rng.normal(size=12) * 30.0
        tau[rng.random(12) < 0.2] = -0.0
        clipped, ctrl = np.empty(12), np.empty(12)
        assert mujoco_torques(tau, -limit, limit, signs, clipped, ctrl)
        ref = np.minimum(np.maximum(tau, -limit), limit)
        np.testing.assert_array_equal(clipped.view(np.int64), ref.view(np.int64))
        np.testing.assert_array_equal(ctrl.view(np.int64), (ref * signs).view(np.int64))
    tau[3] = np.nan
    before = ctrl.copy()
    assert not mujoco_torques(tau, -limit, limit, signs, clipped, ctrl)
    assert np.isnan(clipped[3])
    np.testing.assert_array_equal(ctrl, before)
    with pytest.raises(ValueError, match="finite"):
        MujocoWorld("go1").step(np.full(12, np.nan))  # (an infinite torque saturates, as in NumPy)
