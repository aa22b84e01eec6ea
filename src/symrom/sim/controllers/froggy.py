"""Froggy jump of a quadruped (A1) under Cartesian PD control of the feet.

The jump, after the contact-timing idea of Nguyen et al. (2022): the robot
settles and crouches on four feet, pushes with all four, then lifts the front
legs while the rear legs keep pushing (a rear-only contact phase), flies with
all feet off, lands on four feet and settles.

Every foot follows a Cartesian target in the base frame with PD plus a
feed-forward force, tau_leg = J^T (Kp (p_d - p) + Kd (v_d - v) + f_ff), where
p (3,) m is the foot in the base frame, v = J dq_leg (3,) m/s, J (3, 3) m/rad
the leg Jacobian from ``symrom.robots.leg_kinematics`` and f_ff (3,) N the
force the foot should exert on the ground, in the base frame. f_ff comes from
a desired body wrench (weight or thrust, plus a roll/pitch-levelling moment)
shared among the stance feet by least squares. In stance the targets are
body-fixed; during the push they are the planted feet seen from a desired base
pose moving along the take-off line; in flight they are level, so the legs
reach plumb down for the landing. Each leg's torques are scaled together into
the robot's limits (``World.step`` clips as well).

The hip abduction (hx) joints are held at their standing angle by the world
(``World.hold_joints``), as the paper's froggy jumps held them (its A1 hx
errors are 1e-10 rad); ``FroggyParams(hold_hx=False)`` drives them by the
Cartesian PD like the other joints. The parameters were tuned on the A1; for
another robot they are scaled by its mass and leg length (``scaled``), as pronk
scales its own. A robot whose description states actuator effects gets the legs' torques

A push policy. ``FroggyController(..., push=policy)`` hands the push (four feet, then the
plus what those take (damping and friction loss at the measured joint speeds, armature at the
push's planned joint accelerations), fitted into the limits leg by leg
(``symrom.sim.controllers.actuators``).
rear feet alone) to a ``FroggyPushPolicy``, as the pronk hands its own: called once when the
push is due (``start``: how long each part lasts, ``FroggyPushTiming``) and then at every
tick of the push with the measured state (``command``: the summed ground force of the feet
down and its moment about the base, a ``PushCommand``; it may re-time the rest). The feet
down get the least-norm forces that make that wrench (the force exactly; on the rear feet
alone the pitch moment is what their forces make), as joint torques through massless legs;
the front legs tuck as in the controller's own push. Settle, crouch, hold, flight and landing
are the controller's own. The jump's events (``push_start``, ``liftoff``, ``touchdown``,
``airborne``) are public and read-only, with or without a policy. Without a policy nothing
changes: the controller's own push, compiled.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

import daqp
import numpy as np

from symrom.names import GRAVITY, JOINTS, N_LEGS
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.stance import leg_length, nominal_feet, start_pose
from symrom.sim.controllers import compiled
from symrom.sim.controllers.actuators import Compensation, stance_acceleration
from symrom.sim.controllers.flight import longest_run
from symrom.sim.controllers.motion import PlainMotion, PushCommand
from symrom.sim.engines.world import RobotState, World
from symrom.sim.proxy import RANDOMIZED_RANGES, ProxyConfig, sample_proxy, sample_robot

STAGES = ("settle", "crouch", "hold", "push_all", "push_rear", "flight", "land")  # as compiled.SETTLE ...
FRONT = (0, 1)  # FR, FL
REAR = (2, 3)  # RR, RL
# The landing's leg targets (``FroggyController(landing=...)``), as ``compiled.froggy_torque``
# codes them: all body-fixed, or the pair at the trunk's lower end plumb under its hips.
LANDINGS = {"body": 0, "low_plumb": 1}
# rad: past this pitch a planned jump's flight targets turn with the trunk (``FroggyController``);
# chosen on the tuning targets of bench_jump.py (seed 1) from 0.7, 0.75 and 0.8
FLIGHT_PITCH = 0.75
# the friction pyramid each foot's force keeps to in a policy's push (``wrench_forces``): the
# planners keep the summed force within 0.6 (``plan.config.PlanConfig.mu``), so forces within it exist
PUSH_MU = 0.6
# s: a policy's rear-only push ends once its rear feet have been off the ground this long
FEET_OFF = 0.002


@dataclass(frozen=True)
class FroggyParams:
    """One froggy jump. Heights are base-above-foot-centre distances (m), times s, forces N.

    Stages: settle (t_settle), crouch to crouch_height nose-down by crouch_pitch
    rad (t_crouch), hold (t_hold), four-leg push (t_push_all), rear-only push
    (t_push_rear), flight, landing, t_after_land s of standing. During the push
    the base is driven at push_speed m/s along a line tilted ``angle`` rad from
    vertical towards +x (at most push_rise m up), with total thrust force_all N
    (force_rear N with the rear feet only). raibert (s) places the feet ahead
    by that times the forward speed at touch-down; a run that has not ended
    by max_time s is cut off (and fails the checks). Gains: kp N/m, kd N s/m;
    xy_ratio softens stance gains horizontally; k_att N m/rad and d_att
    N m s/rad level the body. hold_hx: the hip abduction joints are held at
    their standing angle (the paper's froggy), else driven like the others.
    proxy: the randomised world of a ``randomized`` jump (``symrom.sim.proxy``), else None;
    randomized: a domain-randomised source jump (``source = sim``).
    """

    stand_height: float = 0.27
    crouch_height: float = 0.19
    crouch_shift: float = 0.02
    crouch_pitch: float = 0.2
    push_speed: float = 1.3
    push_rise: float = 0.20
    t_settle: float = 0.30
    t_crouch: float = 0.40
    t_hold: float = 0.08
    t_push_all: float = 0.07
    t_push_rear: float = 0.07
    force_all: float = 250.0
    force_rear: float = 150.0
    angle: float = 0.4
    raibert: float = 0.04
    t_after_land: float = 1.10
    max_time: float = 4.0
    kp_stance: float = 800.0
    kd_stance: float = 30.0
    kp_push: float = 200.0
    kd_push: float = 10.0
    kp_swing: float = 400.0
    kd_swing: float = 10.0
    kp_land: float = 900.0
    kd_land: float = 45.0
    xy_ratio: float = 0.4
    k_att: float = 150.0
    d_att: float = 8.0
    hold_hx: bool = True
    proxy: ProxyConfig | None = None
    randomized: bool = False


REFERENCE_ROBOT = "a1"  # the robot the parameters were tuned on

# How each parameter scales with the robot (``scaled``): m mass ratio, l leg-length ratio.
_LENGTHS = ("stand_height", "crouch_height", "crouch_shift", "push_rise")
_TIMES = ("t_settle", "t_crouch", "t_hold", "t_push_all", "t_push_rear", "t_after_land", "max_time", "raibert")
_PUSH = ("t_push_all", "t_push_rear")  # the push: longer on legs weak for their size
WEAK = 0.6  # legs with less than this share of the A1's torque capacity push longer (``scaled``)
_STIFF = ("kp_stance", "kp_push", "kp_swing", "kp_land")  # N/m
_DAMP = ("kd_stance", "kd_push", "kd_swing", "kd_land")  # N s/m


def scales(robot: str) -> tuple[float, float]:
    """(mass, leg length) of ``robot`` as ratios to the A1's; exactly (1, 1) for the A1."""
    ref = REFERENCE_ROBOT
    return (get_robot(robot).mass / get_robot(ref).mass, leg_length(robot) / leg_length(ref))


def torque_capacity(robot: str) -> float:
    """Mean torque limit per unit mass and leg length, N m / (kg m): how hard the legs can push."""
    d = get_robot(robot)
    return float(np.mean(d.torque_limit)) / (d.mass * leg_length(robot))


def scaled(params: FroggyParams, robot: str) -> FroggyParams:
    """``params`` (the A1's) for ``robot``, dynamically similar: lengths with the leg length l,
    times and speeds with sqrt(l) (equal Froude number), forces with the mass m, Cartesian
    stiffness with m / l and damping with m / sqrt(l), the levelling moment's stiffness with
    m l and damping with m l^1.5. Angles stay, but for the crouch's, which is level: the
    A1's nose-down crouch is its own tuning (its push's nose-up turn brings it back through
    level), and on other robots it adds to the nose-down turn of the rear-only push (the
    Mini Cheetah then lands nose-down past the tilt check). A robot whose legs are weaker for its size
    than the A1's (``torque_capacity``, ratio c < 1) gets its thrust times sqrt(c): the
    push then stays within what its motors give for longer (the controller scales each
    leg's torques into the limits). Below 0.6 of the A1's (``WEAK``: Menagerie's Barkour vB,
    ANYmal B and C) both parts of the push also last 1 / sqrt(c) times as long, so the push's
    impulse stays: with the A1's timing those leave the ground at half the speed the flight
    needs. Stronger legs keep it (the Mini Cheetah's landing is tuned on it). The A1's are
    returned unchanged."""
    m, l = scales(robot)
    if (m, l) == (1.0, 1.0):
        return params
    root = float(np.sqrt(l))
    c = min(1.0, torque_capacity(robot) / torque_capacity(REFERENCE_ROBOT))
    m_thrust = m * float(np.sqrt(c))
    stretch = 1.0 / float(np.sqrt(c)) if c < WEAK else 1.0
    f = {n: getattr(params, n) * l for n in _LENGTHS}
    f |= {n: getattr(params, n) * root * (stretch if n in _PUSH else 1.0) for n in _TIMES}
    f |= {n: getattr(params, n) * m / l for n in _STIFF}
    f |= {n: getattr(params, n) * m / root for n in _DAMP}
    f |= {"push_speed": params.push_speed * root, "force_all": params.force_all * m_thrust,
          "force_rear": params.force_rear * m_thrust, "k_att": params.k_att * m * l,
          "d_att": params.d_att * m * l * root,
          "crouch_pitch": 0.0}
    return replace(params, **f)


@dataclass(frozen=True)
class FroggyRanges:
    """Uniform ranges (low, high) of a drawn froggy jump, for the A1 (then ``scaled``):
    crouch_height, crouch_shift m, crouch_pitch rad, push_speed m/s, angle rad, t_hold,
    t_push_all and t_push_rear s (the rear-only push's length), force_all N (force_rear:
    ``rear_share`` of it), k_att N m/rad, d_att N m s/rad, kp_push N/m. ``FroggyRanges()``
    draws ``FroggyParams()``'s jump."""

    crouch_height: tuple[float, float] = (0.19, 0.19)
    crouch_pitch: tuple[float, float] = (0.2, 0.2)
    push_speed: tuple[float, float] = (1.3, 1.3)
    angle: tuple[float, float] = (0.4, 0.4)
    t_hold: tuple[float, float] = (0.08, 0.08)
    t_push_all: tuple[float, float] = (0.07, 0.07)
    t_push_rear: tuple[float, float] = (0.07, 0.07)
    force_all: tuple[float, float] = (250.0, 250.0)
    rear_share: tuple[float, float] = (0.6, 0.6)
    crouch_shift: tuple[float, float] = (0.02, 0.02)
    k_att: tuple[float, float] = (150.0, 150.0)
    d_att: tuple[float, float] = (8.0, 8.0)
    kp_push: tuple[float, float] = (200.0, 200.0)

    def draw(self, rng: np.random.Generator, **fixed) -> FroggyParams:
        """One jump's parameters (the A1's) drawn from the ranges, in the fields' order; ``fixed``:
        other ``FroggyParams`` fields as given."""
        u = rng.uniform
        v = {f: float(u(*getattr(self, f))) for f in ("crouch_height", "crouch_pitch", "push_speed", "angle",
                                                     "t_hold", "t_push_all", "t_push_rear", "force_all")}
        v["force_rear"] = v["force_all"] * float(u(*self.rear_share))
        v |= {f: float(u(*getattr(self, f))) for f in ("crouch_shift", "k_att", "d_att", "kp_push")}
        return FroggyParams(**v, **fixed)


# A real froggy's jump (the A1's jumps by Nguyen et al.'s controller): the front feet leave the
# ground early in a long, slow push (a crouch shifted back over the rear feet, the take-off line
# 47-54 degrees from vertical, the rear feet pushing with about the whole thrust), and the rear
# feet hold the ground for 0.25-0.35 s while the body turns nose-up by 0.15-0.45 rad, where
# ``FroggyParams()``'s jumps spend about 0.07 s on the rear feet and turn nose-down. The thrust is
# what sets the rear-only phase's length: the leg's stroke ends it before the commanded time, the
# sooner the harder it pushes. Measured on the A1 in MuJoCo on the proxy's worlds
# (``proxy.PROXY_RANGES``, one robot per draw): 36 of 60 draws land, their rear-only phase
# 0.25-0.36 s (median 0.32 s), nose-up by 0.18-0.44 rad (docs/simulation.md).
REAL_MOTION = FroggyRanges(
    crouch_height=(0.18, 0.19), crouch_shift=(0.105, 0.122), crouch_pitch=(-0.12, 0.0), push_speed=(0.55, 0.72),
    t_hold=(0.06, 0.1), t_push_all=(0.06, 0.08), t_push_rear=(0.3, 0.37), force_all=(190.0, 230.0),
    rear_share=(0.95, 1.1), angle=(0.82, 0.95), k_att=(100.0, 140.0), d_att=(6.0, 8.5), kp_push=(300.0, 420.0))

# Domain-randomised source jumps, of two kinds drawn with equal chance: ``FroggyParams()``'s quick
# push (the rear feet alone for 0.04-0.1 s, nose-down crouch) and a real froggy's long one
# (``REAL_MOTION`` widened on every side; its softer thrusts, steeper take-offs and higher
# crouches hold the rear feet down for up to 0.4-0.5 s), each over ranges its draws land in on the
# randomised worlds (``proxy.RANDOMIZED_RANGES``); a draw that does not land is replaced by a fresh
# one (``generation.runner.DRAWN_ATTEMPTS``).
RANDOMIZED_QUICK = FroggyRanges(
    crouch_height=(0.175, 0.2), crouch_pitch=(0.12, 0.2), push_speed=(1.1, 1.4), angle=(0.25, 0.45),
    t_hold=(0.03, 0.15), t_push_all=(0.055, 0.09), t_push_rear=(0.055, 0.11), force_all=(260.0, 330.0),
    rear_share=(0.55, 0.7))
RANDOMIZED_LONG = FroggyRanges(
    crouch_height=(0.172, 0.195), crouch_shift=(0.1, 0.125), crouch_pitch=(-0.13, 0.02), push_speed=(0.45, 0.8),
    t_hold=(0.03, 0.15), t_push_all=(0.055, 0.09), t_push_rear=(0.29, 0.42), force_all=(170.0, 320.0),
    rear_share=(0.9, 1.12), angle=(0.8, 1.0), k_att=(95.0, 145.0), d_att=(5.5, 9.0), kp_push=(260.0, 440.0))
RANDOMIZED_MOTION = (RANDOMIZED_QUICK, RANDOMIZED_LONG)


def sample_randomized(rng: np.random.Generator, robot: str = REFERENCE_ROBOT) -> FroggyParams:
    """A domain-randomised froggy jump: the motion from one of ``RANDOMIZED_MOTION``'s kinds
    (equal chance) and the world from ``proxy.RANDOMIZED_RANGES``; scaled to ``robot``."""
    ranges = RANDOMIZED_MOTION[int(rng.random() < 0.5)]
    params = ranges.draw(rng, t_after_land=float(rng.uniform(1.0, 1.2)))
    return scaled(replace(params, proxy=sample_proxy(rng, RANDOMIZED_RANGES), randomized=True), robot)


def sample_real(rng: np.random.Generator, robot: str = REFERENCE_ROBOT,
                proxy_robot: ProxyConfig | None = None) -> FroggyParams:
    """A hardware-like froggy jump (the ``proxy`` variant, ``source = proxy``): the motion of a
    real froggy (``REAL_MOTION``) on the proxy's world (``proxy.PROXY_RANGES``; the hardware
    constants of ``proxy_robot``, one per dataset, and the per-jump rest); scaled to ``robot``."""
    params = REAL_MOTION.draw(rng, t_after_land=float(rng.uniform(1.0, 1.2)))
    return scaled(replace(params, proxy=sample_proxy(rng, robot=proxy_robot)), robot)


def sample_params(rng: np.random.Generator, robot: str = REFERENCE_ROBOT) -> FroggyParams:
    """A random froggy jump: varied crouch, take-off speed and angle, push timing and thrust;
    drawn for the A1 and scaled to ``robot`` (``scaled``)."""
    force_all = float(rng.uniform(240.0, 320.0))
    return scaled(FroggyParams(
        crouch_height=float(rng.uniform(0.18, 0.195)),
        push_speed=float(rng.uniform(1.2, 1.4)),
        angle=float(rng.uniform(0.3, 0.45)),
        t_push_all=float(rng.uniform(0.065, 0.08)),
        t_push_rear=float(rng.uniform(0.06, 0.08)),
        force_all=force_all,
        force_rear=float(0.6 * force_all * rng.uniform(0.9, 1.1)),
        t_after_land=float(rng.uniform(1.0, 1.2)),
    ), robot)


def crouch_pose(robot: str, params: FroggyParams) -> np.ndarray:
    """q (18,): the robot at the bottom of the crouch of ``params`` (at rest, base over the origin):
    the feet at the crouch's targets (``crouch_height`` below the base, the front ones higher by
    ``crouch_pitch``, shifted by ``crouch_shift``), the base pitched nose down by ``crouch_pitch``
    so that the feet stand level, at ``crouch_height`` above the feet's centres."""
    from symrom.robots.stance import leg_ik

    feet0 = nominal_feet(robot) * [1.0, 1.0, 0.0]
    targets = feet0 + np.stack([np.full(N_LEGS, params.crouch_shift), np.zeros(N_LEGS),
                                -params.crouch_height + params.crouch_pitch * feet0[:, 0]], axis=1)
    q = np.zeros(18)
    q[JOINTS] = leg_ik(robot, targets)
    q[14] = params.crouch_height + get_robot(robot).foot_radius
    q[16] = params.crouch_pitch
    return q


def smooth(s: float) -> float:
    """Cosine blend 0 -> 1 on s in [0, 1] (clipped), zero slope at both ends."""
    s = min(max(s, 0.0), 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


def yaw_matrix(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def distribute(foot_pos: np.ndarray, centre: np.ndarray, legs: tuple[int, ...],
               force: np.ndarray, moment: np.ndarray, mu: float = 0.6) -> np.ndarray:
    """Ground reactions (4, 3) N, world, of the feet ``legs`` giving a wrench on the body.

    Least-norm solution of sum F_k = force (3,) N and sum (p_k - centre) x F_k =
    moment (3,) N m, with foot_pos (4, 3) m and centre (3,) m in the world; then
    pulls are dropped and horizontal parts clipped to the friction cone ``mu``.
    Compiled (``symrom.sim.controllers.compiled``).
    """
    grf = np.empty((N_LEGS, 3))
    compiled.distribute(np.ascontiguousarray(foot_pos, dtype=float), np.asarray(centre, dtype=float),
                        np.asarray(legs, dtype=np.int64), np.asarray(force, dtype=float),
                        np.asarray(moment, dtype=float), float(mu), grf)
    return grf


@dataclass(frozen=True)
class FroggyPushTiming:
    """The push a ``FroggyPushPolicy`` means to make: ``four`` s on all four feet from its first
    tick, then ``rear`` s on the rear feet alone; the flight follows."""

    four: float
    rear: float


@runtime_checkable
class FroggyPushPolicy(Protocol):
    """What drives the froggy's push in place of its Cartesian push (``FroggyController(push=...)``).

    ``start`` is called once, at the first tick of the push (the settle, crouch and hold are
    over), with the measured state; then ``command`` at every tick of the push (``since`` = 0
    first), with the measured state and the time since the push began; its
    ``PushCommand.timing`` (a ``FroggyPushTiming``, the whole push's from its start) moves the
    ends of the two parts. The four-foot part ends at the first tick ``four`` s or more after
    the push began, the rear-only part ``four + rear`` s after it."""

    def start(self, state: RobotState) -> FroggyPushTiming:
        """The push's timing, planned from the measured ``state`` at its first tick."""

    def command(self, state: RobotState, since: float) -> PushCommand:
        """The command for this tick of the push, ``since`` s after it began."""


def wrench_forces(foot_pos: np.ndarray, centre: np.ndarray, legs: tuple[int, ...], force: np.ndarray,
                  moment: np.ndarray, mu: float | None = None) -> np.ndarray:
    """Ground forces (4, 3) N, world, on the feet ``legs`` (the others 0): the least-norm
    forces that sum to ``force`` (3,) N and, as closely as the feet allow, make ``moment``
    (3,) N m about ``centre`` (3,) m, the feet at foot_pos (4, 3) m. The sum is held exactly
    (two feet cannot make every moment: on a line across the body, none about it).

    With ``mu``, each foot's force also stays in its friction pyramid (|f_x|, |f_y| <= mu f_z,
    f_z >= 0): where the least-norm forces leave it, a QP (DAQP) finds the forces within the
    pyramids, with the sum, that come closest to the moment. Least norm gives every foot the
    same horizontal share, so a lightly loaded foot (the front pair of a froggy crouched over
    its rear feet) is asked 1-2.5 times its normal force and slides. A sum outside the pyramid
    widens every foot's to the sum's ratio; a sum that does not push (f_z <= 0), or a QP DAQP
    cannot solve, keeps the least-norm forces."""
    r = foot_pos[list(legs)] - centre
    n = len(legs)
    A = np.zeros((6, 3 * n))
    for i, (x, y, z) in enumerate(r):
        A[:3, 3 * i:3 * i + 3] = np.eye(3)
        A[3:, 3 * i:3 * i + 3] = [[0, -z, y], [z, 0, -x], [-y, x, 0]]
    b = np.concatenate([force, moment])
    # the force rows exactly: f = f_p + N z, with N the null space of the force rows
    Af, Am = A[:3], A[3:]
    f_p = np.linalg.lstsq(Af, force, rcond=None)[0]
    vt = np.linalg.svd(Af)[2]
    N = vt[3:].T  # (3 n, 3 n - 3)
    z = np.linalg.lstsq(Am @ N, b[3:] - Am @ f_p, rcond=None)[0]
    f = (f_p + N @ z).reshape(n, 3)
    out = np.zeros((N_LEGS, 3))
    out[list(legs)] = f
    if mu is None:
        return out
    slack = 1e-9 * (1.0 + np.abs(force).max())
    within = np.all(f[:, 2] >= -slack) and np.all(np.abs(f[:, :2]) <= mu * f[:, 2:3] + slack)
    if within or force[2] <= 0.0:
        return out
    # a summed force past the pyramid (a plan at its friction bound, to round-off) widens every
    # foot's to the sum's: the feet then share it in proportion at worst
    mu = max(mu, float(np.abs(force[:2]).max() / force[2]) * (1.0 + 1e-9))
    # min 1/2 |Am f - moment|^2 + eps/2 |f|^2: Af f = force; per foot f_z >= 0 and the pyramid
    eps = 1e-9 * np.trace(Am.T @ Am) / (3 * n)  # least norm only breaks the moment's ties
    H = Am.T @ Am + eps * np.eye(3 * n)
    g = -Am.T @ b[3:]
    faces = np.array([[1.0, 0.0, -mu], [-1.0, 0.0, -mu], [0.0, 1.0, -mu], [0.0, -1.0, -mu]])
    cone = np.kron(np.eye(n), faces)  # each foot's four faces, <= 0 (the MPC's, ``mpc._daqp_parts``)
    big = 1e30
    lo_var = np.tile([-big, -big, 0.0], n)
    upper = np.concatenate([np.full(3 * n, big), force, np.zeros(4 * n)])
    lower = np.concatenate([lo_var, force, np.full(4 * n, -big)])
    sense = np.zeros(upper.size, dtype=np.int32)
    sense[3 * n:3 * n + 3] = 5  # the sum: equalities (the rows after the 3 n bounds)
    x, _, flag, _ = daqp.solve(H, g, np.vstack([Af, cone]), upper, lower, sense)
    if flag < 1 or not np.all(np.isfinite(x)):
        return out
    out[list(legs)] = x.reshape(n, 3)
    return out


class FroggyController:
    """Finite-state froggy jump controller; one instance per jump.

    ``torque(state)`` -> (12,) N m requested joint torques; ``done(state)`` once
    the robot has settled after landing. ``phase`` names the controller's
    current stage (settle, crouch, hold, push_all, push_rear, flight, land).

    ``landing`` (``LANDINGS``): ``body``, every leg's landing target body-fixed, as the
    generated data's jumps land; ``low_plumb``, the pair of legs at the trunk's lower end (the
    front pair while it is pitched nose down, else the rear) held plumb under their hips, the
    other pair body-fixed (the two agree when the trunk is level). A froggy touches down nose
    first; with body-fixed targets the front feet sit behind their hips, close under the CoM,
    so the trunk pivots over them with the rear feet in the air for half a second or more, and
    a jump that comes down turning a little faster goes over. Plumb front legs keep the CoM
    behind the front feet and the trunk settles back onto the rear feet; if it rocks on past
    level, the rear pair does the same. The planned jumps land this way (``plan.execute``).

    ``flight_pitch`` (rad, or None: no limit): in flight the leg targets hang level below the
    base up to this pitch; past it their frame turns with the trunk by the excess, each foot kept
    at its level target's depth below the base. A trunk pitched far nose down puts the front
    feet's level targets up by the hips' plane, where the Cartesian PD folds the knees onto their
    stops: the feet come up and the jump touches down late, low and long. The planned jumps fly
    with ``FLIGHT_PITCH``; the generator's jumps without a limit (their data stay as they were).

    ``flight_track``: while no foot is down (a foot on the ground is not free to follow), the
    flight's PD drives each foot at its target's own velocity in the base frame, which the trunk's
    turning gives it, instead of damping the feet to rest there. A froggy flies turning nose down at
    2-3 rad/s, and a PD that damps the feet to rest in the trunk's frame leaves them kd/kp times
    that speed (1-2 cm) behind their level targets, deeper the faster the trunk turns: the jump
    touches down higher and earlier than planned. The planned jumps track; the generator's jumps
    do not (their data stay as they were).
    """

    def __init__(self, robot: str, params: FroggyParams, push: FroggyPushPolicy | None = None,
                 landing: str = "body", flight_pitch: float | None = None, flight_track: bool = False):
        if landing not in LANDINGS:
            raise ValueError(f"unknown froggy landing {landing!r}; choose from {', '.join(LANDINGS)}")
        if flight_pitch is not None and not (np.isfinite(flight_pitch) and flight_pitch > 0.0):
            raise ValueError(f"flight_pitch must be a positive angle in rad, got {flight_pitch}")
        self.flight_pitch = np.inf if flight_pitch is None else float(flight_pitch)
        self.flight_track = bool(flight_track)
        self.robot = robot
        self.params = params
        self.push = push
        self.landing = landing
        self._plumb_land = LANDINGS[landing]
        self.kin = leg_kinematics(robot)
        self.limit = np.asarray(get_robot(robot).torque_limit, dtype=float)  # (12,) N m
        # the description's actuator effects, fed forward (sim/controllers/actuators.py): the
        # legs' torques are then fitted into the limits with the losses, not before
        self.compensation = Compensation(robot)
        self._fit_at = np.full(self.limit.shape, np.inf) if self.compensation.active else self.limit
        self.feet0 = nominal_feet(robot) * [1.0, 1.0, 0.0]  # (4, 3) level-frame xy of each foot
        self.mass = 12.0  # kg, replaced by the world's true mass in reset
        self.phase = "settle"
        self.t_flight = None  # time the flight stage began
        self.t_land = None
        self._p0 = None  # (feet (4, 3), base (3,)) in the world when the push starts, m
        # the parameters and leg chains as ``compiled.froggy_torque`` takes them
        self._prm = np.array([float(getattr(params, n)) for n in compiled.FROGGY_PARAMS])
        self._chains = self.kin.chain_arrays()
        p = params
        self._t_push = p.t_settle + p.t_crouch + p.t_hold
        self._t_rear = self._t_push + p.t_push_all
        self._t_fly = self._t_rear + p.t_push_rear
        self._rear_off: float | None = None  # s: when a policy's rear-only push saw its rear feet leave
        # the jump's events (the public read-only properties)
        self._push_start: tuple[float, np.ndarray] | None = None
        self._liftoff: tuple[np.ndarray, np.ndarray] | None = None
        self._touchdown: tuple[float, np.ndarray] | None = None
        self._airborne = False

    @property
    def push_start(self) -> tuple[float, np.ndarray] | None:
        """t s and base position (3,) m at the push's first tick (four feet); None before."""
        return self._push_start

    @property
    def liftoff(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Base position (3,) m and velocity (3,) m/s at the first tick of the flight stage (the
        push ended); None before."""
        return self._liftoff

    @property
    def touchdown(self) -> tuple[float, np.ndarray] | None:
        """t s and base position (3,) m at the landing (the first tick a foot met the ground once
        the flight had lasted 0.05 s) if the robot flew (``airborne``); None before."""
        return self._touchdown

    @property
    def airborne(self) -> bool:
        """Whether some tick of the flight stage had no foot on the ground."""
        return self._airborne

    @property
    def timing(self) -> FroggyPushTiming:
        """The push's timing in force: the parameters', or the policy's from the push on."""
        return FroggyPushTiming(self._t_rear - self._t_push, self._t_fly - self._t_rear)

    # --------------------------------------------------------------- set-up
    def reset(self, world: World) -> np.ndarray:
        """Standing configuration (18,), base ``stand_height`` above the foot centres; holds
        the hx joints there unless ``params.hold_hx`` is off."""
        self.mass = world.mass
        if self.params.hold_hx:
            world.hold_joints([0, 3, 6, 9])
        return start_pose(self.robot, self.params.stand_height + get_robot(self.robot).foot_radius)

    def diagnostics(self) -> dict:
        return {}

    # -------------------------------------------------------------- control
    def _stage(self, s: RobotState) -> str:
        t, p = s.t, self.params
        if self.phase in ("flight", "land"):
            if self.phase == "flight" and s.t - self.t_flight > 0.05 and s.contact.any():
                self.phase, self.t_land = "land", s.t
            return self.phase
        if t < p.t_settle:
            return "settle"
        if t < p.t_settle + p.t_crouch:
            return "crouch"
        if t < self._t_push:
            return "hold"
        if t < self._t_rear:
            return "push_all"
        if t < self._t_fly:
            if self.push is None or s.contact[list(REAR)].any():
                self._rear_off = None
                return "push_rear"
            # a policy's push ends when its rear feet have left the ground: pushing on, its legs
            # swing in the air and turn the trunk (a loaded froggy's feet leave 12-16 ms early)
            self._rear_off = t if self._rear_off is None else self._rear_off
            if t - self._rear_off < FEET_OFF - 1e-9:
                return "push_rear"
            self._t_fly = t
        self.t_flight = t
        return "flight"

    def torque(self, s: RobotState) -> np.ndarray:
        """Joint torques (12,) N m for state ``s``.

        The stages above pick the targets; ``symrom.sim.controllers.compiled.froggy_torque`` does the
        arithmetic (it reads as ``torque_numpy``, the reference it is tested against).
        """
        if self.push is not None and self._push_start is None and self.phase not in ("flight", "land") \
                and s.t >= self._t_push:
            self._t_push = s.t  # the policy's push begins at this tick
            self._set_timing(self.push.start(s))
        was = self.phase
        self.phase = self._stage(s)
        self._events(s, was)
        stage = STAGES.index(self.phase)
        if self.phase in ("push_all", "push_rear") and self._p0 is None:
            self._p0 = (s.foot_pos.copy(), s.q[12:15].copy())
        if self.push is not None and self.phase in ("push_all", "push_rear"):
            cmd = self.push.command(s, s.t - self._t_push)
            if cmd.timing is not None:
                self._set_timing(cmd.timing)
            return self.push_torque(s, cmd.force, cmd.moment)
        feet_w, b0 = self._p0 if self._p0 is not None else (self.feet0, np.zeros(3))
        tau = compiled.froggy_torque(stage, float(s.t), self._prm, self._t_push,
                                     float(self.t_land if self.t_land is not None else 0.0), float(self.mass),
                                     s.q, s.dq, s.R, s.omega, s.contact, s.foot_pos, self.feet0, feet_w, b0,
                                     self._fit_at, self._plumb_land, self.flight_pitch, int(self.flight_track),
                                     *self._chains)
        if self.compensation.active:
            return self.compensation.scaled_legs(tau, s.dq[JOINTS], self.limit, self._planned_acceleration(s))
        return tau

    def _planned_acceleration(self, s: RobotState) -> np.ndarray | None:
        """The joint accelerations (12,) rad/s^2 the push plans for its stance legs, zero for
        the others (``stance_acceleration``: their feet leave the base at ``push_speed`` along the
        take-off line, so the joints speed up as the legs straighten); None outside the push or
        for a robot without armature."""
        if self.phase not in ("push_all", "push_rear") or not any(self.compensation.effects.armature):
            return None
        p = self.params
        v_feet = np.tile(-p.push_speed * np.array([np.sin(p.angle), 0.0, np.cos(p.angle)]), (N_LEGS, 1))
        legs = range(N_LEGS) if self.phase == "push_all" else REAR
        return stance_acceleration(self.kin, s.q[JOINTS], v_feet, legs)

    def _set_timing(self, timing: FroggyPushTiming) -> None:
        """A policy's timing: the push's parts end ``four`` and ``four + rear`` s after it began."""
        self._t_rear = self._t_push + float(timing.four)
        self._t_fly = self._t_rear + float(timing.rear)

    def _events(self, s: RobotState, was: str) -> None:
        """Book the jump's events on the stage this tick entered (no effect on the torques)."""
        now = self.phase
        if now in ("push_all", "push_rear") and self._push_start is None:
            self._push_start = (s.t, s.q[12:15].copy())
        if now == "flight" and was != "flight":
            self._liftoff = (s.q[12:15].copy(), s.dq[12:15].copy())
        if now == "flight" and not s.contact.any():
            self._airborne = True
        if now == "land" and was == "flight" and self._airborne:
            self._touchdown = (s.t, s.q[12:15].copy())

    def push_torque(self, s: RobotState, force: np.ndarray, moment: np.ndarray) -> np.ndarray:
        """Joint torques (12,) N m of a policy's push at state ``s`` (stage ``push_all`` or
        ``push_rear``): the feet down (all four, or the rear ones) get the forces of
        ``wrench_forces`` for ``force`` (3,) N and ``moment`` (3,) N m about the base (world),
        each within the friction pyramid ``PUSH_MU``, as tau = -J^T R^T f; in the rear-only
        part the front legs tuck as in the controller's own push (Cartesian PD, ``kp_swing``,
        ``kd_swing``). Each leg's torques are scaled together into the limits."""
        p = self.params
        qj, dqj = s.q[JOINTS], s.dq[JOINTS]
        pos, J = self.kin.one(qj)
        legs = tuple(range(N_LEGS)) if self.phase == "push_all" else REAR
        grf = wrench_forces(s.foot_pos, s.q[12:15], legs, np.asarray(force, float), np.asarray(moment, float),
                            mu=PUSH_MU)
        f = -(grf @ s.R)  # the force on the ground, base frame
        if self.phase == "push_rear":
            vel = np.einsum("kij,kj->ki", J, dqj.reshape(N_LEGS, 3))
            for k in FRONT:  # tuck up and forward, as the controller's own push
                target = self.feet0[k] + np.array([0.04, 0.0, -p.crouch_height + 0.04])
                f[k] = p.kp_swing * (target - pos[k]) - p.kd_swing * vel[k]
        tau = np.einsum("kji,kj->ki", J, f)
        over = np.max(np.abs(tau) / self.limit.reshape(N_LEGS, 3), axis=1, keepdims=True)
        return (tau / np.maximum(over, 1.0)).reshape(-1)

    def torque_numpy(self, s: RobotState) -> np.ndarray:
        """``torque`` in NumPy, the reference of the compiled arithmetic (the same stages)."""
        p = self.params
        self.phase = self._stage(s)
        qj, dqj = s.q[JOINTS], s.dq[JOINTS]
        pos, J = self.kin.one(qj)
        vel = np.einsum("kij,kj->ki", J, dqj.reshape(N_LEGS, 3))
        # Stance targets are body-fixed (their offsets give the body its attitude stiffness);
        # in flight they are level (yaw-only frame), so the legs hang plumb for landing.
        to_base = s.R.T @ yaw_matrix(s.q[17]) if self.phase == "flight" else np.eye(3)
        weight = self.mass * GRAVITY
        height = p.stand_height
        shift = 0.0
        kp = np.full(N_LEGS, p.kp_stance)
        kd = np.full(N_LEGS, p.kd_stance)
        grf = np.zeros((N_LEGS, 3))  # desired ground reaction per foot, world
        z_leg = np.full(N_LEGS, -height)
        x_off = np.zeros(N_LEGS)
        v_d = np.zeros((N_LEGS, 3))  # base-frame target velocity, m/s
        xy = p.xy_ratio
        base = s.q[12:15]
        # Roll/pitch regulation moment (world), fed forward through the stance feet.
        pitch_ref = 0.0
        if self.phase in ("crouch", "hold", "push_all"):
            pitch_ref = p.crouch_pitch * smooth((s.t - p.t_settle) / p.t_crouch)
        level = (-p.k_att * (s.R @ np.array([s.q[15], s.q[16] - pitch_ref, 0.0]))
                 - p.d_att * s.omega * [1, 1, 0])
        all_legs = tuple(range(N_LEGS))
        if self.phase in ("settle", "crouch", "hold"):
            if self.phase != "settle":
                a = smooth((s.t - p.t_settle) / p.t_crouch)
                z_leg[:] = -(p.stand_height + a * (p.crouch_height - p.stand_height))
                # Nose down (front legs shorter): the push's nose-up rotation then
                # passes through level near take-off.
                z_leg += a * p.crouch_pitch * self.feet0[:, 0]
                shift = a * p.crouch_shift
            grf = distribute(s.foot_pos, base, all_legs, np.array([0, 0, weight]), level)
        elif self.phase in ("push_all", "push_rear"):
            # The base tracks a straight take-off line in the world (up and forward at
            # push_speed, level attitude) while the stance feet stay where they are: the
            # foot targets are the planted feet seen from the desired base pose.
            if self._p0 is None:
                self._p0 = (s.foot_pos.copy(), base.copy())
            feet_w, b0 = self._p0
            yaw = yaw_matrix(s.q[17])
            direction = yaw @ np.array([np.sin(p.angle), 0.0, np.cos(p.angle)])
            b_d = b0 + p.push_speed * (s.t - self._t_push) * direction
            b_d[2] = min(b_d[2], b0[2] + p.push_rise)
            p_stroke = (feet_w - b_d) @ yaw  # level-frame offsets, rows: yaw^T (f - b_d)
            v_d[:] = -p.push_speed * np.array([np.sin(p.angle), 0.0, np.cos(p.angle)])
            # Kept in the desired (level) frame: attitude errors show up as foot errors.
            thrust = p.force_all * direction
            kp[:], kd[:] = p.kp_push, p.kd_push
            xy = 1.0
            if self.phase == "push_all":
                grf = distribute(s.foot_pos, base, all_legs, thrust, level)
            else:
                grf = distribute(s.foot_pos, base, REAR, p.force_rear / p.force_all * thrust, level)
                for k in FRONT:  # front feet tuck up and forward
                    z_leg[k], x_off[k] = -p.crouch_height + 0.04, 0.04
                    kp[k], kd[k] = p.kp_swing, p.kd_swing
                    v_d[k] = 0.0
        elif self.phase == "flight":
            kp[:], kd[:] = p.kp_swing, p.kd_swing
            # Raibert-style placement: land the feet ahead by the forward speed.
            x_off[:] = p.raibert * s.dq[12]
            pitch = s.q[16]
            excess = pitch - np.clip(pitch, -self.flight_pitch, self.flight_pitch)
            if excess != 0.0:  # the targets' frame pitched by the excess, the feet at the same depth
                ce, se = np.cos(excess), np.sin(excess)
                to_base = to_base @ np.array([[ce, 0.0, se], [0.0, 1.0, 0.0], [-se, 0.0, ce]])
                z_leg = (self.feet0[:, 2] - height + (self.feet0[:, 0] + x_off) * se) / ce - self.feet0[:, 2]
        else:  # land
            kp[:], kd[:] = p.kp_land, p.kd_land
            a = smooth((s.t - self.t_land) / 0.3)  # ramp the weight support in over 0.3 s
            down = tuple(int(k) for k in np.flatnonzero(s.contact))
            if down:
                grf = a * distribute(s.foot_pos, base, down, np.array([0, 0, weight]), level)
        targets_level = self.feet0 + np.stack([x_off + shift, np.zeros(N_LEGS), z_leg], axis=1)
        p_d = targets_level @ to_base.T
        if self.phase == "land" and self._plumb_land:
            pair = list(FRONT if s.q[16] > 0.0 else REAR)
            p_d[pair] = targets_level[pair] @ (s.R.T @ yaw_matrix(s.q[17])).T
        if self.phase in ("push_all", "push_rear"):
            stroke_legs = list(all_legs) if self.phase == "push_all" else list(REAR)
            p_d[stroke_legs] = p_stroke[stroke_legs]
        if self.phase == "flight" and self.flight_track and not s.contact.any():
            # the targets' frame turns with the yaw (and the pitch past flight_pitch), the trunk at omega
            yaw = yaw_matrix(s.q[17])
            w_yaw = yaw.T @ s.omega
            rel = np.array([-w_yaw[0], 0.0 if excess != 0.0 else -w_yaw[1], 0.0])
            v_d = np.cross(s.R.T @ (yaw @ rel), p_d)
            if excess != 0.0:  # past flight_pitch each target also reaches down as the excess grows
                dz = w_yaw[1] * (self.feet0[:, 0] + x_off + (self.feet0[:, 2] - height) * se) / ce ** 2
                v_d = v_d + dz[:, None] * to_base[:, 2]
        f_ff = -(grf @ s.R)  # force on the ground, in the base frame: -R^T grf
        # Softer horizontally in stance: lightly loaded feet would slip under stiff
        # horizontal springs, and horizontal forces below the CoM pitch the body.
        axis = np.array([xy, xy, 1.0])
        f = (kp[:, None] * axis) * (p_d - pos) + (kd[:, None] * axis) * (v_d - vel) + f_ff
        tau = np.einsum("kji,kj->ki", J, f)  # J^T f per leg
        if self.compensation.active:
            return self.compensation.scaled_legs(tau.reshape(-1), dqj, self.limit, self._planned_acceleration(s))
        # Scale each leg's torques together into the limits: clipping joints one by one
        # would turn the foot force (e.g. a push down becomes a push backwards).
        over = np.max(np.abs(tau) / self.limit.reshape(N_LEGS, 3), axis=1, keepdims=True)
        tau = tau / np.maximum(over, 1.0)
        return tau.reshape(-1)

    def done(self, s: RobotState) -> bool:
        """True once the robot has stood for ``t_after_land`` s after touch-down."""
        return self.t_land is not None and s.t - self.t_land >= self.params.t_after_land


@dataclass(frozen=True)
class FroggyChecks:
    """Froggy's own check: min_rear_only s on the rear feet alone right before the flight."""

    min_rear_only: float = 0.04


@dataclass(frozen=True)
class FroggyMotion(PlainMotion):
    """The froggy plug-in (registry entry ``froggy``): rear-only push right before the flight;
    variant ``randomized``: domain-randomised source jumps (``sample_randomized``); ``proxy``: a
    real froggy's jumps on a hardware-like robot (``sample_real``)."""

    checks: FroggyChecks = FroggyChecks()

    def sample_params(self, rng: np.random.Generator, robot: str, variant: str | None,
                      dataset_rng: np.random.Generator | None = None) -> FroggyParams:
        if variant == "proxy":  # one robot per dataset, as pronk's proxy
            return sample_real(rng, robot, sample_robot(dataset_rng) if dataset_rng is not None else None)
        return sample_randomized(rng, robot) if variant == "randomized" else sample_params(rng, robot)

    def source(self, params: FroggyParams) -> str:
        return "sim" if params.proxy is None or params.randomized else "proxy"

    def make_controller(self, robot: str, params: FroggyParams, mpc_solver: str = "osqp") -> FroggyController:
        """A froggy controller (a Cartesian PD: no MPC, ``mpc_solver`` is not used)."""
        return FroggyController(robot, params)

    def check(self, log: dict[str, np.ndarray], dt: float, checks) -> list[str]:
        """One main flight (``PlainMotion``) and at least ``self.checks.min_rear_only`` s on
        the rear feet alone right before it."""
        bad = super().check(log, dt, checks)
        contact = log["contact"]
        airborne = contact.sum(axis=1) == 0
        if not airborne.any():
            return bad  # the common checks report the missing flight
        a = longest_run(airborne)[0]
        rear_only = (contact[:, 0] == 0) & (contact[:, 1] == 0) & (contact[:, 2:].sum(axis=1) > 0)
        n = 0
        while a - n - 1 >= 0 and rear_only[a - n - 1]:
            n += 1
        if n * dt < self.checks.min_rear_only - 1e-9:
            bad.append(f"rear-only contact {n * dt:.3f} s before flight")
        return bad


MOTION = FroggyMotion()
