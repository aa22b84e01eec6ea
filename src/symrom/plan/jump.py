"""A jump to a target: build a planner for a model, know its reach, plan from the measured crouch,
execute (open or closed loop), record.

    planner = make_planner("learned", "go1", model=load_model("model.json"))
    result = jump(planner, target_x=0.3)                  # plan + simulate (PyBullet)
    result = jump(planner, 0.3, control="mpc", engine="mujoco",
                  disturbances=Disturbances(payload=2.6)) # closed loop, a load on the base
    write_landing(out_dir, result)                        # landing.json (+ trajectory.json)

Planners (``PLANNERS``): ``learned`` (a fitted ``HybridModel``), ``point-mass``
(Newton's law on the description's mass) and ``aslip`` (fitted aSLIP
parameters, ``symrom aslip``'s params.json). All plan the same problem
(``plan.problem``) and are executed the same way (``plan.execute``). Motions
(``MotionPlan``): the pronk (one stance) and the froggy jump (four feet, then the rear feet
alone); a learned model plans the motion of its training data.

Reach (``RobotPlanner.reach``): from the motion's crouch at rest, what the model can do under
the problem's force, friction, torque and stance bounds (``JumpPlanner.reach``), within what
its training jumps did (the model's provenance, ``DataRecord.envelope``; ``data.envelope``). A target outside
it is refused (``OutOfReach``) unless the closest reachable jump is asked for.

Controls (``CONTROLS``): ``plan``, the push planned once at its start (open loop); ``mpc``,
re-planned from the measured state every ``1 / replan_hz`` s of the push (``plan.replan``).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from symrom.atomic import atomic_dir
from symrom.baselines.aslip import ASlipParams
from symrom.model.hybrid import HybridModel
from symrom.names import BASE_POS, BASE_RPY, FLIGHT_PHASE, JOINTS, PARTIAL_PHASE, STANCE_PHASE
from symrom.plan.bias import fit_flight_bias
from symrom.plan.dynamics import ASlipDynamics, LearnedDynamics, PlanDynamics, PlanModelError, PointMass
from symrom.plan.execute import LYING, MOTIONS, TILTED, Execution, execute
from symrom.plan.guards import HeightGuards, LearnedGuards
from symrom.plan.inputs import ALL_LEGS, force_input_map, holds_pitch, pitch_moment_map, torque_map
from symrom.plan.problem import FlightBias, JumpPlanner, Plan, PlanConfig, PlanError, Release, Stance
from symrom.plan.replan import Replanner, ReplanStats, Schedule, check_disturbance_gain
from symrom.robots import get_robot, leg_kinematics, robot_key
from symrom.robots.stance import start_pose
from symrom.sim.controllers.froggy import REAR, FroggyParams, crouch_pose
from symrom.sim.controllers.froggy import scaled as froggy_scaled
from symrom.sim.controllers.froggy import scales as froggy_scales
from symrom.sim.controllers.pronk import PronkParams, scales
from symrom.sim.engines.world import RobotState
from symrom.sim.proxy import Disturbances

PLANNERS = ("learned", "point-mass", "aslip")
# How far the robot a jump is for may be from the one a learned model was trained on: its
# mass and leg length, as fractions of the model's robot's; its knees must bend the same way.
MODEL_ROBOT_TOL = {"mass": 0.10, "leg length": 0.10}
GUARDS = ("height", "learned")
CONTROLS = ("plan", "mpc")
REACH_TOL = 5e-3  # m: a plan landing farther than this from its target did not reach it
LANDING_FORMAT = 6  # 2: apex_rule, apex_floor; 3: rest, upright; 4: heights; 5: release; 6: flight_bias, disturbance
TRAJECTORY_FORMAT = 2
INFEASIBLE = "Infeasible_Problem_Detected"  # IPOPT's status of constraints no plan meets
# how the apex was planned (landing.json's apex_rule): a target, held at or above the motion's
# nominal apex, or, where no plan reaches that within the torque limits, held at or above
# REACH_SHARE of the highest apex gain over the lift-off height the model reaches
APEX_RULES = ("target", "at least nominal", "at least reachable")
REACH_SHARE = 0.8
REPLAN_HZ = 100.0  # Hz: the closed loop's re-planning rate

# The A1's froggy jump as its data show it (``symrom generate --robot a1 --motion froggy``, 27
# PyBullet training jumps, medians): base height at lift-off and at touchdown (it lands nose
# down, lower than it left), apex; lengths scale with the leg length for other robots.
FROGGY_HEIGHTS = {"liftoff": 0.325, "touchdown": 0.29, "apex": 0.37}


class OutOfReach(ValueError):
    """A target outside the planner's reach (``Reach``); ``reach``: the reach it was checked
    against."""

    def __init__(self, message: str, reach: JumpReach):
        super().__init__(message)
        self.reach = reach


@dataclass(frozen=True)
class MotionPlan:
    """What a motion's jump is planned with: its stances in turn (``problem.Stance``), the
    crouch the push starts from (q (18,), at rest), the base heights at lift-off and
    touchdown and the nominal apex (m), the yaw of the jump (rad) and the controller's
    parameters the jump runs with."""

    motion: str
    stances: tuple[Stance, ...]
    q_crouch: np.ndarray
    liftoff_height: float
    touchdown_height: float
    nominal_apex: float
    params: object


def pronk_params(robot: str) -> PronkParams:
    """The pronk's nominal jump for ``robot`` (heights scaled by its leg length), its yaw 0."""
    length = scales(robot)[1]
    p = PronkParams()
    return PronkParams(distance=p.distance * length, apex_height=p.apex_height * length,
                       crouch_height=p.crouch_height * length, takeoff_height=p.takeoff_height * length)


