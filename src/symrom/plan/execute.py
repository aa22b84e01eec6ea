"""A planned jump executed in simulation, the same way whichever model planned it.

The motion's controller runs unchanged but for its push, which a push policy
(``PlannedPush``) drives: the pronk (``sim.controllers.pronk``, a ``PushPolicy``) or the
froggy (``sim.controllers.froggy``, a ``FroggyPushPolicy``: four feet, then the rear feet
alone):

1. *Crouch and hold*: the controller's own start and crouch.
2. *Plan*: when the push is due, the policy's ``start`` hands the planner the measured
   state and gets a ``Plan`` (one solve; its wall time is the plan's solve time); the
   push then lasts the planned stances' durations (a froggy's ends sooner if its rear feet
   leave the ground first: ``froggy.FEET_OFF``).
3. *Push*: at every tick the policy commands the planned force F(t) (piecewise constant)
   and an attitude PD's moment (``AttitudeGains``: it keeps the trunk level and does not
   change the sum); the controller makes joint torques whose ground force through massless
   legs is that wrench (the pronk's ``push_torque``, the froggy's), as a model's input is
   derived from torques (``data.preprocess``). Closed loop (``Feedback``): every
   ``period`` s of the push (from its first tick) the rest of the push is re-planned from
   the measured state (``plan.replan``) and F(t) and the push's end follow the new schedule.
4. *Flight and landing*: the controller's own. The froggy's follow its push at once, and it
   lands with the legs at the trunk's lower end plumb under their hips
   (``FroggyController(landing="low_plumb")``: with the data's body-fixed targets a froggy
   pivots over its front feet after touchdown, and a long planned jump went over onto its
   nose), and its flight's leg targets turn with the trunk past ``FLIGHT_PITCH`` (a trunk
   pitched further put the front feet's level targets out of the legs' reach: the knees folded,
   and the jump touched down late and long) and are tracked as the trunk turns under them
   (``flight_track``: damped to rest in the trunk's frame, the feet lagged 1-2 cm behind and
   deeper, and a loaded jump touched down early and short); the pronk first holds the legs without ground
   force for ``pronk.release_time`` (20 ms for the Go1), as its own push ends, so that the feet
   leave the ground before its flight's joint PD swings the legs to the landing posture, as in
   its data.

The episode is the one loop every simulated jump runs (``sim.generation.episode``), on the
engine's world with the ``Disturbances`` asked for (``sim.proxy.DisturbedWorld``).

Landing point: the base's x at the first touchdown after the push (the first
physics tick with a foot in contact once the flight has lasted 0.05 s, the
controllers' rule), measured from the base's x at the start of the push, along the
heading (world x). The apex is the largest base height between the end of the
push and that touchdown. Where the robot comes to rest is reported as well
(``rest_x``). Units: m, s, N, N m.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from symrom.names import BASE_POS, BASE_RPY
from symrom.plan.problem import Plan
from symrom.plan.replan import ReplanStats, Schedule
from symrom.sim.controllers.froggy import FLIGHT_PITCH, FroggyController, FroggyParams, FroggyPushTiming
from symrom.sim.controllers.froggy import scaled as froggy_scaled
from symrom.sim.controllers.motion import PushCommand
from symrom.sim.controllers.pronk import PronkController, PronkParams, PushTiming, heading, scales
from symrom.sim.engines.registry import make_world
from symrom.sim.engines.world import RobotState, WorldConfig
from symrom.sim.generation.episode import run_episode
from symrom.sim.proxy import Disturbances, DisturbedWorld

MOTIONS = ("pronk", "froggy")
TILTED = 0.3  # rad: a trunk further than this from level in roll or pitch at the end has fallen over
LYING = 0.6  # a base below this fraction of its standing height at the end lies on the ground


class ExecutionError(RuntimeError):
    """A planned jump that could not be carried out (no flight, no touchdown)."""


@dataclass(frozen=True)
class AttitudeGains:
    """The push's attitude PD on the trunk (moment about the CoM, N m): kp N m/rad on roll,
    pitch and yaw error, kd N m s/rad on the angular velocity; for the Go1, scaled by mass x
    length^2 for other robots (the pronk's ``scales``). Chosen so that the trunk leaves the
    ground as level as in the pronk's own jumps (pitch at lift-off -0.02..0.01 rad in the
    training data; 0.015 rad median with these gains, 0.043 with 60 and 4, on the tuning
    targets), whatever the planner. A froggy push holds the pitch it began with (its crouch's
    nose-down pitch), the roll and the yaw."""

    kp: float = 200.0
    kd: float = 8.0


class Feedback(Protocol):
    """A closed loop on a planned push: ``begin(plan, state)`` once the plan is made at the
    push's first tick; then every ``period`` s ``replan(state, since)`` re-plans the rest of
    the push from the measured state and returns the new ``Schedule``; ``stats`` records each
    re-plan."""

    period: float
    stats: ReplanStats

    def begin(self, plan: Plan, state: RobotState) -> Schedule:
        """The schedule of the plan made at the push's first tick."""

    def replan(self, state: RobotState, since: float) -> Schedule:
        """The rest of the push re-planned from ``state``, ``since`` s after it began."""


