"""A planned jump executed in simulation, the same way whichever model planned it.

The pronk (``sim.pronk``) runs unchanged except for the push:

1. *Crouch and hold*: the pronk's standing start and MPC crouch.
2. *Plan*: when the push is due, the planner is handed the measured state and
   returns a ``Plan`` (one solve; its wall time is the plan's solve time).
3. *Push*, for the planned stance duration: joint torques tau = -J^T R^T f
   (leg Jacobians J at the measured joints) plus the pronk's stance joint PD
   (hip abduction held, legs damped). The foot forces f_k are the least-norm
   ones that sum to the planned force F(t) (piecewise constant) less the force
   the PD's torques stand for, and whose moment about the CoM is an attitude
   PD's (``AttitudeGains``: it keeps the trunk level and does not change the
   sum). A model's input is the ground force derived from all joint torques
   through massless legs (``data.preprocess``), so the torques applied are
   those whose derived force is the plan; no leg-weight torque is added.
4. *Flight and landing*: the pronk's flight joint PD (landing posture at the
   take-off leg length) and its MPC landing, from the first touchdown.

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

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_LEGS
from symrom.plan.problem import Plan
from symrom.robots.compiled import legs_one
from symrom.sim.compiled import pronk_stance_torque as stance_torque
from symrom.sim.engine import make_world
from symrom.sim.pronk import JumpPlan, PronkController, PronkParams
from symrom.sim.world import RobotState, WorldConfig


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


def distribute(F: np.ndarray, M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Least-norm foot forces (4, 3) N summing to F (3,) N with moment M (3,) N m about the
    point the lever arms r (4, 3) m start from: the minimum-norm solution of
    [I ... I; [r_k]x ...] f = [F; M]."""
    A = np.zeros((6, 3 * N_LEGS))
    for k in range(N_LEGS):
        x, y, z = r[k]
        A[:3, 3 * k:3 * k + 3] = np.eye(3)
        A[3:, 3 * k:3 * k + 3] = [[0, -z, y], [z, 0, -x], [-y, x, 0]]
    return np.linalg.lstsq(A, np.concatenate([F, M]), rcond=None)[0].reshape(N_LEGS, 3)