def motion_plan(motion: str, robot: str, config: PlanConfig) -> MotionPlan:
    """The ``MotionPlan`` of ``motion`` for ``robot``: the pronk (one ``contact`` stance of
    ``config``'s knots and bounds, its take-off height for lift-off and touchdown, its nominal
    apex) or the froggy jump (``contact`` then ``partial`` on the rear feet, 3 force intervals
    each, 0.04-0.14 s and 0.03-0.12 s for the A1, times scaled with the square root of the leg
    length; heights ``FROGGY_HEIGHTS`` scaled with it)."""
    if motion == "pronk":
        p = pronk_params(robot)
        return MotionPlan("pronk", (Stance(STANCE_PHASE, config.knots, config.stance_min, config.stance_max),),
                          start_pose(robot, p.crouch_height), p.takeoff_height, p.takeoff_height, p.apex_height, p)
    if motion == "froggy":
        p = froggy_scaled(FroggyParams(), robot)
        length = froggy_scales(robot)[1]
        root = float(np.sqrt(length))
        h = {k: v * length for k, v in FROGGY_HEIGHTS.items()}
        return MotionPlan("froggy", (Stance(STANCE_PHASE, 3, 0.04 * root, 0.14 * root),
                                     Stance(PARTIAL_PHASE, 3, 0.03 * root, 0.12 * root)),
                          crouch_pose(robot, p), h["liftoff"], h["touchdown"], h["apex"], p)
    raise ValueError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")


@dataclass(frozen=True)
class JumpReach:
    """Where a planner can land from the motion's crouch (m): forward distance x_min..x_max
    and apex z_min..z_max, what the model's bounds allow (``model``: ``problem.Reach``) within
    what the training jumps did (``data``: the envelope's travel and apex ranges, None without
    one); ``apex``: the apex the x range was found for (the reachable apex nearest a target
    apex, or None: at or above the nominal apex)."""

    x_min: float
    x_max: float
    z_min: float
    z_max: float
    model: tuple[float, float, float, float]
    data: tuple[float, float, float, float] | None
    apex: float | None

    def holds(self, x: float, z: float | None) -> bool:
        tol = REACH_TOL
        ok = self.x_min - tol <= x <= self.x_max + tol
        return ok and (z is None or self.z_min - tol <= z <= self.z_max + tol)

    def describe(self) -> str:
        """One clause naming the reach and where it comes from."""
        mx = self.model
        apex = f"at an apex of {self.apex:.3f} m" if self.apex is not None else "with the nominal apex or higher"
        s = (f"{self.x_min:.3f}-{self.x_max:.3f} m forward {apex}, apex {self.z_min:.3f}-{self.z_max:.3f} m "
             f"(the model's force, friction, torque and stance bounds allow x {mx[0]:.3f}-{mx[1]:.3f} m, apex "
             f"{mx[2]:.3f}-{mx[3]:.3f} m")
        if self.data is not None:
            d = self.data
            s += f"; its training jumps went {d[0]:.3f}-{d[1]:.3f} m forward, apex {d[2]:.3f}-{d[3]:.3f} m)"
        else:
            s += "; the model records no training jumps' envelope)"
        return s

    def to_dict(self) -> dict:
        return {"x_m": [self.x_min, self.x_max], "z_m": [self.z_min, self.z_max], "apex_for_x_m": self.apex,
                "model_bounds": {"x_m": list(self.model[:2]), "z_m": list(self.model[2:])},
                "training_data": None if self.data is None
                else {"x_m": list(self.data[:2]), "z_m": list(self.data[2:])}}


