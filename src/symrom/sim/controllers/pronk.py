"""Go1 forward pronking under convex MPC: crouch, push-off, flight, landing, settle.

How the controller works. A jump is a fixed sequence of phases driven by the
time since reset and by the contact flags. (1) *Crouch*: from the standing pose
the base is lowered to ``crouch_height`` along a cosine profile. (2) *Push*:
the base follows a constant-acceleration reference from rest at the crouch to
the take-off height, reaching the take-off velocity ``(vx, vz)`` that gives a
ballistic flight with the commanded apex height and a total forward travel of
the commanded distance (``plan_jump``); the MPC's contact schedule turns all
four feet off at the planned take-off time, so the plan already holds the
ballistic start. In both phases a convex single-rigid-body MPC
(``symrom.sim.controllers.mpc``, OSQP, 10 steps of 25 ms, solved at ``mpc_hz``) computes
the ground-reaction forces ``f`` of the four feet (world frame); they become
joint torques ``tau = -J^T R^T f`` (leg Jacobian ``J`` from the URDF
kinematics in the base frame, ``R`` base -> world), plus the torques that hold
the legs' own weight (``LegGravity``: the MPC's legs are massless, Go1's are
not) and a small joint-space PD holding the hip abduction and damping the legs.
The MPC's body inertia is that of the parts turning with the trunk while the
feet are planted (``BodyModel.inertia_upper``); with the whole robot's inertia
the roll loop oscillates. (3) *Flight*: joint PD to a landing posture, feet
under the hips and shifted forward in proportion to the forward speed so that
the landing forces brake the body. (4) *Landing*: from the first touchdown the
MPC tracks a critically damped reference that takes the base from its
touchdown height and velocity to the standing height at rest, while a
Cartesian impedance per leg (spring towards the reference leg length, damping
of the foot velocity relative to the body) softens the impact and holds legs
that have not touched down yet. (5) *Settle*: ``done`` turns true once the
landing has lasted ``settle_time`` and the base is nearly at rest.

Any robot. The gains and the jump's heights were tuned on the Go1; for another
robot they are scaled by its mass and leg length relative to the Go1's
(``scales``, ``PronkGains.scaled``): heights and distances with leg length,
forces with mass, joint stiffness and damping with mass x length, Cartesian
stiffness with mass / length, times of the landing reference with the square
root of length. For the Go1 both ratios are exactly 1. A robot whose description states
actuator effects (joint damping, friction loss, armature) gets every torque plus what they take
at the measured joint speeds, within the limits (``symrom.sim.controllers.actuators``).

A push policy. ``PronkController(..., push=policy)`` hands the push to a
``PushPolicy`` in place of the MPC: called once when the push is due and then at
every tick of the push with the measured state, it commands the summed ground
force on the feet and its moment about the CoM (``PushCommand``), and says when
the push ends and what flight follows (``PushTiming``); it may re-plan at any
tick. The pronk turns the command into joint torques through massless legs
(``push_torque``) and runs its own flight and landing after it, handing over as
its own push does: its MPC's forces end about ``release_time`` (20 ms) before its
flight, the feet leave the ground in between with the legs held without ground
force (their weight and the stance posture terms), and the flight's joint PD
starts with the feet already off. A policy's push is followed by the same hold
for ``release_time``; with the flight's PD started at the push's end instead, it
would swing the legs towards the landing posture while the feet are still down.
The jump's
events (``push_start``, ``liftoff``, ``touchdown``) and ``phase`` are public,
read-only. ``symrom.plan.execute`` runs a planned jump this way.

Use: ``MOTION`` is the plug-in generation drives (``symrom.sim.controllers.motion``)::

    params = sample_params(rng, proxy=False, robot="go1")   # PronkParams
    ctrl = PronkController("go1", params)
    world.reset(ctrl.reset(world))
    while not ctrl.done(s := world.state()):
        applied = world.step(ctrl.torque(s))      # one 1 kHz tick
    np.median(ctrl.mpc_solve_times)               # s, for the benchmark

A Go1 jump lasts about 1.4-1.5 s (crouch and push ~0.6 s, flight ~0.25 s,
landing and settling >= 0.6 s), i.e. ~730 samples at 500 Hz.
Units: m, s, rad, N, N m. ``RobotState`` as in ``symrom.sim.engines.world``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

import numpy as np

from symrom.names import BASE_POS, BASE_RPY, GRAVITY, JOINTS, N_JOINTS, N_LEGS
from symrom.robots import get_robot, leg_kinematics
from symrom.robots.compiled import legs_one
from symrom.robots.stance import leg_length, standing_joints, start_pose
from symrom.sim.controllers.actuators import Compensation
from symrom.sim.controllers.body import LegGravity, body_model
from symrom.sim.controllers.compiled import pronk_stance_torque as stance_torque
from symrom.sim.controllers.motion import PlainMotion, PushCommand
from symrom.sim.controllers.mpc import ConvexMPC, MPCConfig, rot_z, srb_state
from symrom.sim.engines.world import RobotState, World
from symrom.sim.proxy import RANDOMIZED_RANGES, ProxyConfig, sample_proxy, sample_robot

REFERENCE_ROBOT = "go1"  # the robot the gains and heights were tuned on


@dataclass
class PronkParams:
    """One forward pronking jump.

    distance: commanded forward travel of the base from start to rest, m;
    apex_height: commanded base height at the top of the flight, m;
    crouch_height / takeoff_height: base heights at the bottom of the crouch
    and at lift-off, m; crouch_time: standing -> crouched, s; hold_time: pause
    in the crouch, s; settle_time: minimum time after touchdown before the
    jump may be done, s; max_time: the jump is done at the latest then, s;
    yaw: heading, rad; pitch: body pitch the MPC holds through crouch and push
    (rad, positive nose down; 0 level); proxy: hardware-like perturbations
    (``source = proxy``), or the randomised world of a ``randomized`` jump, or None
    for the nominal simulator; randomized: a domain-randomised source jump
    (``source = sim``).
    """

    distance: float = 0.25
    apex_height: float = 0.43
    crouch_height: float = 0.21
    takeoff_height: float = 0.33
    crouch_time: float = 0.40
    hold_time: float = 0.05
    settle_time: float = 0.60
    max_time: float = 3.0
    yaw: float = 0.0
    proxy: ProxyConfig | None = None
    pitch: float = 0.0
    randomized: bool = False


@dataclass
class PronkGains:
    """Controller gains and rates.

    mpc: MPC settings; mpc_hz: MPC solve rate, Hz; kp/kd_flight: joint PD in
    flight (N m/rad, N m s/rad); kp/kd_hx: stance hip-abduction PD; kd_stance:
    stance joint damping; k/d_land: landing Cartesian impedance (N/m, N s/m);
    foot_forward: landing foot placement ahead of the hip per forward speed, s;
    land_omega: bandwidth of the landing reference, rad/s; brake_time: time
    constant of the forward braking after touchdown, s; takeoff_boost: factor on
    the push reference's take-off velocity, making up for the lag of the real
    (leg-inertia-laden) robot behind the single-rigid-body plan.
    """

    mpc: MPCConfig = field(default_factory=MPCConfig)
    mpc_hz: float = 100.0
    kp_flight: float = 30.0
    kd_flight: float = 0.5
    kp_hx: float = 20.0
    kd_hx: float = 0.4
    kd_stance: float = 0.15
    k_land: float = 400.0
    d_land: float = 6.0
    foot_forward: float = 0.06
    land_omega: float = 6.0
    brake_time: float = 0.12
    takeoff_boost: float = 1.2

    @classmethod
    def scaled(cls, mass: float, length: float) -> PronkGains:
        """The Go1's gains for a robot ``mass`` times as heavy with legs ``length`` times as long."""
        g, root = cls(), np.sqrt(length)
        ml = mass * length
        return cls(mpc=MPCConfig(fz_max=g.mpc.fz_max * mass, alpha=g.mpc.alpha / mass ** 2),
                   mpc_hz=g.mpc_hz, kp_flight=g.kp_flight * ml, kd_flight=g.kd_flight * ml,
                   kp_hx=g.kp_hx * ml, kd_hx=g.kd_hx * ml, kd_stance=g.kd_stance * ml,
                   k_land=g.k_land * mass / length, d_land=g.d_land * mass / root,
                   foot_forward=g.foot_forward * root, land_omega=g.land_omega / root,
                   brake_time=g.brake_time * root, takeoff_boost=g.takeoff_boost)


