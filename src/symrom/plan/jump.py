"""A jump to a target: build a planner for a model, plan from the measured crouch, execute, record.

    planner = make_planner("learned", "go1", model=load_model("model.json"))
    result = jump(planner, target_x=0.3)                  # plan + simulate (PyBullet)
    write_landing(out_dir, result)                        # landing.json (+ trajectory.json)

Planners (``PLANNERS``): ``learned`` (a fitted ``HybridModel``), ``point-mass``
(Newton's law on the description's mass) and ``aslip`` (fitted aSLIP
parameters, ``symrom aslip``'s params.json). All plan the same problem
(``plan.problem``) and are executed the same way (``plan.execute``).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from symrom.atomic import atomic_dir
from symrom.baselines.aslip import ASlipParams
from symrom.model.hybrid import HybridModel
from symrom.names import BASE_POS, JOINTS
from symrom.plan.dynamics import ASlipDynamics, LearnedDynamics, PlanDynamics, PointMass
from symrom.plan.execute import Execution, execute
from symrom.plan.guards import HeightGuards, LearnedGuards
from symrom.plan.inputs import force_input_map, torque_map
from symrom.plan.problem import JumpPlanner, Plan, PlanConfig, PlanError
from symrom.robots import get_robot, leg_kinematics, robot_key
from symrom.robots.stance import start_pose
from symrom.sim.controllers.pronk import PronkParams, scales
from symrom.sim.engines.world import RobotState

PLANNERS = ("learned", "point-mass", "aslip")
# How far the robot a jump is for may be from the one a learned model was trained on: its
# mass and leg length, as fractions of the model's robot's; its knees must bend the same way.
MODEL_ROBOT_TOL = {"mass": 0.10, "leg length": 0.10}
GUARDS = ("height", "learned")
REACH_TOL = 5e-3  # m: a plan landing farther than this from its target did not reach it
LANDING_FORMAT = 2  # 2: apex_rule, apex_floor
TRAJECTORY_FORMAT = 1
INFEASIBLE = "Infeasible_Problem_Detected"  # IPOPT's status of constraints no plan meets
# how the apex was planned (landing.json's apex_rule): a target, held at or above the motion's
# nominal apex, or, where no plan reaches that within the torque limits, held at or above
# REACH_SHARE of the highest apex gain over the lift-off height the model reaches
APEX_RULES = ("target", "at least nominal", "at least reachable")
REACH_SHARE = 0.8


@dataclass
class RobotPlanner:
    """A built planner for ``robot``: kind (``PLANNERS``), its guards (``GUARDS``), the NLP, and the motion's heights: the
    crouch (m), lift-off (the pronk's take-off height, m) and nominal apex (m)."""

    kind: str
    robot: str
    guards: str
    nlp: JumpPlanner
    crouch_height: float
    liftoff_height: float
    nominal_apex: float

    @property
    def dyn(self) -> PlanDynamics:
        return self.nlp.dyn

    def plan(self, q: np.ndarray, dq: np.ndarray, target_x: float, target_z: float | None = None,
             warm: bool = True, min_apex: float | None = None) -> Plan:
        """Plan from the robot's configuration q (18,) and velocity dq (18,) at the start of the
        push; for point-mass and aSLIP the state's x is measured from the start (their laws do
        not depend on where the jump is). Without ``target_z`` the apex is held at or above
        ``min_apex`` m (default: the nominal apex)."""
        s0 = self.dyn.initial_state(q, dq)
        if self.kind != "learned":
            s0[0] = 0.0
        return self.nlp.solve(s0, target_x, self.liftoff_height, apex=target_z,
                              min_apex=None if target_z is not None else (min_apex or self.nominal_apex), warm=warm)


def pronk_params(robot: str) -> PronkParams:
    """The pronk's nominal jump for ``robot`` (heights scaled by its leg length), its yaw 0."""
    length = scales(robot)[1]
    p = PronkParams()
    return PronkParams(distance=p.distance * length, apex_height=p.apex_height * length,
                       crouch_height=p.crouch_height * length, takeoff_height=p.takeoff_height * length)


def make_planner(kind: str, robot: str, model: HybridModel | None = None, aslip: ASlipParams | None = None,
                 config: PlanConfig | None = None, guards: str = "height") -> RobotPlanner:
    """Build the NLP of planner ``kind`` for ``robot`` once; ``model`` for ``learned``,
    ``aslip`` for ``aslip``; ``guards`` (``GUARDS``): ``height`` (``HeightGuards``) or, for the
    learned planner, ``learned`` (the model's own switches, ``LearnedGuards``)."""
    if kind not in PLANNERS:
        raise ValueError(f"unknown planner {kind!r}; choose from {', '.join(PLANNERS)}")
    if guards not in GUARDS:
        raise ValueError(f"unknown guards {guards!r}; choose from {', '.join(GUARDS)}")
    if guards == "learned" and kind != "learned":
        raise ValueError(f"learned guards belong to a learned model; the {kind} planner uses height guards")
    desc, params = get_robot(robot), pronk_params(robot)
    mass = desc.mass
    q_crouch = start_pose(robot, params.crouch_height)
    if kind == "learned":
        if model is None:
            raise ValueError("the learned planner needs a model (model.json)")
        trained_on = model.info.get("robot")
        if trained_on is not None and robot_key(trained_on) != robot_key(robot):
            check_model_robot(trained_on, robot)
        dyn: PlanDynamics = LearnedDynamics(model, force_input_map(model, robot, q_crouch))
    elif kind == "point-mass":
        dyn = PointMass(mass)
    else:
        if aslip is None:
            raise ValueError("the aslip planner needs fitted aSLIP parameters (params.json of symrom aslip)")
        feet = leg_kinematics(robot).foot_positions(q_crouch[None, JOINTS])[0]  # base frame, level
        pivot = feet.mean(axis=0)
        dyn = ASlipDynamics(aslip.m, params=aslip, pivot=(float(pivot[0]), float(pivot[2] + q_crouch[BASE_POS][2])))
    cfg = config or PlanConfig(fz_max=PlanConfig.fz_max * mass / get_robot("go1").mass)
    rule = LearnedGuards.of(model) if guards == "learned" else HeightGuards()
    # the legs' torques at the start and at the end of the push (crouch, take-off height)
    limits = torque_map(robot, [q_crouch, start_pose(robot, params.takeoff_height)], desc.torque_limit)
    return RobotPlanner(kind, robot, guards, JumpPlanner(dyn, mass, cfg, rule, limits), params.crouch_height, params.takeoff_height,
                        params.apex_height)


def check_model_robot(trained_on: str, robot: str) -> None:
    """Refuse, in one line, to plan for ``robot`` with a model trained on another robot
    ``trained_on`` unless both are the same build: knees bending the same way on every leg
    and mass and leg length within ``MODEL_ROBOT_TOL`` of the model's robot's (another model of
    the same robot, e.g. a Menagerie Go1 for a model of symrom's Go1). The jump is planned
    with the model's dynamics and the executing robot's description (its legs map the force
    to the model's input; it is the robot simulated)."""
    from symrom.robots.description import RobotDescriptionError
    from symrom.robots.stance import leg_length

    head = f"the model was trained on {trained_on!r}, the jump is for {robot!r}"
    try:
        a, b = get_robot(trained_on), get_robot(robot)
    except (RobotDescriptionError, OSError) as e:
        raise ValueError(f"{head}, and the model's robot cannot be read to compare them ({e})") from None
    bend_a, bend_b = np.sign(np.mean(a.knee_range, axis=0)), np.sign(np.mean(b.knee_range, axis=0))
    if not np.array_equal(bend_a, bend_b):
        raise ValueError(f"{head}: their knees bend different ways (knee ranges {a.knee_range.T.round(2).tolist()} "
                         f"and {b.knee_range.T.round(2).tolist()} rad, FR FL RR RL)")
    for what, x, y, unit in (("mass", a.mass, b.mass, "kg"),
                             ("leg length", leg_length(trained_on), leg_length(robot), "m")):
        if abs(y / x - 1.0) > MODEL_ROBOT_TOL[what]:
            raise ValueError(f"{head}: its {what} {y:.3g} {unit} is {100 * (y / x - 1):+.0f} % of the model's robot's "
                             f"{x:.3g} {unit} (at most {100 * MODEL_ROBOT_TOL[what]:.0f} %)")


def read_aslip_params(path: str | os.PathLike) -> ASlipParams:
    """The aSLIP parameters in ``path`` (params.json of ``symrom aslip``); one clear error per bad key."""
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not a readable aSLIP params.json ({e})") from None
    missing = [k for k in ("k_s", "l_0", "m") if k not in d]
    if missing:
        raise ValueError(f"{path}: key {missing[0]!r} missing (an aSLIP params.json has k_s, l_0, m)")
    try:
        return ASlipParams(float(d["k_s"]), float(d["l_0"]), float(d["m"]))
    except (TypeError, ValueError) as e:
        raise ValueError(f"{path}: {e}") from None


@dataclass
class JumpResult:
    """One planned and executed jump: the planner's kind, the target (m), the execution."""

    planner: str
    robot: str
    engine: str
    guards: str
    target_x: float
    target_z: float | None
    execution: Execution
    apex_rule: str = "target"
    apex_floor: float | None = None

    @property
    def error_x(self) -> float:
        return self.execution.landing_x - self.target_x

    @property
    def reachable(self) -> bool:
        """Whether the plan itself lands on the target (within ``REACH_TOL``): a target out of
        the model's reach under the force, friction and stance bounds gets the closest plan."""
        return abs(self.execution.plan.landing_x - self.target_x) <= REACH_TOL

    def landing(self) -> dict:
        """landing.json's content (``LANDING_FORMAT``)."""
        ex, plan = self.execution, self.execution.plan
        return {"format_version": LANDING_FORMAT, "planner": self.planner, "guards": self.guards,
                "robot": self.robot, "engine": self.engine, "target_x": self.target_x, "target_z": self.target_z,
                "apex_rule": self.apex_rule, "apex_floor": self.apex_floor,
                "landing_x": ex.landing_x, "error_x": self.error_x,
                "planned_landing_x": plan.landing_x, "target_reachable": self.reachable, "apex_z": ex.apex_z,
                "solve_time_s": plan.solve_time_s, "rest_x": ex.rest_x,
                "liftoff": dict(zip(("x", "z", "vx", "vz"), ex.liftoff.tolist())), "t_push_s": ex.t_push,
                "t_touchdown_s": ex.t_touchdown, "settled": ex.finished,
                "definition": "landing_x: base x at the first touchdown after the push, from the base x at the "
                              "start of the push (m); apex_z: largest base height between lift-off and "
                              "touchdown (m); rest_x: base x at the end of the run, from the same start (m)",
                "plan": plan.to_dict()}


def plan_jump(planner: RobotPlanner, q: np.ndarray, dq: np.ndarray, target_x: float, target_z: float | None = None,
              warm: bool = True) -> tuple[Plan, str, float | None]:
    """The plan from configuration q (18,) and velocity dq (18,) to ``target_x`` m, the rule its
    apex was planned by (``APEX_RULES``) and the least apex it held (m; None for a target):
    ``target_z`` m if given, else at or above the nominal apex; where no plan holds that within
    the torque limits (IPOPT finds the problem infeasible: a robot whose motors are weak for its
    size, whose own pronks peak below it), at or above ``REACH_SHARE`` of the highest apex gain
    over the lift-off height the model reaches (a plan aimed at the nominal apex finds it),
    which leaves the push some torque to spare."""
    if target_z is not None:
        return planner.plan(q, dq, target_x, target_z, warm=warm), "target", None
    plan = planner.plan(q, dq, target_x, None, warm=warm)
    if plan.success or plan.status != INFEASIBLE:
        return plan, "at least nominal", planner.nominal_apex
    top = planner.plan(q, dq, target_x, planner.nominal_apex, warm=warm)
    if not top.success:
        return top, "at least reachable", None
    floor = planner.liftoff_height + REACH_SHARE * (top.apex_z - planner.liftoff_height)
    return planner.plan(q, dq, target_x, None, warm=warm, min_apex=floor), "at least reachable", floor


def jump(planner: RobotPlanner, target_x: float, target_z: float | None = None, engine: str = "pybullet",
         warm: bool = True) -> JumpResult:
    """Plan (from the measured crouch: ``plan_jump``) and execute one jump ``target_x`` m forward,
    with apex ``target_z`` m if given, else at or above the pronk's nominal apex, or what the
    model reaches of it (``JumpResult.apex_rule``, ``apex_floor``); raise ``PlanError`` if the
    plan fails."""
    if not (np.isfinite(target_x) and target_x >= 0):
        raise ValueError(f"--target-x must be a non-negative distance in m, got {target_x}")
    if target_z is not None and not (np.isfinite(target_z) and target_z > planner.liftoff_height):
        raise ValueError(f"--target-z must be above the lift-off height {planner.liftoff_height:.3f} m, got {target_z}")

    rule: list = ["target", None]

    def plan_fn(state: RobotState) -> Plan:
        plan, rule[0], rule[1] = plan_jump(planner, state.q, state.dq, target_x, target_z, warm=warm)
        if not plan.success:
            raise PlanError(f"the {planner.kind} plan to x = {target_x} m did not converge (IPOPT: {plan.status})")
        return plan

    params = pronk_params(planner.robot)
    params.distance = target_x
    ex = execute(planner.robot, plan_fn, engine, params)
    return JumpResult(planner.kind, planner.robot, engine, planner.guards, float(target_x), target_z, ex, *rule)


def write_landing(out: str | os.PathLike, result: JumpResult, trajectory: bool = True, force: bool = False) -> None:
    """Write ``landing.json`` (and ``trajectory.json``: t s, base x y z roll pitch yaw, contact,
    phase at 500 Hz) into folder ``out``, atomically."""
    with atomic_dir(out, force) as tmp:
        (tmp / "landing.json").write_text(json.dumps(result.landing(), indent=1, allow_nan=False) + "\n")
        if trajectory:
            tr = result.execution.trajectory
            doc = {"format_version": TRAJECTORY_FORMAT, "columns": ["x", "y", "z", "roll", "pitch", "yaw"],
                   "units": "s, m, rad", "t": np.asarray(tr["t"]).tolist(), "base": np.asarray(tr["base"]).tolist(),
                   "contact": np.asarray(tr["contact"]).tolist(), "phase": list(tr["phase"])}
            (tmp / "trajectory.json").write_text(json.dumps(doc, allow_nan=False) + "\n")


__all__ = ["APEX_RULES", "JumpResult", "MODEL_ROBOT_TOL", "PLANNERS", "REACH_SHARE", "RobotPlanner", "check_model_robot", "jump",
           "make_planner", "plan_jump", "pronk_params", "read_aslip_params",
           "write_landing"]