@dataclass
class RobotPlanner:
    """A built planner for ``robot``: kind (``PLANNERS``), its guards (``GUARDS``), the NLP, and the motion
    (``MotionPlan``): the crouch (m), lift-off and touchdown heights (m) and nominal apex (m);
    envelope: what the training jumps did (a learned model's ``provenance.data.envelope``), else None."""

    kind: str
    robot: str
    guards: str
    nlp: JumpPlanner
    crouch_height: float
    liftoff_height: float
    nominal_apex: float
    motion: MotionPlan | None = None
    envelope: dict | None = None
    disturbance_gain: float | None = None  # the closed loop's (``Replanner``; None: its default)
    _replanner: Replanner | None = field(default=None, repr=False)

    @property
    def dyn(self) -> PlanDynamics:
        return self.nlp.dyn

    @property
    def replanner(self) -> Replanner:
        """The closed loop's re-planner of this planner's problem (``plan.replan``), built once."""
        if self._replanner is None:
            self._replanner = Replanner(self.nlp, disturbance_gain=self.disturbance_gain)
        return self._replanner

    @property
    def touchdown_height(self) -> float:
        return self.motion.touchdown_height if self.motion is not None else self.liftoff_height

    def state(self, q: np.ndarray, dq: np.ndarray, x0: float = 0.0) -> np.ndarray:
        """The model's state of configuration q (18,) and velocity dq (18,); for point-mass and
        aSLIP the x measured from ``x0`` m (their laws do not depend on where the jump is)."""
        s = self.dyn.initial_state(q, dq)
        if self.kind != "learned":
            s[0] = q[BASE_POS][0] - x0
        return s

    def plan(self, q: np.ndarray, dq: np.ndarray, target_x: float, target_z: float | None = None,
             warm: bool = True, remember: bool = True, min_apex: float | None = None) -> Plan:
        """Plan from the robot's configuration q (18,) and velocity dq (18,) at the start of the
        push; for point-mass and aSLIP the state's x is measured from the start. ``warm``,
        ``remember``: as ``JumpPlanner.solve``'s. Without ``target_z`` the apex is held at or above
        ``min_apex`` m (default: the nominal apex)."""
        s0 = self.state(q, dq, float(q[BASE_POS][0]))
        return self.nlp.solve(s0, target_x, self.liftoff_height, apex=target_z,
                              min_apex=None if target_z is not None else (min_apex or self.nominal_apex), warm=warm,
                              z_touchdown=self.touchdown_height, remember=remember)

    def reach(self, target_z: float | None = None) -> JumpReach:
        """Where the planner can land from the motion's crouch at rest (``JumpReach``): with the
        apex at ``target_z`` m (if given; the x range at the reachable apex nearest it) or at or
        above the nominal apex. Raises
        ``PlanModelError`` if no jump is feasible (a model that cannot plan)."""
        q = self.motion.q_crouch if self.motion is not None else start_pose(self.robot, self.crouch_height)
        s0 = self.state(q, np.zeros(18), float(q[BASE_POS][0]))
        env = self.envelope
        data = None
        if env is not None:
            data = (*env["travel_x_m"], *env["apex_z_m"])
        z_lo, z_td = self.liftoff_height, self.touchdown_height
        lo_x = 0.0
        full = self.nlp.reach(s0, z_lo, self.nominal_apex if target_z is None else z_lo, z_touchdown=z_td,
                              x_range=(lo_x, np.inf))
        apex_floor = self.nominal_apex
        if full is None and target_z is None:  # weak motors: the apex rule of ``plan_jump``
            low = self.nlp.reach(s0, z_lo, z_lo, z_touchdown=z_td, x_range=(lo_x, np.inf))
            if low is not None:
                apex_floor = z_lo + REACH_SHARE * (low.z_max - z_lo)
                full = self.nlp.reach(s0, z_lo, apex_floor, z_touchdown=z_td, x_range=(lo_x, np.inf))
        if full is None:
            raise PlanModelError(f"the {self.kind} model cannot plan a {self._motion_name()} from the crouch: no jump "
                                 "meets its force, friction, torque and stance bounds and its guards")
        z_min, z_max = full.z_min, full.z_max
        x_min, x_max = max(full.x_min, 0.0), full.x_max
        zc = None
        if target_z is not None:
            # the x range at the reachable apex nearest the target: within the training jumps' apexes
            # too, where they leave any (at an apex past them the model's x range can miss theirs)
            lo_z, hi_z = (max(z_min, data[2]), min(z_max, data[3])) if data is not None else (z_min, z_max)
            zc = float(np.clip(target_z, lo_z, hi_z) if lo_z <= hi_z else np.clip(target_z, z_min, z_max))
            at = self.nlp.reach(s0, z_lo, zc, max_apex=zc, z_touchdown=z_td, x_range=(lo_x, np.inf))
            if at is not None:
                x_min, x_max = max(at.x_min, 0.0), at.x_max
        model = (x_min, x_max, z_min, z_max)
        if target_z is None:  # the apex is held at the nominal one (or the weak motors' floor) or above
            z_min = max(z_min, apex_floor)
        if data is not None:
            x_min, x_max = max(x_min, data[0]), min(x_max, data[1])
            z_min, z_max = max(z_min, data[2]), min(z_max, data[3])
        if x_min > x_max or z_min > z_max:
            raise PlanModelError(f"the {self.kind} model's bounds ({model[0]:.3f}-{model[1]:.3f} m forward, apex "
                                 f"{model[2]:.3f}-{model[3]:.3f} m) and its training jumps "
                                 f"({data[0]:.3f}-{data[1]:.3f} m, apex {data[2]:.3f}-{data[3]:.3f} m) "
                                 f"leave no jump it can plan")
        return JumpReach(x_min, x_max, z_min, z_max, model, data, zc)

    def _motion_name(self) -> str:
        return "froggy jump" if self.motion is not None and self.motion.motion == "froggy" else "pronk"


