"""A planned jump executed in simulation, the same way whichever model planned it.

The pronk (``sim.controllers.pronk``) runs unchanged but for its push, which a push
policy (``PlannedPush``, a ``PushPolicy``) drives:

1. *Crouch and hold*: the pronk's standing start and MPC crouch.
2. *Plan*: when the push is due, the policy's ``start`` hands the planner the measured
   state and gets a ``Plan`` (one solve; its wall time is the plan's solve time); the
   push then lasts the planned stance duration.
3. *Push*: at every tick the policy commands the planned force F(t) (piecewise constant)
   and an attitude PD's moment about the CoM (``AttitudeGains``: it keeps the trunk level
   and does not change the sum); the pronk makes joint torques whose ground force through
   massless legs is that wrench (``PronkController.push_torque``), as a model's input is
   derived from torques (``data.preprocess``).
4. *Flight and landing*: the pronk's flight joint PD (landing posture at the take-off leg
   length) and its MPC landing, from the first touchdown.

The episode is the one loop every simulated jump runs (``sim.generation.episode``).

Landing point: the base's x at the first touchdown after the push (the first
physics tick with a foot in contact once the flight has lasted 0.05 s, the
pronk's rule), measured from the base's x at the start of the push, along the
heading (world x). The apex is the largest base height between the end of the
push and that touchdown. Where the robot comes to rest is reported as well
(``rest_x``). Units: m, s, N, N m.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from symrom.names import BASE_POS, BASE_RPY
from symrom.plan.problem import Plan
from symrom.sim.controllers.pronk import PronkController, PronkParams, PushCommand, PushTiming, heading, scales
from symrom.sim.engines.registry import make_world
from symrom.sim.engines.world import RobotState, WorldConfig
from symrom.sim.generation.episode import run_episode


class ExecutionError(RuntimeError):
    """A planned jump that could not be carried out (no flight, no touchdown)."""


@dataclass(frozen=True)
class AttitudeGains:
    """The push's attitude PD on the trunk (moment about the CoM, N m): kp N m/rad on roll,
    pitch and yaw error, kd N m s/rad on the angular velocity; for the Go1, scaled by mass x
    length^2 for other robots (the pronk's ``scales``). Chosen so that the trunk leaves the
    ground as level as in the pronk's own jumps (pitch at lift-off -0.02..0.01 rad in the
    training data; 0.015 rad median with these gains, 0.043 with 60 and 4, on the tuning
    targets), whatever the planner."""

    kp: float = 200.0
    kd: float = 8.0


class PlannedPush:
    """The pronk's push by a plan (a ``sim.controllers.pronk.PushPolicy``; module docstring):
    ``plan_fn(state) -> Plan`` is called once, when the push is due; then the plan's force
    F(t) along the heading of ``yaw`` rad, with the attitude PD (``AttitudeGains`` for the
    Go1, scaled to ``robot``) holding the trunk level at that yaw. ``result``: the ``Plan``,
    None until the push began."""

    def __init__(self, robot: str, yaw: float, plan_fn: Callable[[RobotState], Plan],
                 attitude: AttitudeGains | None = None):
        mass, length = scales(robot)
        a = attitude or AttitudeGains()
        self.attitude = AttitudeGains(a.kp * mass * length ** 2, a.kd * mass * length ** 2)
        self.plan_fn = plan_fn
        self.yaw = yaw
        self._e = heading(yaw)
        self.result: Plan | None = None

    def start(self, state: RobotState) -> PushTiming:
        plan = self.result = self.plan_fn(state)
        v = plan.liftoff
        return PushTiming(duration=plan.t_stance, vx=float(v[0]), vz=float(v[1]),
                          flight_time=plan.t_rise + plan.t_fall)

    def command(self, state: RobotState, since: float) -> PushCommand:
        Fx, Fz = self.result.force_at(since)
        e = self._e
        F = np.array([Fx * e[0], Fx * e[1], Fz])
        err = state.q[BASE_RPY] - np.array([0.0, 0.0, self.yaw])
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        M = -self.attitude.kp * err - self.attitude.kd * state.omega
        return PushCommand(F, M)


@dataclass
class Execution:
    """An executed jump: landing_x m (module docstring), apex_z m, rest_x m (base x at the end,
    from the push start), t_push / t_touchdown s, finished (settled before max_time), the plan,
    liftoff (4,): the base's x (from the push start), z (m), vx, vz (m/s) when the push ended,
    and the trajectory at log_hz: t (n,) s, base (n, 6) x, y, z, roll, pitch, yaw, contact (n, 4),
    phase (n,) names."""

    landing_x: float
    apex_z: float
    rest_x: float
    t_push: float
    t_touchdown: float
    finished: bool
    plan: Plan
    liftoff: np.ndarray
    trajectory: dict = field(default_factory=dict)


def execute(robot: str, plan_fn: Callable[[RobotState], Plan], engine: str = "pybullet",
            params: PronkParams | None = None, config: WorldConfig | None = None,
            attitude: AttitudeGains | None = None) -> Execution:
    """Run one planned pronk on ``engine`` (module docstring); raise ``ExecutionError`` if the
    robot never leaves the ground or never lands."""
    params = params or PronkParams()
    config = config or WorldConfig()
    push = PlannedPush(robot, params.yaw, plan_fn, attitude)
    ctrl = PronkController(robot, params, push=push)
    world = make_world(engine, robot, config)
    log = {"t": [], "base": [], "contact": [], "phase": []}

    def on_sample(tick: int, s: RobotState, applied: np.ndarray) -> None:
        log["t"].append(s.t)
        log["base"].append(np.concatenate([s.q[BASE_POS], s.q[BASE_RPY]]))
        log["contact"].append(s.contact.astype(int))
        log["phase"].append(ctrl.phase)

    try:
        finished = run_episode(world, ctrl, ctrl.reset(world), params.max_time, on_sample=on_sample).finished
        end = world.state()
    finally:
        world.close()
    if push.result is None or ctrl.push_start is None:
        raise ExecutionError("the jump ended before its push began")
    if ctrl.touchdown is None:
        what = "did not land within its flight time" if ctrl.airborne else "never left the ground"
        raise ExecutionError(f"no touchdown after the planned push: the robot {what}")
    t0, p0 = ctrl.push_start
    t_td, p_td = ctrl.touchdown
    e = ctrl.heading
    base = np.asarray(log["base"], float)
    t = np.asarray(log["t"], float)
    air = (t >= t0 + ctrl.plan.push_time) & (t <= t_td)
    apex = float(base[air, 2].max()) if air.any() else float(p_td[2])
    return Execution(landing_x=float((p_td - p0) @ e), apex_z=apex,
                     rest_x=float((end.q[BASE_POS] - p0) @ e), t_push=float(t0), t_touchdown=float(t_td),
                     finished=finished, plan=push.result, liftoff=_liftoff(ctrl, p0, e),
                     trajectory={"t": t, "base": base, "contact": np.asarray(log["contact"], int),
                                 "phase": log["phase"]})


def _liftoff(ctrl: PronkController, p0: np.ndarray, e: np.ndarray) -> np.ndarray:
    p, v = ctrl.liftoff
    return np.array([(p - p0) @ e, p[2], v @ e, v[2]])


__all__ = ["AttitudeGains", "Execution", "ExecutionError", "PlannedPush", "execute"]
