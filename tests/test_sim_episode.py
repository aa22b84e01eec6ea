"""The one episode loop (its order of reading, stopping, pushing, stepping and logging, on a
scripted world) and the pronk's and the froggy's push-policy seams (a policy called every tick of
the push that re-plans its end; the commanded wrench as the torques' derived force; the events
the controllers record with or without a policy)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from symrom.data.preprocess import input_from_torques
from symrom.names import BASE_POS, JOINTS, N_Q
from symrom.robots import leg_kinematics
from symrom.sim.controllers.froggy import FroggyController, FroggyParams, FroggyPushPolicy, FroggyPushTiming
from symrom.sim.controllers.froggy import scaled as froggy_scaled
from symrom.sim.controllers.pronk import PronkController, PronkParams, PushCommand, PushPolicy, PushTiming
from symrom.sim.engines.bullet import BulletWorld
from symrom.sim.engines.world import RobotState, WorldConfig
from symrom.sim.generation.episode import BasePush, run_episode


class ScriptedWorld:
    """A world whose tick count is its state: records every call the loop makes."""

    def __init__(self, config: WorldConfig):
        self.config, self.calls, self.tick = config, [], 0

    def reset(self, q, dq=None):
        self.calls.append(("reset", float(q[0])))
        self.tick = 0

    def state(self):
        q = np.zeros(N_Q)
        q[0] = self.tick
        return RobotState(t=self.tick * self.config.dt, q=q, dq=np.zeros(N_Q), omega=np.zeros(3), R=np.eye(3),
                          contact=np.array([0, 0, 0, self.tick % 3 == 0], dtype=np.uint8),
                          foot_pos=np.zeros((4, 3)), foot_vel=np.zeros((4, 3)))

    def apply_base_force(self, f):
        self.calls.append(("push", self.tick))

    def step(self, tau, report=True):
        self.calls.append(("step", self.tick, report))
        self.tick += 1
        return np.asarray(tau) if report else None


class Counter:
    """Done at ``done_tick``; its torque is the q[0] it saw."""

    def __init__(self, done_tick=None):
        self.done_tick, self.seen = done_tick, []

    def reset(self, world):
        return np.full(N_Q, 7.0)

    def done(self, s):
        return self.done_tick is not None and s.q[0] >= self.done_tick

    def torque(self, s):
        self.seen.append(s.q[0])
        return np.full(12, s.q[0])

    def diagnostics(self):
        return {}


class StopAt:
    """A watcher failing at its ``n``-th logged sample."""

    reason = "planted"

    def __init__(self, n):
        self.n, self.updates = n, 0

    def update(self, contact):
        self.updates += 1
        return self.updates >= self.n


def test_the_loop_reads_stops_pushes_steps_and_logs_in_order():
    world, ctrl = ScriptedWorld(WorldConfig(physics_hz=1000, log_hz=250)), Counter(done_tick=10)
    samples = []
    end = run_episode(world, ctrl, ctrl.reset(world), max_time=1.0,
                      on_sample=lambda tick, s, applied: samples.append((tick, s.q[0], applied[0])),
                      reading=lambda s: RobotState(**{**s.__dict__, "q": s.q + 0.5}),
                      push=BasePush(np.ones(3), t_start=0.003, t_end=0.006))
    assert world.calls[0] == ("reset", 7.0)
    # done is asked of the reading (tick 9 reads 9.5 < 10, tick 10 reads 10.5): ten ticks stepped
    assert end == type(end)(finished=True, ticks=10, stopped_at=None)
    assert ctrl.seen == [k + 0.5 for k in range(10)]
    assert [c[1] for c in world.calls if c[0] == "push"] == [3, 4, 5]  # t in [3 ms, 6 ms)
    assert [c for c in world.calls if c[0] == "step"] == [("step", k, k % 4 == 0) for k in range(10)]
    # every 4th tick from the first, after its step, with the reading and the applied torque
    assert samples == [(0, 0.5, 0.5), (4, 4.5, 4.5), (8, 8.5, 8.5)]


def test_the_watcher_stops_the_loop_and_the_time_limit_ends_it():
    world, ctrl = ScriptedWorld(WorldConfig()), Counter()
    end = run_episode(world, ctrl, ctrl.reset(world), max_time=1.0, watch=StopAt(3))
    assert end.stopped_at == 4 and not end.finished and end.ticks == 5  # the 3rd logged tick, then no step
    world = ScriptedWorld(WorldConfig())
    end = run_episode(world, Counter(), np.zeros(N_Q), max_time=0.0123)
    assert end == type(end)(finished=False, ticks=13)  # round(0.0123 s x 1 kHz) + 1 ticks


class ReplanningPush:
    """A closed loop in miniature: a constant lift for ``duration`` s, re-planned once, at
    ``replan_at`` s into the push, to end at ``new_duration`` s."""

    def __init__(self, weight: float, duration=0.2, replan_at=0.05, new_duration=0.12):
        self.weight, self.duration, self.replan_at, self.new_duration = weight, duration, replan_at, new_duration
        self.started, self.calls = [], []

    def start(self, state):
        self.started.append(state.t)
        return PushTiming(duration=self.duration, vx=0.5, vz=1.5, flight_time=0.3)

    def command(self, state, since):
        self.calls.append((state.t, since))
        timing = None
        if since >= self.replan_at and len([c for c in self.calls if c[1] >= self.replan_at]) == 1:
            timing = PushTiming(duration=self.new_duration, vx=0.4, vz=1.4, flight_time=0.25)
        return PushCommand(np.array([0.2, 0.0, 2.0]) * self.weight, np.zeros(3), timing)


def test_a_push_policy_is_called_every_tick_of_the_push_and_may_replan_its_end():
    params = PronkParams()
    world = BulletWorld("go1")
    policy = ReplanningPush(weight=world.mass * 9.81)
    ctrl = PronkController("go1", params, push=policy)
    assert isinstance(policy, PushPolicy)
    t_due = ctrl.plan.t_push
    phases = []
    try:
        run_episode(world, ctrl, ctrl.reset(world), max_time=t_due + 0.2,
                    on_sample=lambda tick, s, applied: phases.append((s.t, ctrl.phase)))
    finally:
        world.close()
    dt = world.config.dt
    t0 = policy.started[0]
    assert policy.started == [t0] and t_due <= t0 < t_due + dt  # once, at the first tick it is due
    assert ctrl.push_start[0] == t0
    sinces = np.array([s for _, s in policy.calls])
    assert sinces[0] == 0.0 and np.allclose(np.diff(sinces), dt)  # every tick, from the first
    # the push ended at the first tick at or past the re-planned end, not the first plan's
    assert t0 + 0.12 - dt < policy.calls[-1][0] < t0 + 0.12
    assert ctrl.plan.push_time == 0.12 and ctrl.plan.t_push == t0 and ctrl.plan.vx == 0.4
    assert ctrl.liftoff is not None and ctrl.phase in ("flight", "land")
    assert {p for t, p in phases if t0 <= t < t0 + 0.12 - dt} == {"push"}
    assert {p for t, p in phases if t < t0} == {"crouch"}


def test_the_pronk_records_its_events_without_a_policy():
    world, ctrl = BulletWorld("go1"), PronkController("go1", PronkParams())
    try:
        run_episode(world, ctrl, ctrl.reset(world), max_time=ctrl.plan.t_push + ctrl.plan.push_time + 0.01)
    finally:
        world.close()
    t0, p0 = ctrl.push_start
    assert ctrl.plan.t_push <= t0 < ctrl.plan.t_push + world.config.dt and p0.shape == (3,)
    pos, vel = ctrl.liftoff
    assert vel[2] > 0.5 and pos[2] > p0[2]  # the MPC's push left the crouch rising
    assert ctrl.touchdown is None and ctrl.phase == "flight"


@pytest.mark.parametrize("force", [[0.0, 0.0, 250.0], [40.0, -10.0, 180.0]])
def test_the_commanded_wrench_is_the_torques_derived_force(force):
    """push_torque's torques, read back as a dataset reads a model's input (massless legs, all
    feet down), give the commanded force, the posture PD's share made up for: what the planner's
    execution relies on."""
    world = BulletWorld("go1")
    ctrl = PronkController("go1", PronkParams())
    try:
        world.reset(ctrl.reset(world))
        s = world.state()
    finally:
        world.close()
    assert s.q[BASE_POS][2] > 0.2 and s.contact.all()  # standing, feet down
    q, dq = s.q.copy(), s.dq.copy()
    q[JOINTS] += np.tile([0.05, -0.03, 0.04], 4)  # off the standing pose, moving: the PD pushes
    dq[JOINTS] = np.random.default_rng(0).normal(0.0, 1.0, 12)
    s = replace(s, q=q, dq=dq)
    F = np.array(force)
    tau = ctrl.push_torque(s, F, np.array([0.5, -1.0, 0.2]))
    assert np.all(np.abs(tau) < world.torque_limit)  # not clipped, so exact
    u = input_from_torques("go1", s.q, tau, np.ones((1, 4)))
    np.testing.assert_allclose(u[0, 12:15], F, rtol=0, atol=1e-8)


class FroggyScript:
    """A froggy push policy: a constant thrust for ``four`` s on four feet, then ``rear`` s on the
    rear feet, re-timed once (the rear part lengthened to ``new_rear``) ``retime_at`` s in."""

    def __init__(self, weight: float, four=0.08, rear=0.05, retime_at=0.03, new_rear=0.06):
        self.weight, self.four, self.rear, self.retime_at, self.new_rear = weight, four, rear, retime_at, new_rear
        self.started, self.calls, self.torques = [], [], []

    def start(self, state):
        self.started.append(state.t)
        return FroggyPushTiming(self.four, self.rear)

    def command(self, state, since):
        self.calls.append((state.t, since))
        timing = None
        if since >= self.retime_at and len([c for c in self.calls if c[1] >= self.retime_at]) == 1:
            timing = FroggyPushTiming(self.four, self.new_rear)
        return PushCommand(np.array([0.5, 0.0, 1.6]) * self.weight, np.zeros(3), timing)


def test_a_froggy_push_policy_drives_four_feet_then_the_rear_feet():
    params = froggy_scaled(FroggyParams(), "a1")
    world = BulletWorld("a1")
    policy = FroggyScript(weight=world.mass * 9.81)
    ctrl = FroggyController("a1", params, push=policy)
    assert isinstance(policy, FroggyPushPolicy)
    t_due = params.t_settle + params.t_crouch + params.t_hold
    stages = []
    try:
        run_episode(world, ctrl, ctrl.reset(world), max_time=t_due + 0.4,
                    on_sample=lambda tick, s, applied: stages.append((s.t, ctrl.phase)))
    finally:
        world.close()
    dt = world.config.dt
    t0 = policy.started[0]
    assert policy.started == [t0] and t_due <= t0 < t_due + dt and ctrl.push_start[0] == t0
    sinces = np.array([s for _, s in policy.calls])
    assert sinces[0] == 0.0 and np.allclose(np.diff(sinces), dt)
    assert t0 + 0.14 - dt < policy.calls[-1][0] < t0 + 0.14  # the re-timed end: 0.08 + 0.06 s
    assert (ctrl.timing.four, ctrl.timing.rear) == pytest.approx((0.08, 0.06))
    four = {p for t, p in stages if t0 <= t < t0 + 0.08 - dt}
    rear = {p for t, p in stages if t0 + 0.08 <= t < t0 + 0.14 - dt}
    assert four == {"push_all"} and rear == {"push_rear"}
    assert ctrl.liftoff is not None and ctrl.airborne  # 1.6 weights of thrust throw it


def test_the_froggy_records_its_events_without_a_policy():
    params = froggy_scaled(FroggyParams(), "a1")
    world, ctrl = BulletWorld("a1"), FroggyController("a1", params)
    try:
        run_episode(world, ctrl, ctrl.reset(world), max_time=params.max_time)
    finally:
        world.close()
    t0, p0 = ctrl.push_start
    assert t0 == pytest.approx(params.t_settle + params.t_crouch + params.t_hold, abs=1e-3)
    pos, vel = ctrl.liftoff
    assert vel[0] > 0.5 and pos[0] > p0[0]
    t_td, p_td = ctrl.touchdown
    assert ctrl.airborne and t_td > t0 + 0.2 and p_td[0] > pos[0]


@pytest.mark.parametrize("legs", ["four", "rear"])
def test_the_froggy_policy_wrench_is_the_torques_derived_force(legs):
    """The froggy's push_torque, read back as a dataset reads a model's input (massless legs, the
    feet down), gives the commanded force: on four feet with the commanded moment too, on the
    rear feet alone the force exactly."""
    world = BulletWorld("a1")
    ctrl = FroggyController("a1", froggy_scaled(FroggyParams(), "a1"))
    try:
        world.reset(ctrl.reset(world))
        s = world.state()
    finally:
        world.close()
    ctrl.phase = "push_all" if legs == "four" else "push_rear"
    F, M = np.array([60.0, 0.0, 150.0]), np.array([0.0, 2.0, 0.0])
    tau = ctrl.push_torque(s, F, M)
    contact = np.ones((1, 4)) if legs == "four" else np.array([[0.0, 0.0, 1.0, 1.0]])
    u = input_from_torques("a1", s.q, tau, contact)
    np.testing.assert_allclose(u[0, 12:15], F, rtol=0, atol=1e-6)
    if legs == "four":
        r = s.foot_pos - s.q[BASE_POS]
        grf = -np.stack([np.linalg.solve(J.T, t) for J, t in zip(leg_kinematics("a1").one(s.q[JOINTS])[1],
                                                                     tau.reshape(4, 3))]) @ s.R.T
        np.testing.assert_allclose(np.cross(r, grf).sum(axis=0), M, atol=1e-6)


def test_a_froggy_policy_push_ends_when_its_rear_feet_leave():
    # a rear-only part planned far longer than the legs can push: the push ends once the rear
    # feet have been off the ground for FEET_OFF, not at the planned end, and its timing says so
    from symrom.sim.controllers.froggy import FEET_OFF

    params = froggy_scaled(FroggyParams(), "a1")
    world = BulletWorld("a1")
    policy = FroggyScript(weight=world.mass * 9.81, rear=0.3, retime_at=1.0)
    ctrl = FroggyController("a1", params, push=policy)
    log = []
    try:
        run_episode(world, ctrl, ctrl.reset(world), max_time=params.t_settle + params.t_crouch + params.t_hold + 0.6,
                    on_sample=lambda tick, s, applied: log.append((s.t, ctrl.phase, s.contact[2:].any())))
    finally:
        world.close()
    t0, dt = policy.started[0], world.config.dt
    t, phase, rear_down = (np.array(v) for v in zip(*log))  # logged samples, every log period
    period = float(np.median(np.diff(t)))
    i_flight = np.flatnonzero(phase == "flight")[0]
    last_down = np.flatnonzero(rear_down[:i_flight])[-1]  # the rear feet's last logged contact
    assert phase[last_down] == "push_rear" and not rear_down[last_down + 1:i_flight + 1].any()
    # the flight began FEET_OFF after they left (between the two samples), to a tick
    assert t[last_down] + FEET_OFF - dt <= ctrl.t_flight <= t[last_down + 1] + FEET_OFF + dt
    assert t[i_flight] - t[last_down] <= FEET_OFF + 2 * period
    assert ctrl.timing.rear < 0.3 - 0.05  # the push ended well before its planned 0.3 s
    assert ctrl.timing.four + ctrl.timing.rear == pytest.approx(ctrl.t_flight - t0, abs=1e-9)
    assert ctrl.airborne and ctrl.liftoff is not None