def make_planner(kind: str, robot: str, model: HybridModel | None = None, aslip: ASlipParams | None = None,
                 config: PlanConfig | None = None, guards: str = "height", motion: str | None = None,
                 heights: tuple[float, float] | None = None, release: Release | None = None,
                 bias: bool | None = None) -> RobotPlanner:
    """Build the NLP of planner ``kind`` for ``robot`` once; ``model`` for ``learned``,
    ``aslip`` for ``aslip``; ``guards`` (``GUARDS``): ``height`` (``HeightGuards``) or, for the
    learned planner, ``learned`` (the model's own switches, ``LearnedGuards``); ``motion``
    (``MOTIONS``): the jump planned (default: the learned model's training motion, else the
    pronk; a learned model plans only its own); ``heights``: the base's (lift-off, touchdown)
    heights m the height guards use (default: the motion's, ``motion_plan``, but for a learned
    model's pronk on its own robot its training jumps' medians, ``training_heights``);
    ``release``: what follows the push before the feet leave (``Release``; default: none, but for a
    learned model's pronk on its own robot its training jumps' release, ``training_release``);
    ``bias``: whether the landing adds what this planner's flight misses of the training jumps'
    travel (``plan.bias``, fitted on ``model``'s training lift-offs: ``training_bias``; default: for
    a learned model's pronk on its own robot with height guards; a froggy's only when asked: it
    lands in another posture than its data's, and with the bias it landed further)."""
    if kind not in PLANNERS:
        raise ValueError(f"unknown planner {kind!r}; choose from {', '.join(PLANNERS)}")
    if guards not in GUARDS:
        raise ValueError(f"unknown guards {guards!r}; choose from {', '.join(GUARDS)}")
    if guards == "learned" and kind != "learned":
        raise ValueError(f"learned guards belong to a learned model; the {kind} planner uses height guards")
    trained_motion = model.provenance.data.motion if (kind == "learned" and model is not None) else None
    if motion is None:
        motion = trained_motion or "pronk"
    if motion not in MOTIONS:
        raise ValueError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")
    if trained_motion is not None and trained_motion != motion:
        raise ValueError(f"the model was trained on {trained_motion!r} jumps; it cannot plan a {motion!r} jump")
    desc = get_robot(robot)
    mass = desc.mass
    cfg = config or PlanConfig(fz_max=PlanConfig.fz_max * mass / get_robot("go1").mass)
    mp = motion_plan(motion, robot, cfg)
    q_crouch = mp.q_crouch
    legs = {STANCE_PHASE: ALL_LEGS, PARTIAL_PHASE: REAR}
    envelope = None
    own_robot = False
    if kind == "learned":
        if model is None:
            raise ValueError("the learned planner needs a model (model.json)")
        trained_on = model.provenance.data.robot
        own_robot = trained_on is None or robot_key(trained_on) == robot_key(robot)
        if not own_robot:
            check_model_robot(trained_on, robot)
        B = {st.phase: force_input_map(model, robot, q_crouch, legs[st.phase]) for st in mp.stances}
        dyn: PlanDynamics = LearnedDynamics(model, B if motion != "pronk" else B[STANCE_PHASE])
        envelope = model.provenance.data.envelope
        if motion == "pronk" and own_robot:  # another robot's heights and legs differ
            heights = training_heights(model) if heights is None else heights
            release = training_release(model) if release is None else release
    elif kind == "point-mass":
        dyn = PointMass(mass)
    else:
        if aslip is None:
            raise ValueError("the aslip planner needs fitted aSLIP parameters (params.json of symrom aslip)")
        feet = leg_kinematics(robot).foot_positions(q_crouch[None, JOINTS])[0]  # base frame
        pivot = feet.mean(axis=0)
        dyn = ASlipDynamics(aslip.m, params=aslip, pivot=(float(pivot[0]), float(pivot[2] + q_crouch[BASE_POS][2])))
    if heights is not None:
        z_lo, z_td = (float(h) for h in heights)
        if not (np.isfinite(z_lo) and np.isfinite(z_td) and z_lo > 0 and z_td > 0):
            raise ValueError(f"the lift-off and touchdown heights must be positive, got {heights}")
        mp = replace(mp, liftoff_height=z_lo, touchdown_height=z_td)
    if bias is None:
        bias = kind == "learned" and motion == "pronk" and own_robot and guards == "height"
    flight_bias = None
    if bias:
        if model is None:
            raise ValueError(f"a flight bias is fitted on a model's training jumps; the {kind} planner was "
                             "given no model")
        flight_bias = training_bias(dyn, model, mp.touchdown_height)
    last = mp.stances[-1].phase
    rule = LearnedGuards.of(model, stance=last, flight=FLIGHT_PHASE) if guards == "learned" else HeightGuards()
    # the legs' torques at the start and at the end of the push (crouch, take-off height)
    if motion == "pronk":
        limits = torque_map(robot, [q_crouch, start_pose(robot, mp.params.takeoff_height)], desc.torque_limit)
    else:
        q_up = start_pose(robot, mp.liftoff_height)
        limits = {st.phase: torque_map(robot, [q_crouch, q_up], desc.torque_limit, legs=legs[st.phase])
                  for st in mp.stances}
    if envelope is not None and motion != "pronk" and not reads_pitch(model):
        limits = {st.phase: pitch_bounds(limits[st.phase], robot, [q_crouch, q_up], legs[st.phase],
                                         envelope, st.phase) for st in mp.stances}
    # a froggy's flight follows its push at once: no release
    nlp = JumpPlanner(dyn, mass, cfg, rule, limits, stances=mp.stances if motion != "pronk" else None,
                      release=release if motion == "pronk" else None, bias=flight_bias)
    crouch = float(q_crouch[BASE_POS][2]) if motion != "pronk" else mp.params.crouch_height
    # without a target apex the jump rises at least to the motion's nominal apex, or to the highest
    # apex of the training jumps where that is lower: a model knows the motion only where its data went
    nominal = mp.nominal_apex if envelope is None else min(mp.nominal_apex, float(envelope["apex_z_m"][1]))
    return RobotPlanner(kind, robot, guards, nlp, crouch, mp.liftoff_height, nominal, mp, envelope)