class PlannedPronk(PronkController):
    """The pronk with a planned push (module docstring); ``plan_fn(state) -> Plan`` is called once,
    when the push is due. After the jump: ``result`` (the ``Plan``), ``push_start`` (t s and base
    position (3,) m when the push began), ``liftoff`` (base position (3,) m and velocity (3,) m/s
    when the planned push ended), ``touchdown`` (t s and base position at the first touchdown);
    each None until it happened."""

    def __init__(self, robot: str, params: PronkParams, plan_fn: Callable[[RobotState], Plan],
                 attitude: AttitudeGains | None = None):
        super().__init__(robot, params)
        from symrom.sim.pronk import scales

        mass, length = scales(robot)
        a = attitude or AttitudeGains()
        self.attitude = AttitudeGains(a.kp * mass * length ** 2, a.kd * mass * length ** 2)
        self.plan_fn = plan_fn
        self.result: Plan | None = None
        self.push_start: tuple[float, np.ndarray] | None = None
        self.touchdown: tuple[float, np.ndarray] | None = None
        self.airborne = False  # no foot on the ground at some tick of the flight phase
        self.liftoff: tuple[np.ndarray, np.ndarray] | None = None
        self._tau_g0 = np.zeros(N_JOINTS)

    def _start_push(self, state: RobotState) -> None:
        plan = self.result = self.plan_fn(state)
        self.push_start = (state.t, state.q[BASE_POS].copy())
        v = plan.liftoff
        self.phase = "push"
        # the pronk's phase clock now runs on the plan: push for t_stance, flight timeout after
        self.plan = JumpPlan(t_push=state.t, push_time=plan.t_stance, vx=float(v[0]), vz=float(v[1]),
                             flight_time=plan.t_rise + plan.t_fall)

    def torque(self, state: RobotState) -> np.ndarray:
        if self.result is None and self._x0 is not None and state.t >= self.plan.t_push:
            self._start_push(state)
        was_flight = self.phase == "flight"
        if self.phase != "push" or state.t >= self.plan.t_push + self.plan.push_time:
            if self.phase == "push" and self.liftoff is None:  # the push ends at this tick
                self.liftoff = (state.q[BASE_POS].copy(), state.dq[BASE_POS].copy())
            if was_flight and not state.contact.any():
                self.airborne = True
            tau = super().torque(state)
            # a touchdown is a foot meeting the ground after the robot flew: the pronk's flight also
            # ends on its time-out or on a foot that never left the ground, which are no landing
            if (was_flight and self.phase == "land" and self.touchdown is None and self.airborne
                    and state.contact.any()):
                self.touchdown = (state.t, state.q[BASE_POS].copy())
            return tau
        return self._push_torque(state)

    def _push_torque(self, state: RobotState) -> np.ndarray:
        Fx, Fz = self.result.force_at(state.t - self.plan.t_push)
        e = self._e
        F = np.array([Fx * e[0], Fx * e[1], Fz])
        err = state.q[BASE_RPY] - np.array([0.0, 0.0, self.params.yaw])
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        M = -self.attitude.kp * err - self.attitude.kd * state.omega
        qj, dqj = state.q[JOINTS], state.dq[JOINTS]
        p_b, J = self._p_b, self._J
        legs_one(qj, *self._chains, p_b, J)
        # the ground force the joint PD's torques stand for (massless legs, as the data derive it),
        # made up for by the feed-forward so that the torques' derived force is the plan
        kp, kd, q_stand = self._posture
        tau_pd = (kp * (q_stand - qj) - kd * dqj).reshape(N_LEGS, 3)
        G = sum(state.R @ -np.linalg.solve(J[k].T, tau_pd[k]) for k in range(N_LEGS))
        p_com = state.q[BASE_POS] + state.R @ self.body.com_base
        f = distribute(F - G, M, state.foot_pos - p_com)
        f_base = -(f @ state.R)
        tau = np.empty(N_JOINTS)
        stance_torque(J, f_base, self._tau_g0, False, p_b, p_b, state.contact, p_b, 0.0, 0.0, 0.0,
                      self._posture, qj, dqj, self.torque_limit, tau)
        return tau


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
    ctrl = PlannedPronk(robot, params, plan_fn, attitude)
    world = make_world(engine, robot, config)
    log = {"t": [], "base": [], "contact": [], "phase": []}
    finished = False
    try:
        world.reset(ctrl.reset(world))
        for tick in range(int(round(params.max_time * config.physics_hz)) + 1):
            s = world.state()
            if ctrl.done(s):
                finished = True
                break
            tau = ctrl.torque(s)
            if tick % config.log_every == 0:
                log["t"].append(s.t)
                log["base"].append(np.concatenate([s.q[BASE_POS], s.q[BASE_RPY]]))
                log["contact"].append(s.contact.astype(int))
                log["phase"].append(ctrl.phase)
            world.step(tau)
        end = world.state()
    finally:
        world.close()
    if ctrl.result is None or ctrl.push_start is None:
        raise ExecutionError("the jump ended before its push began")
    if ctrl.touchdown is None:
        what = "did not land within its flight time" if ctrl.airborne else "never left the ground"
        raise ExecutionError(f"no touchdown after the planned push: the robot {what}")
    t0, p0 = ctrl.push_start
    t_td, p_td = ctrl.touchdown
    e = ctrl._e
    base = np.asarray(log["base"], float)
    t = np.asarray(log["t"], float)
    air = (t >= t0 + ctrl.plan.push_time) & (t <= t_td)
    apex = float(base[air, 2].max()) if air.any() else float(p_td[2])
    return Execution(landing_x=float((p_td - p0) @ e), apex_z=apex,
                     rest_x=float((end.q[BASE_POS] - p0) @ e), t_push=float(t0), t_touchdown=float(t_td),
                     finished=finished, plan=ctrl.result, liftoff=_liftoff(ctrl, p0, e),
                     trajectory={"t": t, "base": base, "contact": np.asarray(log["contact"], int),
                                 "phase": log["phase"]})


def _liftoff(ctrl: PlannedPronk, p0: np.ndarray, e: np.ndarray) -> np.ndarray:
    p, v = ctrl.liftoff
    return np.array([(p - p0) @ e, p[2], v @ e, v[2]])


__all__ = ["AttitudeGains", "Execution", "ExecutionError", "PlannedPronk", "distribute", "execute"]