def scales(robot: str) -> tuple[float, float]:
    """(mass, leg length) of ``robot`` as ratios to the Go1's; exactly (1, 1) for the Go1."""
    ref = REFERENCE_ROBOT
    return (get_robot(robot).mass / get_robot(ref).mass, leg_length(robot) / leg_length(ref))


@dataclass(frozen=True)
class PronkRanges:
    """Uniform ranges (low, high) of a ``randomized`` jump's motion, for the Go1 (lengths
    scale with the leg length): distance, apex_height, crouch_height, takeoff_height m;
    crouch_time, hold_time s (the take-off timing); pitch rad. Wide enough to cover what a
    real controller's jumps do: the nominal jumps' ranges and beyond on every side."""

    distance: tuple[float, float] = (0.05, 0.5)
    apex_height: tuple[float, float] = (0.395, 0.47)
    crouch_height: tuple[float, float] = (0.195, 0.235)
    takeoff_height: tuple[float, float] = (0.315, 0.345)
    crouch_time: tuple[float, float] = (0.28, 0.55)
    hold_time: tuple[float, float] = (0.0, 0.15)
    pitch: tuple[float, float] = (-0.1, 0.1)


RANDOMIZED_MOTION = PronkRanges()


def sample_params(rng: np.random.Generator, proxy: bool = False, robot: str = REFERENCE_ROBOT,
                  randomized: bool = False, proxy_robot: ProxyConfig | None = None) -> PronkParams:
    """A random jump: for the Go1 a distance of 0.1-0.4 m, apex 0.41-0.45 m, small
    crouch/timing spread; lengths scale with the robot's leg length (``scales``).

    With ``proxy`` the hardware-like perturbations are drawn too (see
    ``symrom.sim.proxy``): the hardware constants of ``proxy_robot`` (``proxy.sample_robot``,
    one per dataset) and the per-jump rest; without ``proxy_robot`` all per jump.
    ``randomized``: domain randomisation of source data, the motion from
    ``RANDOMIZED_MOTION`` and the world from ``proxy.RANDOMIZED_RANGES`` (all per jump).
    """
    length = scales(robot)[1]
    if randomized:
        r, u = RANDOMIZED_MOTION, rng.uniform
        return PronkParams(
            distance=float(u(*r.distance)) * length, apex_height=float(u(*r.apex_height)) * length,
            crouch_height=float(u(*r.crouch_height)) * length,
            takeoff_height=float(u(*r.takeoff_height)) * length,
            crouch_time=float(u(*r.crouch_time)), hold_time=float(u(*r.hold_time)), pitch=float(u(*r.pitch)),
            proxy=sample_proxy(rng, RANDOMIZED_RANGES), randomized=True)
    return PronkParams(
        distance=float(rng.uniform(0.1, 0.4)) * length,
        apex_height=float(rng.uniform(0.41, 0.45)) * length,
        crouch_height=float(rng.uniform(0.205, 0.225)) * length,
        takeoff_height=PronkParams.takeoff_height * length,
        crouch_time=float(rng.uniform(0.35, 0.45)),
        proxy=sample_proxy(rng, robot=proxy_robot) if proxy else None,
    )