def training_heights(model: HybridModel | None) -> tuple[float, float] | None:
    """A learned model's training jumps' median base heights (m) at lift-off (their flight's
    first row) and touchdown (the first row after it), from its envelope; None without one.

    The pronk's own take-off height (0.33 m on the Go1) is where its push's force ends; the feet
    leave 8-10 ms later at 0.345 m, the trunk having lost upward speed lifting the legs, and come
    down with the base at 0.347 m. Height guards at the take-off height make a planned flight
    last tens of ms longer than the robot's, and its closed loop lands short (docs/benchmarks.md,
    "Jumps to a target")."""
    env = None if model is None else model.provenance.data.envelope
    if not env or env.get("liftoff_z_m") is None or env.get("touchdown_z_m") is None:
        return None
    return float(env["liftoff_z_m"]), float(env["touchdown_z_m"])


def training_release(model: HybridModel | None) -> Release | None:
    """A learned model's training jumps' release (``data.envelope``): the pronk's push ends by
    holding the legs without ground force, and the trunk, catching them up, keeps rising and slows
    faster than a free fall for 8-10 ms before the feet leave (at the lift-off height). A plan whose
    push ran to the lift-off height left that out: the robot then left higher and slower than
    planned, and its landing error grew along the targets (docs/benchmarks.md, "Jumps to a
    target"). None without one; a malformed one is refused naming its key."""
    env = None if model is None else model.provenance.data.envelope
    rel = (env or {}).get("release")
    if not rel or rel.get("phase", STANCE_PHASE) != STANCE_PHASE:
        return None
    try:
        return Release(float(rel["s"]), (float(rel["force_n"][0]), float(rel["force_n"][1])))
    except (KeyError, IndexError, TypeError, ValueError) as e:
        raise ValueError(f"the model's provenance.data.envelope.release {dict(rel)}: {e}") from None


def training_bias(dyn: PlanDynamics, model: HybridModel, z_touchdown: float) -> FlightBias | None:
    """What the flight of ``dyn`` misses of the travel of ``model``'s training jumps from their
    lift-offs (its envelope's ``liftoffs``) down to ``z_touchdown`` m: the line ``plan.bias``
    fits. None for a model file that records no lift-offs or too few landed flights; malformed
    ones are refused naming their key."""
    env = model.provenance.data.envelope
    liftoffs = (env or {}).get("liftoffs")
    if not liftoffs:
        return None
    return fit_flight_bias(dyn, liftoffs, z_touchdown, where="the model's provenance.data.envelope.liftoffs")


def reads_pitch(model: HybridModel) -> bool:
    """Whether the model's latents read the trunk's pitch (its encoder weighs it)."""
    return bool(np.any(model.autoencoder.W_e[:, BASE_RPY.start + 1] != 0))


def pitch_bounds(tmap: tuple[np.ndarray, np.ndarray], robot: str, qs: list[np.ndarray], legs: tuple[int, ...],
                 envelope: dict, phase: str) -> tuple[np.ndarray, ...]:
    """The torque map ``tmap`` (A, limits) of a stance on the feet ``legs`` in ``phase`` of a model
    whose latents do not read the pitch, and, where those feet cannot hold the trunk's pitch
    (``inputs.holds_pitch``: a froggy's rear pair), the pitching moment the force makes at the
    configurations ``qs`` within what the training pushes made in that phase
    (``envelope["push_wrench"]``). Such a model learned how the push moves the base only for pushes
    that pitched the trunk as its data's did; planned free of it, a rear push can spin the trunk
    (a Laikago froggy plan turned it 1.5 rad in flight). As it is where there is no such record."""
    pushed = (envelope.get("push_wrench") or {}).get("phases", {}).get(phase)
    if pushed is None or holds_pitch(legs):
        return tmap
    k = list(envelope["push_wrench"]["components"]).index("my")
    A, lim = tmap
    M = pitch_moment_map(robot, qs, legs)
    return (np.vstack([A, M]), np.concatenate([-lim, np.full(len(qs), pushed["min"][k])]),
            np.concatenate([lim, np.full(len(qs), pushed["max"][k])]))


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


class ModelFeedback:
    """The closed loop of ``plan.execute`` (a ``Feedback``): the rest of the push re-planned by a
    ``Replanner`` every ``1 / rate_hz`` s from the measured state, encoded to the planner's
    model state; the targets the plan was made for."""

    def __init__(self, planner: RobotPlanner, replanner: Replanner, target_x: float, target_z: float | None,
                 rate_hz: float = REPLAN_HZ):
        self.planner, self.replanner = planner, replanner
        self.target_x, self.target_z = target_x, target_z
        self.period = 1.0 / rate_hz
        self._x0 = 0.0

    @property
    def stats(self) -> ReplanStats:
        return self.replanner.stats

    def begin(self, plan: Plan, state: RobotState) -> Schedule:
        pl = self.planner
        self._x0 = float(state.q[BASE_POS][0])
        return self.replanner.begin(plan, self.target_x, plan.x0, pl.liftoff_height, pl.touchdown_height,
                                    self.target_z, None if self.target_z is not None else pl.nominal_apex)

    def replan(self, state: RobotState, since: float) -> Schedule:
        return self.replanner.step(self.planner.state(state.q, state.dq, self._x0), since)