class PlannedPush:
    """A motion's push by a plan (module docstring): a pronk ``PushPolicy`` or a froggy
    ``FroggyPushPolicy`` (``motion``). ``plan_fn(state) -> Plan`` is called once, when the
    push is due; then the plan's force F(t) along the heading of ``yaw`` rad, with the
    attitude PD (``AttitudeGains`` for the Go1, scaled to ``robot``) holding the trunk at that
    yaw, level (the pronk) or at the pitch the push began with (the froggy). With
    ``feedback``, F(t) and the push's end follow its re-plans. ``result``: the ``Plan``,
    None until the push began; ``schedule``: the schedule in force (closed loop)."""

    def __init__(self, robot: str, yaw: float, plan_fn: Callable[[RobotState], Plan],
                 attitude: AttitudeGains | None = None, motion: str = "pronk", feedback: Feedback | None = None):
        if motion not in MOTIONS:
            raise ValueError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")
        mass, length = scales(robot)
        a = attitude or AttitudeGains()
        self.attitude = AttitudeGains(a.kp * mass * length ** 2, a.kd * mass * length ** 2)
        self.plan_fn, self.motion, self.feedback = plan_fn, motion, feedback
        self.yaw = yaw
        self._e = heading(yaw)
        self.result: Plan | None = None
        self.schedule: Schedule | None = None
        self._last = -np.inf
        self._pitch = 0.0
        self._four_end: float | None = None  # s: when the froggy's four-foot part ends

    def _timing(self, schedule_end: float, four_end: float | None, plan: Plan):
        if self.motion == "froggy":
            return FroggyPushTiming(four=four_end, rear=schedule_end - four_end)
        v = plan.liftoff
        return PushTiming(duration=schedule_end, vx=float(v[0]), vz=float(v[1]), flight_time=plan.t_rise + plan.t_fall)

    def start(self, state: RobotState):
        plan = self.result = self.plan_fn(state)
        if self.motion == "froggy":
            self._pitch = float(state.q[BASE_RPY][1])
            self._four_end = plan.durations[0]
        if self.feedback is not None:
            self.schedule = self.feedback.begin(plan, state)
        four = plan.durations[0] if self.motion == "froggy" else None
        return self._timing(plan.t_stance, four, plan)

    def command(self, state: RobotState, since: float) -> PushCommand:
        timing = None
        if self.feedback is not None:
            if since - self._last >= self.feedback.period - 1e-9:
                self._last = since
                if since > 0:  # the plan itself was made at this tick
                    sch = self.schedule = self.feedback.replan(state, since)
                    if self.motion == "froggy" and sch.first == 0:
                        self._four_end = sch.ends[0]
                    timing = self._timing(sch.end, self._four_end, self.result)
            Fx, Fz = self.schedule.force_at(since)
        else:
            Fx, Fz = self.result.force_at(since)
        e = self._e
        F = np.array([Fx * e[0], Fx * e[1], Fz])
        err = state.q[BASE_RPY] - np.array([0.0, self._pitch, self.yaw])
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        M = -self.attitude.kp * err - self.attitude.kd * state.omega
        return PushCommand(F, M, timing)