@dataclass(frozen=True)
class JumpPlan:
    """Derived jump timing (s) and take-off velocity (m/s) of a ``PronkParams``."""

    t_push: float
    push_time: float
    vx: float
    vz: float
    flight_time: float


def plan_jump(params: PronkParams, brake_time: float, boost: float = 1.0) -> JumpPlan:
    """Take-off velocity and timing that realise the commanded apex and distance.

    vz from the apex above the take-off height; push at constant acceleration
    from the crouch; vx so that the base travels the commanded distance over
    half the push (mean speed vx/2), the flight (landing at take-off height)
    and the exponential braking after touchdown (vx * brake_time). ``boost``
    scales the take-off velocity of the reference (not the timing).
    """
    dz = params.takeoff_height - params.crouch_height
    vz = np.sqrt(2.0 * GRAVITY * max(params.apex_height - params.takeoff_height, 1e-3))
    push_time = 2.0 * dz / vz
    flight_time = 2.0 * vz / GRAVITY
    vx = params.distance / (0.5 * push_time + flight_time + brake_time)
    return JumpPlan(t_push=params.crouch_time + params.hold_time, push_time=push_time,
                    vx=float(boost * vx), vz=float(boost * vz), flight_time=float(flight_time))


def release_time(gains: PronkGains) -> float:
    """s from the end of the ground force to the flight's joint PD in the pronk's own push (20 ms
    for the Go1): its MPC plans the feet off from one step (``mpc.dt``) before the take-off, so
    its forces end at the first solve (every 1 / ``mpc_hz`` s) within that step, half a solve
    period into it on average (docs/benchmarks.md has what its jumps do)."""
    return gains.mpc.dt - 0.5 / gains.mpc_hz


@dataclass(frozen=True)
class PushTiming:
    """The push a ``PushPolicy`` means to make: duration s from its first tick to its end (where
    its ground force ends: the plan's lift-off), the lift-off velocity vx (along the heading) and
    vz (up), m/s, and flight_time s, lift-off to touchdown (the pronk waits for a touchdown at
    most 0.4 s longer)."""

    duration: float
    vx: float
    vz: float
    flight_time: float