@dataclass
class JumpResult:
    """One planned and executed jump: the planner's kind, the target (m) asked for, the target
    planned for (the closest reachable one when the target was out of reach and that was
    asked for), the reach it was checked against, the control, the execution."""

    planner: str
    robot: str
    engine: str
    guards: str
    target_x: float
    target_z: float | None
    execution: Execution
    apex_rule: str = "target"
    apex_floor: float | None = None
    control: str = "plan"
    planned_target_x: float | None = None
    planned_target_z: float | None = None
    reach: JumpReach | None = None
    in_reach: bool = True
    heights: tuple[float, float] | None = None  # the guards' (lift-off, touchdown) heights, m
    release: Release | None = None  # what the plan put between its push and the lift-off
    bias: FlightBias | None = None  # what the plan added to its flight's landing
    replan_hz: float = REPLAN_HZ  # the closed loop's re-planning rate, Hz
    disturbance_gain: float = 0.0  # the closed loop's disturbance estimate's gain (``Replanner``)

    @property
    def error_x(self) -> float:
        return self.execution.landing_x - self.target_x

    @property
    def error_z(self) -> float | None:
        return None if self.target_z is None else self.execution.apex_z - self.target_z

    @property
    def reachable(self) -> bool:
        """Whether the target is within reach and the plan itself lands on it (within
        ``REACH_TOL``)."""
        return self.in_reach and abs(self.execution.plan.landing_x - self.target_x) <= REACH_TOL

    def landing(self) -> dict:
        """landing.json's content (``LANDING_FORMAT``)."""
        ex, plan = self.execution, self.execution.plan
        d = {"format_version": LANDING_FORMAT, "planner": self.planner, "guards": self.guards,
             "robot": self.robot, "engine": self.engine, "motion": ex.motion, "control": self.control,
             "disturbances": ex.disturbances.to_dict(), "target_x": self.target_x, "target_z": self.target_z,
                "apex_rule": self.apex_rule, "apex_floor": self.apex_floor,
             "planned_target_x": self.target_x if self.planned_target_x is None else self.planned_target_x,
             "planned_target_z": self.target_z if self.planned_target_x is None else self.planned_target_z,
             "landing_x": ex.landing_x, "error_x": self.error_x, "error_z": self.error_z,
             "planned_landing_x": plan.landing_x, "target_reachable": self.reachable,
             "reach": None if self.reach is None else self.reach.to_dict(), "apex_z": ex.apex_z,
             "solve_time_s": plan.solve_time_s, "rest_x": ex.rest_x,
             "liftoff": dict(zip(("x", "z", "vx", "vz"), ex.liftoff.tolist())), "t_push_s": ex.t_push,
             "push_duration_s": ex.push_s, "t_touchdown_s": ex.t_touchdown, "settled": ex.finished,
             "rest": ex.rest, "upright": ex.upright,
             "heights": None if self.heights is None else dict(zip(("liftoff_z", "touchdown_z"), self.heights)),
             "release": None if self.release is None else {"s": self.release.duration,
                                                           "force_n": list(self.release.force)},
             "flight_bias": None if self.bias is None else self.bias.to_dict(),
             "definition": "landing_x: base x at the first touchdown after the push, from the base x at the "
                           "start of the push (m); error_x: landing_x - target_x; error_z: apex_z - target_z; "
                           "apex_z: largest base height between lift-off and touchdown (m); rest_x: base x at "
                           "the end of the run, from the same start (m); rest: base height (m), roll and "
                           f"pitch (rad) at the end; upright: roll and pitch within {TILTED:g} rad of level and the "
                           f"base at least {LYING:g} of its standing height at the end; heights: the base "
                           "heights (m) at which the plan's height guards put lift-off (the push's end, or "
                           "the release's after it) and touchdown; release: the length (s) and summed force "
                           "(x, z; N, as the model's input reads it) the plan put between its push and the "
                           "lift-off, or null; flight_bias: the line the plan added to its flight's landing "
                           "(offset m, per m/s of lift-off velocity x, z in s), fitted on the training jumps' "
                           "travel (jumps, and their rms error m without and with it), or null",
             "plan": plan.to_dict()}
        if ex.replans is not None:
            r = ex.replans
            times = np.asarray(r.solve_time_s, float)
            d["replans"] = {"rate_hz": self.replan_hz, "disturbance_gain": self.disturbance_gain, "count": len(times),
                            "solve_time_median_s": float(np.median(times)) if times.size else None,
                            "solve_time_max_s": float(times.max()) if times.size else None,
                            "not_ok": int(sum(s != "ok" for s in r.status)), **r.to_dict()}
        return d


def check_replan_hz(replan_hz: float) -> None:
    """Refuse a closed loop's re-planning rate below ``REPLAN_HZ`` (Hz)."""
    if not (np.isfinite(replan_hz) and replan_hz >= REPLAN_HZ):
        raise ValueError(f"the re-planning rate must be {REPLAN_HZ:g} Hz or faster, got {replan_hz:g}")


def _check_targets(planner: RobotPlanner, target_x: float, target_z: float | None) -> None:
    if not (np.isfinite(target_x) and target_x >= 0):
        raise ValueError(f"the target x must be a non-negative distance in m, got {target_x}")
    if target_z is not None and not (np.isfinite(target_z) and target_z > planner.liftoff_height):
        raise ValueError(f"the target apex must be above the lift-off height {planner.liftoff_height:.3f} m, "
                         f"got {target_z}")