@dataclass
class Execution:
    """An executed jump: landing_x m (module docstring), apex_z m, rest_x m (base x at the end,
    from the push start), t_push / t_touchdown s, finished (settled before max_time), the plan,
    liftoff (4,): the base's x (from the push start), z (m), vx, vz (m/s) when the push ended,
    the trajectory at log_hz: t (n,) s, base (n, 6) x, y, z, roll, pitch, yaw, contact (n, 4),
    phase (n,) names; motion; disturbances; replans: each re-plan's record (closed loop), else
    None; push_s: how long the executed push lasted, s. ``upright``: whether the robot ended
    on its feet (``TILTED``, ``LYING``)."""

    landing_x: float
    apex_z: float
    rest_x: float
    t_push: float
    t_touchdown: float
    finished: bool
    plan: Plan
    liftoff: np.ndarray
    trajectory: dict = field(default_factory=dict)
    motion: str = "pronk"
    disturbances: Disturbances = field(default_factory=Disturbances)
    replans: ReplanStats | None = None
    push_s: float = float("nan")

    @property
    def rest(self) -> dict[str, float]:
        """The base at the end of the run: height z m, roll and pitch rad."""
        z, roll, pitch = (float(v) for v in self.trajectory["base"][-1, [2, 3, 4]])
        return {"z": z, "roll": roll, "pitch": pitch}

    @property
    def upright(self) -> bool:
        """Whether the robot ended on its feet: roll and pitch within ``TILTED`` rad of level
        and the base at least ``LYING`` times its height when the run began (standing). An
        upside-down trunk reads roll pi and pitch near 0, so the pitch alone does not tell."""
        r = self.rest
        return (abs(r["roll"]) <= TILTED and abs(r["pitch"]) <= TILTED
                and r["z"] >= LYING * float(self.trajectory["base"][0, 2]))


def execute(robot: str, plan_fn: Callable[[RobotState], Plan], engine: str = "pybullet",
            params: PronkParams | FroggyParams | None = None, config: WorldConfig | None = None,
            attitude: AttitudeGains | None = None, motion: str = "pronk", feedback: Feedback | None = None,
            disturbances: Disturbances | None = None) -> Execution:
    """Run one planned jump of ``motion`` (``pronk`` or ``froggy``) on ``engine`` (module
    docstring), in a world with ``disturbances``, closed loop with ``feedback``; raise
    ``ExecutionError`` if the robot never leaves the ground or never lands."""
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")
    config = config or WorldConfig()
    disturbances = disturbances or Disturbances()
    if motion == "pronk":
        params = params or PronkParams()
        yaw = params.yaw
    else:
        params = params or froggy_scaled(FroggyParams(), robot)
        yaw = 0.0
    push = PlannedPush(robot, yaw, plan_fn, attitude, motion, feedback)
    ctrl = (PronkController(robot, params, push=push) if motion == "pronk"
            else FroggyController(robot, params, push=push, landing="low_plumb",
                                   flight_pitch=FLIGHT_PITCH, flight_track=True))
    world = make_world(engine, robot, config)
    if not disturbances.none:
        world = DisturbedWorld(world, disturbances)
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
    e = heading(yaw)
    base = np.asarray(log["base"], float)
    t = np.asarray(log["t"], float)
    if motion == "pronk":
        push_s = ctrl.plan.push_time
    else:
        tm = ctrl.timing
        push_s = tm.four + tm.rear
    air = (t >= t0 + push_s) & (t <= t_td)
    apex = float(base[air, 2].max()) if air.any() else float(p_td[2])
    p_lo, v_lo = ctrl.liftoff
    liftoff = np.array([(p_lo - p0) @ e, p_lo[2], v_lo @ e, v_lo[2]])
    return Execution(landing_x=float((p_td - p0) @ e), apex_z=apex,
                     rest_x=float((end.q[BASE_POS] - p0) @ e), t_push=float(t0), t_touchdown=float(t_td),
                     finished=finished, plan=push.result, liftoff=liftoff,
                     trajectory={"t": t, "base": base, "contact": np.asarray(log["contact"], int),
                                 "phase": log["phase"]},
                     motion=motion, disturbances=disturbances,
                     replans=feedback.stats if feedback is not None else None, push_s=float(push_s))


__all__ = ["LYING", "MOTIONS", "TILTED", "AttitudeGains", "Execution", "ExecutionError", "Feedback", "PlannedPush",
           "execute"]