@runtime_checkable
class PushPolicy(Protocol):
    """What drives the pronk's push in place of its MPC (``PronkController(push=...)``).

    ``start`` is called once, at the first tick of the push (the crouch and hold are over),
    with the measured state; then ``command`` at every tick of the push, from that first one
    (``since`` = 0), with the measured state and the time since the push began. Either may
    plan; ``command`` may re-plan the rest of the push at any tick (a closed loop), its
    ``PushCommand.timing`` then moving the push's end. The push ends at the first tick
    ``duration`` s or more after it began; the pronk holds the legs without ground force for
    ``release_time`` s (module docstring), then its flight and landing follow.
    """

    def start(self, state: RobotState) -> PushTiming:
        """The push's timing, planned from the measured ``state`` at its first tick."""

    def command(self, state: RobotState, since: float) -> PushCommand:
        """The command for this tick of the push, ``since`` s after it began."""


def heading(yaw: float) -> np.ndarray:
    """(3,) horizontal unit vector, world, of the heading ``yaw`` rad."""
    return np.array([np.cos(yaw), np.sin(yaw), 0.0])


def distribute_wrench(F: np.ndarray, M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Least-norm foot forces (4, 3) N summing to F (3,) N with moment M (3,) N m about the
    point the lever arms r (4, 3) m start from: the minimum-norm solution of
    [I ... I; [r_k]x ...] f = [F; M]."""
    A = np.zeros((6, 3 * N_LEGS))
    for k in range(N_LEGS):
        x, y, z = r[k]
        A[:3, 3 * k:3 * k + 3] = np.eye(3)
        A[3:, 3 * k:3 * k + 3] = [[0, -z, y], [z, 0, -x], [-y, x, 0]]
    return np.linalg.lstsq(A, np.concatenate([F, M]), rcond=None)[0].reshape(N_LEGS, 3)


class PronkController:
    """Forward-pronking controller of one jump; see the module docstring.

    ``torque(state)`` -> (12,) N m is called every physics tick; ``done(state)``
    is true once the robot has settled after landing (or at ``max_time``).
    push: a ``PushPolicy`` driving the push in place of the MPC, or None.
    Read-only: ``phase`` (``crouch``, ``push``, ``flight``, ``land``), the jump's
    events ``push_start``, ``liftoff``, ``touchdown`` and ``airborne``, its
    ``heading``; ``plan`` (``JumpPlan``) is the timing in force (a push policy's
    from the push on); ``mpc_solve_times`` (list, s) are the wall times of all
    MPC solves so far.
    """

    def __init__(self, robot: str, params: PronkParams, gains: PronkGains | None = None,
                 push: PushPolicy | None = None):
        self.robot, self.spec, self.params = robot, get_robot(robot), params
        self.push = push
        self.gains = gains or PronkGains.scaled(*scales(robot))
        self.body = body_model(robot)
        self.kin = leg_kinematics(robot)
        self._chains = self.kin.chain_arrays()
        self._p_b, self._J = np.empty((N_LEGS, 3)), np.empty((N_LEGS, 3, 3))  # filled every tick
        self.mpc = ConvexMPC(self.body.mass, self.body.inertia_upper, self.gains.mpc)
        self.leg_gravity = LegGravity(robot)
        self.plan = plan_jump(params, self.gains.brake_time, self.gains.takeoff_boost)
        self.torque_limit = np.asarray(self.spec.torque_limit, dtype=float)
        # the description's actuator effects, fed forward (sim/controllers/actuators.py); the
        # torques before it are clipped at infinity, after it at the limits
        self.compensation = Compensation(robot)
        self._clip_at = np.full(N_JOINTS, np.inf) if self.compensation.active else self.torque_limit
        self._phase = "crouch"
        self._x0: np.ndarray | None = None  # base position at the first call
        self._forces = np.zeros((N_LEGS, 3))
        self._last_solve = -np.inf
        self._t_td: float | None = None
        self._td_state: tuple[np.ndarray, np.ndarray] | None = None
        self._land_z: tuple[float, float, float] | None = None  # the landing height's terms, kept at touchdown
        # the jump's events (the public read-only properties)
        self._push_start: tuple[float, np.ndarray] | None = None
        self._liftoff: tuple[np.ndarray, np.ndarray] | None = None
        self._touchdown: tuple[float, np.ndarray] | None = None
        self._airborne = False
        self._zero_tau = np.zeros(N_JOINTS)  # no leg-weight torque in a policy's push
        # posture terms per joint (3, 12): kp (hip abduction only), kd, standing angles
        self._posture = np.stack([np.tile([self.gains.kp_hx, 0.0, 0.0], N_LEGS),
                                  np.tile([self.gains.kd_hx, self.gains.kd_stance, self.gains.kd_stance], N_LEGS),
                                  standing_joints(robot)])
        self._q_land: np.ndarray | None = None
        # a policy's push: how long the legs are held without ground force between its end and
        # the flight (``release``), s; none in the pronk's own jumps
        self._release = release_time(self.gains) if push is not None else 0.0
        # fixed parts of the references: heading (3,), take-off velocity (3,) m/s, CoM offset
        # from the base origin for a level body at the commanded heading (3,) m, world
        self._e = heading(params.yaw)
        self._v_to = self.plan.vx * self._e + np.array([0.0, 0.0, self.plan.vz])
        self._off_ref = rot_z(params.yaw) @ self.body.com_base
        self._p_crouch = self._p_to = None  # bottom of the crouch and take-off point (3,) m, set with _x0

    @property
    def mpc_solve_times(self) -> list[float]:
        return self.mpc.solve_times

    @property
    def phase(self) -> str:
        """The current phase: ``crouch`` (with the hold), ``push``, ``flight`` or ``land``."""
        return self._phase

    @property
    def push_start(self) -> tuple[float, np.ndarray] | None:
        """t s and base position (3,) m at the push's first tick; None before."""
        return self._push_start

    @property
    def liftoff(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Base position (3,) m and velocity (3,) m/s at the tick the push ended; None before."""
        return self._liftoff

    @property
    def touchdown(self) -> tuple[float, np.ndarray] | None:
        """t s and base position (3,) m at the first tick a foot met the ground after the robot
        flew (``airborne``); None before, and for a flight that ended on its time-out or on a
        foot that never left the ground (no landing)."""
        return self._touchdown

    @property
    def airborne(self) -> bool:
        """Whether some tick of the flight phase had no foot on the ground."""
        return self._airborne

    @property
    def heading(self) -> np.ndarray:
        """(3,) unit vector of the jump's heading (``params.yaw``), world, horizontal."""
        return self._e.copy()

    def reset(self, world: World) -> np.ndarray:
        """The start pose (18,): standing at the start height, heading ``params.yaw``."""
        return start_pose(self.robot, yaw=self.params.yaw)

    def diagnostics(self) -> dict:
        """Wall times (s) of all MPC solves so far."""
        return {"mpc_solve_times": [float(x) for x in self.mpc_solve_times]}

    # -------------------------------------------------------------- references
    def _references(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Reference base positions (h, 3) m, velocities (h, 3) m/s and planned contact (h,)
        (0/1) at the MPC's steps after t: t + k dt, k = 1..h. Squares are taken of Python
        floats, as ever (``x ** 2`` is libm's pow there, not NumPy's x * x)."""
        cfg, pr, pl = self.gains.mpc, self.params, self.plan
        h = cfg.horizon
        times = [t + (k + 1) * cfg.dt for k in range(h)]
        ts = np.array(times)
        if self._phase == "land" and self._t_td is not None:
            pos, vel = self._ref_land(np.maximum(ts - self._t_td, 0.0))
            return pos, vel, np.ones(h)
        x0, e, v_to = self._x0, self._e, self._v_to
        pos, vel, contact = np.empty((h, 3)), np.zeros((h, 3)), np.ones(h)
        # The times increase, so each phase is a run of steps: crouch [0, n_c), hold [n_c, n_h),
        # push [n_h, n_p), flight [n_p, h) (the same steps and numbers as masks of ts would give).
        taus = [x - pl.t_push for x in times]
        n_c = sum(x < pr.crouch_time for x in times)
        n_h = max(n_c, sum(x < pl.t_push for x in times))
        n_p = max(n_h, sum(x < pl.push_time for x in taus))
        if n_c:  # cosine from standing height down to the crouch
            x = np.pi * ts[:n_c] / pr.crouch_time
            s = 0.5 * (1 - np.cos(x))
            ds = 0.5 * np.pi / pr.crouch_time * np.sin(x)
            h0, h1 = self.spec.start_height, pr.crouch_height
            pos[:n_c, 0], pos[:n_c, 1], pos[:n_c, 2] = x0[0], x0[1], h0 + (h1 - h0) * s
            vel[:n_c, 2] = (h1 - h0) * ds
        pos[n_c:n_h] = x0[0], x0[1], pr.crouch_height
        if n_p > n_h:  # constant acceleration from rest
            a = np.array([0.5 * x ** 2 / pl.push_time for x in taus[n_h:n_p]])
            pos[n_h:n_p] = self._p_crouch + a[:, None] * v_to
            vel[n_h:n_p] = (np.array(taus[n_h:n_p]) / pl.push_time)[:, None] * v_to
        if n_p < h:  # ballistic
            tf = np.array(taus[n_p:]) - pl.push_time
            rise = np.zeros((tf.size, 3))
            rise[:, 2] = [pl.vz * x - 0.5 * GRAVITY * x ** 2 for x in tf.tolist()]
            pos[n_p:] = self._p_to + (pl.vx * tf)[:, None] * e + rise
            fall = np.zeros((tf.size, 3))
            fall[:, 2] = pl.vz - GRAVITY * tf
            vel[n_p:] = pl.vx * e + fall
            contact[n_p:] = 0.0
        return pos, vel, contact

    def _ref_land(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Critically damped return from the touchdown state to rest at the standing height:
        positions and velocities (n, 3) at the times tau (n,) s after touchdown."""
        g = self.gains
        p_td, v_td = self._td_state
        # horizontal: exponential braking, v = v_td exp(-tau / brake_time)
        decay = np.exp(-tau / g.brake_time)[:, None]
        pos = p_td + v_td * g.brake_time * (1 - decay)
        vel = v_td * decay
        pos[:, 2], vel[:, 2] = self._ref_land_z(tau)
        return pos, vel

    def _ref_land_z(self, tau):
        """Vertical part of ``_ref_land`` tau s (float or array) after touchdown: height m and
        speed m/s, critically damped from (z_td, vz_td) to the standing height (the terms kept
        at touchdown, ``_land_z``)."""
        w = self.gains.land_omega
        z_f, a0, b0 = self._land_z
        ew = np.exp(-w * tau)
        return z_f + (a0 + b0 * tau) * ew, (b0 - w * (a0 + b0 * tau)) * ew

    def _ref_land_height(self, tau: float) -> float:
        """The height m of ``_ref_land_z`` at one time tau s after touchdown, the same number in
        Python's floats (the touchdown's terms kept from the touchdown on, ``_land_z``)."""
        z_f, a0, b0 = self._land_z
        ew = float(np.exp(-self.gains.land_omega * tau))
        return z_f + (a0 + b0 * tau) * ew

    # ------------------------------------------------------------------ control
    def _mpc_forces(self, state, contact_now: np.ndarray) -> np.ndarray:
        """Solve the MPC for the current state; (4, 3) N, world, ground on foot."""
        cfg = self.gains.mpc
        off = state.R @ self.body.com_base
        p_com = state.q[BASE_POS] + off
        (w0, w1, w2), (o0, o1, o2) = state.omega.tolist(), off.tolist()  # omega x off, as np.cross
        v_com = state.dq[BASE_POS] + np.array([w1 * o2 - w2 * o1, w2 * o0 - w0 * o2, w0 * o1 - w1 * o0])
        x0 = srb_state(state.q[BASE_RPY], p_com, state.omega, v_com, GRAVITY)
        # keep the yaw reference continuous with the measured yaw
        yaw_ref = self.params.yaw
        x_ref = np.zeros((cfg.horizon, 13))  # srb_state of the references: level, not turning
        x_ref[:, 2], x_ref[:, 12] = yaw_ref, GRAVITY
        if self.params.pitch and self._phase in ("crouch", "push"):
            x_ref[:, 1] = self.params.pitch
        pos, vel, c = self._references(state.t)
        x_ref[:, 3:6], x_ref[:, 9:12] = pos + self._off_ref, vel
        contact = np.empty((cfg.horizon, N_LEGS))
        contact[:] = c[:, None]
        contact[0] = np.minimum(contact[0], contact_now)
        if self._phase == "land":
            contact[:] = np.maximum(contact, contact_now)  # feet already down stay down
        r_feet = state.foot_pos - p_com
        return self.mpc.solve(x0, x_ref, r_feet, contact, yaw=yaw_ref).forces

    def _update_phase(self, state) -> None:
        pl = self.plan
        t = state.t
        if self._phase == "crouch" and t >= pl.t_push:
            self._phase = "push"
            self._push_start = (t, state.q[BASE_POS].copy())
        if self._phase == "push" and t >= pl.t_push + pl.push_time + self._release:
            self._phase = "flight"
            self._q_land = None
            if self._liftoff is None:
                self._liftoff = (state.q[BASE_POS].copy(), state.dq[BASE_POS].copy())
        if self._phase == "flight":
            since = t - (pl.t_push + pl.push_time + self._release)
            if (np.count_nonzero(state.contact) and since > 0.05) or since > pl.flight_time + 0.4:
                self._phase = "land"
                self._t_td = t
                self._td_state = (state.q[BASE_POS].copy(), state.dq[BASE_POS].copy())
                # the landing height's terms (``_ref_land_z``): the standing height less 1 cm, and
                # the touchdown's offset from it and rate, critically damped at land_omega
                z_f = self.spec.start_height - 0.01
                a0 = float(self._td_state[0][2]) - z_f
                self._land_z = (z_f, a0, float(self._td_state[1][2]) + self.gains.land_omega * a0)
                self._last_solve = -np.inf

    def _start_push(self, state: RobotState) -> None:
        """The policy's push begins at this tick: its timing replaces the plan's from now on."""
        self._phase = "push"
        self._push_start = (state.t, state.q[BASE_POS].copy())
        self._set_timing(state.t, self.push.start(state))

    def _set_timing(self, t_push: float, timing: PushTiming) -> None:
        self.plan = JumpPlan(t_push=t_push, push_time=timing.duration, vx=float(timing.vx), vz=float(timing.vz),
                             flight_time=timing.flight_time)

    def torque(self, state) -> np.ndarray:
        """Joint torques (12,) N m for ``state`` (a ``RobotState``), within the torque limits."""
        if self._x0 is None:
            x0 = self._x0 = state.q[BASE_POS].copy()
            self._p_crouch = np.array([x0[0], x0[1], self.params.crouch_height])
            self._p_to = self._p_crouch + 0.5 * self.plan.push_time * self._v_to
        if self.push is not None:
            if self._phase == "crouch" and state.t >= self.plan.t_push:
                self._start_push(state)
            if self._phase == "push" and state.t < self.plan.t_push + self.plan.push_time:
                cmd = self.push.command(state, state.t - self.plan.t_push)
                if cmd.timing is not None:
                    self._set_timing(self.plan.t_push, cmd.timing)
                return self.push_torque(state, cmd.force, cmd.moment)
            if self._phase == "push" and state.t < self.plan.t_push + self.plan.push_time + self._release:
                if self._liftoff is None:  # the push's force ended at this tick
                    self._liftoff = (state.q[BASE_POS].copy(), state.dq[BASE_POS].copy())
                return self._released_torque(state)
        was_flight = self._phase == "flight"
        if was_flight and not np.count_nonzero(state.contact):
            self._airborne = True
        self._update_phase(state)
        if (was_flight and self._phase == "land" and self._touchdown is None and self._airborne
                and np.count_nonzero(state.contact)):
            self._touchdown = (state.t, state.q[BASE_POS].copy())
        g = self.gains
        if self._phase == "flight":
            tau = self._flight_pd(state)
            if self.compensation.active:
                return self.compensation.clipped(tau, state.dq[JOINTS], self.torque_limit)
            return np.minimum(np.maximum(tau, -self.torque_limit), self.torque_limit)
        qj, dqj = state.q[JOINTS], state.dq[JOINTS]
        p_b, J = self._p_b, self._J  # feet (4, 3) m and leg Jacobians (4, 3, 3), base frame
        legs_one(qj, *self._chains, p_b, J)
        if state.t - self._last_solve >= 1.0 / g.mpc_hz - 1e-9:
            contact = np.ones(N_LEGS) if self._phase in ("crouch", "push") else state.contact.astype(float)
            self._forces = self._mpc_forces(state, contact)
            self._last_solve = state.t
        f_base = -(self._forces @ state.R)  # force the foot exerts, base frame (rows R^T f)
        tau_g = self.leg_gravity.torques(qj, state.R)
        land = self._phase == "land"
        if land:
            # Cartesian impedance per leg in the base frame: spring along the base z axis
            # towards the reference leg length, damping of the foot velocity relative to the
            # base; legs still in the air also get a spring holding their landing x and y.
            h_ref = self._ref_land_height(max(state.t - self._t_td, 0.0)) - self.body.foot_radius
            p_land = self._p_land if self._q_land is not None else p_b
        else:
            h_ref, p_land = 0.0, p_b  # unused
        # J^T f + legs' weight (+ landing impedance, damping the feet's velocities relative to the
        # base, J dq) + posture terms (hold hip abduction with kp_hx, kd_hx; damp the legs with
        # kd_stance), clipped: one compiled call
        tau = np.empty(N_JOINTS)
        stance_torque(J, f_base, tau_g, land, p_b, p_land, state.contact, h_ref, g.k_land, g.d_land,
                      self._posture, qj, dqj, self._clip_at, tau)
        if self.compensation.active:
            return self.compensation.clipped(tau, dqj, self.torque_limit)
        return tau

    def push_torque(self, state: RobotState, force: np.ndarray, moment: np.ndarray) -> np.ndarray:
        """Joint torques (12,) N m, within the limits, whose ground force through massless legs is
        ``force`` (3,) N with ``moment`` (3,) N m about the CoM (world): a push policy's command.

        The pronk's stance joint PD (hip abduction held, legs damped) stays on; the foot forces
        are the least-norm ones (``distribute_wrench``) that sum to ``force`` less the force the
        PD's torques stand for, with ``moment`` about the CoM, and become tau = -J^T R^T f. A
        model's input is the ground force derived from all joint torques through massless legs
        (``symrom.data.preprocess``), so no leg-weight torque is added."""
        qj, dqj = state.q[JOINTS], state.dq[JOINTS]
        p_b, J = self._p_b, self._J
        legs_one(qj, *self._chains, p_b, J)
        kp, kd, q_stand = self._posture
        tau_pd = (kp * (q_stand - qj) - kd * dqj).reshape(N_LEGS, 3)
        G = sum(state.R @ -np.linalg.solve(J[k].T, tau_pd[k]) for k in range(N_LEGS))
        p_com = state.q[BASE_POS] + state.R @ self.body.com_base
        f = distribute_wrench(force - G, moment, state.foot_pos - p_com)
        return self._stance_off_landing(state, J, p_b, -(f @ state.R), self._zero_tau)

    def _released_torque(self, state: RobotState) -> np.ndarray:
        """Joint torques (12,) N m of the pronk's stance with no ground force: what its own push
        commands once its MPC's schedule has the feet off (the legs' weight held, the stance
        posture terms), within the limits."""
        qj = state.q[JOINTS]
        p_b, J = self._p_b, self._J
        legs_one(qj, *self._chains, p_b, J)
        return self._stance_off_landing(state, J, p_b, np.zeros((N_LEGS, 3)), self.leg_gravity.torques(qj, state.R))

    def _stance_off_landing(self, state: RobotState, J: np.ndarray, p_b: np.ndarray, f_base: np.ndarray,
                            tau_g: np.ndarray) -> np.ndarray:
        """Joint torques (12,) N m of the stance before any landing: the feet's forces f_base (4, 3)
        N (base frame) through the leg Jacobians J (4, 3, 3) at the feet p_b (4, 3) m, the legs'
        torques tau_g (12,) N m and the posture terms, within the limits (one compiled call)."""
        qj, dqj = state.q[JOINTS], state.dq[JOINTS]
        tau = np.empty(N_JOINTS)
        stance_torque(J, f_base, tau_g, False, p_b, p_b, state.contact, 0.0, 0.0, 0.0,
                      self._posture, qj, dqj, self._clip_at, tau)
        if self.compensation.active:
            return self.compensation.clipped(tau, dqj, self.torque_limit)
        return tau

    def _flight_pd(self, state) -> np.ndarray:
        """Joint PD to the landing posture, feet ahead of the hips by foot_forward * vx."""
        g = self.gains
        if self._q_land is None:
            e = self._e
            v_fwd = float(state.dq[BASE_POS] @ e)
            # landing leg length: the planned take-off height (legs fairly extended)
            self._q_land = standing_joints(self.robot, self.params.takeoff_height,
                                           dx=g.foot_forward * v_fwd)
            self._p_land = self.kin.foot_positions(self._q_land[None])[0]
        qj, dqj = state.q[JOINTS], state.dq[JOINTS]
        return g.kp_flight * (self._q_land - qj) - g.kd_flight * dqj

    def done(self, state) -> bool:
        """True once settled after landing (or when the jump has run ``max_time``)."""
        if state.t >= self.params.max_time:
            return True
        if self._phase != "land" or self._t_td is None:
            return False
        if not state.t - self._t_td >= self.params.settle_time:  # the cheap test first
            return False
        v, w = state.dq[BASE_POS], state.omega
        return float(v @ v) < 0.15 ** 2 and float(w @ w) < 0.6 ** 2


class PronkMotion(PlainMotion):
    """The pronk plug-in (registry entry ``pronk``); variant ``proxy``: a hardware-like world;
    ``randomized``: domain-randomised source jumps (motion and world drawn per jump)."""

    def sample_params(self, rng: np.random.Generator, robot: str, variant: str | None,
                      dataset_rng: np.random.Generator | None = None) -> PronkParams:
        one = variant == "proxy" and dataset_rng is not None  # the proxy target: one robot per dataset
        return sample_params(rng, proxy=variant == "proxy", robot=robot, randomized=variant == "randomized",
                             proxy_robot=sample_robot(dataset_rng) if one else None)

    def make_controller(self, robot: str, params: PronkParams, mpc_solver: str = "osqp") -> PronkController:
        gains = PronkGains.scaled(*scales(robot))
        return PronkController(robot, params, replace(gains, mpc=replace(gains.mpc, solver=mpc_solver)))

    def source(self, params: PronkParams) -> str:
        return "sim" if params.proxy is None or params.randomized else "proxy"


MOTION = PronkMotion()