def aim(planner: RobotPlanner, target_x: float, target_z: float | None = None,
        closest: bool = False) -> tuple[float, float | None, JumpReach, bool]:
    """Check a target against the planner's reach (``RobotPlanner.reach``) before any
    simulation: ``(x, z, reach, in_reach)``, the target to plan for. Out of reach, raise
    ``OutOfReach`` naming the reach, or with ``closest`` return the closest reachable target
    (the target clipped to the reach; if the two together are out of reach, where the plan
    from the crouch lands) and ``in_reach`` False."""
    _check_targets(planner, target_x, target_z)
    reach = planner.reach(target_z)
    what = f"x = {target_x:g} m" + (f", apex {target_z:g} m" if target_z is not None else "")
    x, z = target_x, target_z
    inside = reach.holds(x, z)
    if not inside:
        if not closest:
            raise OutOfReach(f"the target {what} is out of the {planner.kind} planner's reach: {reach.describe()}",
                             reach)
        x = float(np.clip(x, reach.x_min, reach.x_max))
        z = None if z is None else float(np.clip(z, reach.z_min, reach.z_max))
    # both together: the plan from the crouch at rest must reach them
    q = planner.motion.q_crouch
    trial, _, _ = plan_jump(planner, q, np.zeros(18), x, z, warm=False, remember=False)
    misses = (not trial.success or abs(trial.landing_x - x) > REACH_TOL
              or (z is not None and abs(trial.apex_z - z) > REACH_TOL))
    if misses:
        if not closest:
            got = (f"the closest plan lands at {trial.landing_x:.3f} m, apex {trial.apex_z:.3f} m" if trial.success
                   else f"IPOPT: {trial.status}")
            raise OutOfReach(f"the target {what} is out of the {planner.kind} planner's reach ({got}); "
                             f"its reach: {reach.describe()}", reach)
        if trial.success:
            x, z = float(trial.landing_x), (None if z is None else float(trial.apex_z))
        inside = False
    return x, z, reach, inside


def plan_jump(planner: RobotPlanner, q: np.ndarray, dq: np.ndarray, target_x: float, target_z: float | None = None,
              warm: bool = True, remember: bool = True) -> tuple[Plan, str, float | None]:
    """The plan from configuration q (18,) and velocity dq (18,) to ``target_x`` m, the rule its
    apex was planned by (``APEX_RULES``) and the least apex it held (m; None for a target):
    ``target_z`` m if given, else at or above the nominal apex; where no plan holds that within
    the torque limits (IPOPT finds the problem infeasible: a robot whose motors are weak for its
    size, whose own pronks peak below it), at or above ``REACH_SHARE`` of the highest apex gain
    over the lift-off height the model reaches (a plan aimed at the nominal apex finds it),
    which leaves the push some torque to spare. ``warm``, ``remember``: as ``RobotPlanner.plan``'s."""
    if target_z is not None:
        return planner.plan(q, dq, target_x, target_z, warm=warm, remember=remember), "target", None
    plan = planner.plan(q, dq, target_x, None, warm=warm, remember=remember)
    if plan.success or plan.status != INFEASIBLE:
        return plan, "at least nominal", planner.nominal_apex
    top = planner.plan(q, dq, target_x, planner.nominal_apex, warm=warm, remember=remember)
    if not top.success:
        return top, "at least reachable", None
    floor = planner.liftoff_height + REACH_SHARE * (top.apex_z - planner.liftoff_height)
    return (planner.plan(q, dq, target_x, None, warm=warm, min_apex=floor, remember=remember),
            "at least reachable", floor)


def jump(planner: RobotPlanner, target_x: float, target_z: float | None = None, engine: str = "pybullet",
         warm: bool = True, control: str = "plan", disturbances: Disturbances | None = None,
         closest: bool = False, check_reach: bool = True, replan_hz: float = REPLAN_HZ) -> JumpResult:
    """Plan (from the measured crouch) and execute one jump ``target_x`` m forward, with apex
    ``target_z`` m if given, in a world with ``disturbances``, open loop (``control="plan"``)
    or re-planned at ``replan_hz`` (``"mpc"``). With ``check_reach``, the target is checked
    against the reach first (``aim``: ``OutOfReach``, or the closest reachable target with
    ``closest``). Raise ``PlanError`` if the plan fails."""
    if control not in CONTROLS:
        raise ValueError(f"unknown control {control!r}; choose from {', '.join(CONTROLS)}")
    check_replan_hz(replan_hz)
    _check_targets(planner, target_x, target_z)
    reach, in_reach = None, True
    x, z = target_x, target_z
    if check_reach:
        x, z, reach, in_reach = aim(planner, target_x, target_z, closest)

    rule: list = ["target", None]

    def plan_fn(state: RobotState) -> Plan:
        plan, rule[0], rule[1] = plan_jump(planner, state.q, state.dq, x, z, warm=warm)
        if not plan.success:
            raise PlanError(f"the {planner.kind} plan to x = {x:g} m did not converge (IPOPT: {plan.status})")
        return plan

    feedback = None
    if control == "mpc":
        feedback = ModelFeedback(planner, planner.replanner, x, z, replan_hz)
    mp = planner.motion
    if mp.motion == "pronk":
        params = replace(mp.params, distance=x)
    else:
        params = mp.params
    ex = execute(planner.robot, plan_fn, engine, params, motion=mp.motion, feedback=feedback,
                 disturbances=disturbances)
    return JumpResult(planner.kind, planner.robot, engine, planner.guards, float(target_x), target_z, ex,
                      apex_rule=rule[0], apex_floor=rule[1], control=control, planned_target_x=float(x),
                      planned_target_z=z, reach=reach, in_reach=in_reach,
                      heights=(planner.liftoff_height, planner.touchdown_height), replan_hz=float(replan_hz),
                      release=planner.nlp.release, bias=planner.nlp.bias,
                      disturbance_gain=feedback.replanner.disturbance_gain if feedback is not None else 0.0)


@dataclass(frozen=True)
class JumpRequest:
    """One jump asked for (``run_jump``): the target (m; ``target_z`` the apex, or None), the
    robot, the planner (``PLANNERS``) and its model file (model.json for ``learned``, an aSLIP
    params.json for ``aslip``, none for ``point-mass``), the guards (``GUARDS``), the engine,
    the control (``CONTROLS``; None: ``plan`` on the model's own robot, ``mpc`` on another robot
    of its build, where the model's forces do not carry over open loop), the motion (None: the
    model's, else the pronk), the world's disturbances (payload kg, ground friction or None, motor
    scale), whether an out-of-reach target gets the closest reachable jump (else it is refused),
    the closed loop's re-planning rate (Hz, ``REPLAN_HZ`` or faster) and its disturbance
    estimate's gain (``Replanner``; in [0, 1], None: the re-planner's default)."""

    target_x: float
    target_z: float | None = None
    robot: str | None = None
    planner: str = "learned"
    model_path: Path | None = None
    guards: str = "height"
    engine: str = "pybullet"
    control: str | None = None
    motion: str | None = None
    payload: float = 0.0
    friction: float | None = None
    motor_scale: float = 1.0
    closest: bool = False
    replan_hz: float = REPLAN_HZ
    disturbance_gain: float | None = None


def run_jump(req: JumpRequest, out: str | os.PathLike, trajectory: bool = True, force: bool = False) -> JumpResult:
    """Everything ``symrom jump`` does: check the request, read the model, build the planner,
    check the target's reach, plan and execute the jump, write ``landing.json`` (and
    ``trajectory.json``) into ``out``. Nothing is written if any step fails (an out-of-reach
    target: ``OutOfReach``)."""
    from symrom.sim.engines.registry import check_engine

    if req.planner not in PLANNERS:
        raise ValueError(f"the planner must be one of {', '.join(PLANNERS)}, got {req.planner!r}")
    if req.guards not in GUARDS or (req.guards == "learned" and req.planner != "learned"):
        raise ValueError(f"the guards must be height or (with the learned planner) learned, got {req.guards!r}")
    if req.control is not None and req.control not in CONTROLS:
        raise ValueError(f"the control must be one of {', '.join(CONTROLS)}, got {req.control!r}")
    check_engine(req.engine)
    check_replan_hz(req.replan_hz)
    if req.planner == "point-mass" and req.model_path is not None:
        raise ValueError(f"the point-mass planner uses no model: leave model_path={str(req.model_path)!r} out "
                         "(or plan with the learned or aslip planner)")
    if req.planner != "point-mass" and req.model_path is None:
        raise ValueError(f"the {req.planner} planner needs its model: "
                         + ("model.json" if req.planner == "learned" else "an aSLIP params.json (symrom aslip)"))
    disturbances = Disturbances(req.payload, req.friction, req.motor_scale)
    model = aslip = None
    if req.planner == "learned":
        from symrom.model.persistence import load_model

        model = load_model(req.model_path)
    elif req.planner == "aslip":
        aslip = read_aslip_params(req.model_path)
    trained_on = model.provenance.data.robot if model is not None else None
    robot = req.robot or trained_on or "go1"
    control = req.control or ("mpc" if trained_on is not None and robot_key(trained_on) != robot_key(robot) else "plan")
    if req.disturbance_gain is not None:
        check_disturbance_gain(req.disturbance_gain)
        if control != "mpc":
            raise ValueError(f"a disturbance gain is the closed loop's: it needs control 'mpc', not {control!r}")
    built = make_planner(req.planner, robot, model=model, aslip=aslip, guards=req.guards, motion=req.motion)
    built.disturbance_gain = req.disturbance_gain
    result = jump(built, req.target_x, req.target_z, engine=req.engine, control=control,
                  disturbances=disturbances, closest=req.closest, replan_hz=req.replan_hz)
    write_landing(out, result, trajectory=trajectory, force=force)
    return result


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


__all__ = [
    "APEX_RULES",
    "CONTROLS",
    "MODEL_ROBOT_TOL",
    "PLANNERS",
    "REACH_SHARE",
    "JumpReach",
    "JumpRequest",
    "JumpResult",
    "ModelFeedback",
    "MotionPlan",
    "OutOfReach",
    "RobotPlanner",
    "aim",
    "check_model_robot",
    "check_replan_hz",
    "jump",
    "make_planner",
    "motion_plan",
    "plan_jump",
    "pronk_params",
    "read_aslip_params",
    "run_jump",
    "write_landing",
]
