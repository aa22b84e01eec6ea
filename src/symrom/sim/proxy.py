"""A hardware-like Go1 (``source = "proxy"``) for the sim-to-real step, and the
per-jump domain randomisation of source data (the ``randomized`` variant).

Not hardware: the nominal world with the imperfections a real robot shows, all
drawn from an rng into a ``ProxyConfig`` that is recorded with the data
(``dataclasses.asdict(cfg)`` is JSON-ready):

- link masses and inertias off their URDF values (``World.scale_inertia``), a
  different ground friction, and a softer ground contact (``contact_stiffness``,
  ``contact_damping``: a spring-damper instead of the source's rigid contact,
  ``World.set_ground_contact``);
- what sits between motor and joint (``World.set_actuator_effects``): viscous
  joint damping, armature (reflected rotor inertia) and Coulomb friction loss.
  PyBullet has no armature: on that engine ``ProxyWorld`` sets the proxy's
  armature to zero (``for_engine``; the jump's record holds what was simulated)
  and MuJoCo is the target that has every effect;
- motor latency: commanded torques reach the joints ``latency`` s late (a delay
  buffer of whole physics ticks) and torque-speed saturation: while a motor
  drives (torque and speed of the same sign) its limit falls linearly from full
  torque at ``knee_speed_frac * no_load_speed`` to zero at ``no_load_speed``
  (``TorqueChannel``);
- the torque model of the log (``torque_log``): ``applied`` (exact, what reaches
  the joints after latency and saturation, before damping and friction loss),
  ``commanded`` (what the controller asked) or ``measured``
  (``torque_bias + torque_scale * applied``, a current sensor's error);
- sensor noise on every reading and a slow drift of the estimated base position
  and yaw (``SensorModel``), as a state estimator would give.

The ranges are named tables (``ProxyRanges``): ``PROXY_RANGES`` for the proxy
target, ``RANDOMIZED_RANGES`` (wider, covering the proxy's and the nominal
world) for randomised source data; ``sample_proxy(rng, ranges)`` draws one jump's
``ProxyConfig``. ``ProxyConfig()`` is the nominal world (no effect at all).

Per robot and per jump. A proxy target is ONE robot: its hardware constants
(``ROBOT_FIELDS``: masses and inertias, the foot's contact stiffness and damping,
joint damping, armature and friction loss, the motors' torque-speed limit, the
torque sensor's bias and scale) are drawn once per dataset (``sample_robot`` from
a generator seeded by the generation seed alone) and are the same in all its
jumps; what differs between jumps of one robot (``JUMP_FIELDS``: the ground
friction patch, the latency's jitter, the sensor noise stream and the estimator's
drift) is drawn per jump (``sample_proxy(rng, robot=...)``). Randomised source
data draws everything per jump (``robot=None``): that is domain randomisation.

Use, in this order (what a runner does)::

    cfg = sample_proxy(rng)                      # or PronkParams.proxy
    world = ProxyWorld(make_world(engine, "go1", config), cfg)  # a World too
    world.reset(q0); s = world.state()           # corrupted readings (what is logged)
    applied = world.step(tau_cmd)                # delayed, saturated torque actually applied
    world.true_state()                           # the simulator's exact state
    logged = world.logged_torque(tau_cmd, applied)  # what the log holds (torque_log)

``apply_to_world(world, cfg)``, ``TorqueChannel`` and ``SensorModel`` are the
parts, usable on their own.

Disturbances a model's data never held, for testing a controller (``Disturbances``,
``DisturbedWorld``, on any engine): a payload fixed to the base, the ground's friction, motors
that deliver a fraction of their command. Units: s, m, rad, N m; arrays as in
``symrom.sim.engines.world``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from symrom.names import BASE_POS, N_JOINTS, N_LEGS, N_Q
from symrom.robots import ActuatorEffects
from symrom.sim.engines.world import RobotState


@dataclass
class ProxyConfig:
    """Perturbations of one proxy jump (see the module docstring); the defaults are the
    nominal world.

    trunk_mass_scale, leg_mass_scale: factors on the URDF masses (and, with the
    mass, on the inertias); inertia_scale: extra factor on all inertias;
    friction: ground lateral friction; contact_stiffness N/m, contact_damping
    N s/m: the ground contact as a spring-damper (None: the engine's rigid
    contact); damping N m s/rad, armature kg m^2, friction_loss N m: per joint
    kind (hx, hy, kn), as ``ActuatorEffects``; latency: s; no_load_speed (3,)
    rad/s for hx, hy, kn; knee_speed_frac: fraction of no_load_speed up to which
    the full torque is available; torque_log: ``applied``, ``commanded`` or
    ``measured``; torque_bias (3,) N m per joint kind and torque_scale: of the
    ``measured`` torque; noise_*: standard deviations of the readings (rad,
    rad/s, m, m/s); drift_vel (2,) m/s and drift_yaw_rate rad/s: estimator
    drift; seed: seed of the sensor noise stream.
    """

    trunk_mass_scale: float = 1.0
    leg_mass_scale: float = 1.0
    inertia_scale: float = 1.0
    friction: float = 0.8
    latency: float = 0.0
    no_load_speed: tuple[float, float, float] = (30.1, 30.1, 20.06)
    knee_speed_frac: float = 0.5
    noise_q: float = 0.0
    noise_dq: float = 0.0
    noise_pos: float = 0.0
    noise_rpy: float = 0.0
    noise_vel: float = 0.0
    noise_omega: float = 0.0
    drift_vel: tuple[float, float] = (0.0, 0.0)
    drift_yaw_rate: float = 0.0
    seed: int = 0
    damping: tuple[float, float, float] = (0.0, 0.0, 0.0)
    armature: tuple[float, float, float] = (0.0, 0.0, 0.0)
    friction_loss: tuple[float, float, float] = (0.0, 0.0, 0.0)
    contact_stiffness: float | None = None
    contact_damping: float | None = None
    torque_log: str = "applied"
    torque_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque_scale: float = 1.0

    def __post_init__(self) -> None:
        if self.torque_log not in TORQUE_LOGS:
            raise ValueError(f"proxy torque_log must be one of {TORQUE_LOGS}, got {self.torque_log!r}")
        if (self.contact_stiffness is None) != (self.contact_damping is None):
            raise ValueError("proxy: give both contact_stiffness and contact_damping, or neither")

    @property
    def effects(self) -> ActuatorEffects:
        """The joint damping, armature and friction loss as ``ActuatorEffects`` (12 joints)."""
        return ActuatorEffects(tuple(self.damping), tuple(self.armature), tuple(self.friction_loss))


TORQUE_LOGS = ("applied", "commanded", "measured")


@dataclass(frozen=True)
class ProxyRanges:
    """Uniform ranges (low, high) a ``ProxyConfig`` is drawn from (the hardware constants,
    ``ROBOT_FIELDS``, once per robot for the proxy target, per jump for randomised data; the
    rest per jump), and the fixed sensor noise (standard deviations). Units as in ``ProxyConfig``; per-joint-kind fields
    (damping, armature, friction_loss, torque_bias) draw each kind on its own;
    no_load_speed_scale multiplies the Go1's no-load speeds (30.1, 30.1, 20.06) rad/s;
    contact_stiffness / contact_damping None keep the engine's rigid contact; drift_vel_std
    m/s and drift_yaw_std rad/s are normal standard deviations."""

    trunk_mass_scale: tuple[float, float] = (0.95, 1.12)  # payload: battery, cables, covers
    leg_mass_scale: tuple[float, float] = (0.92, 1.08)
    inertia_scale: tuple[float, float] = (0.9, 1.2)
    friction: tuple[float, float] = (0.55, 0.9)
    latency: tuple[float, float] = (0.002, 0.005)
    no_load_speed_scale: tuple[float, float] = (0.9, 1.05)
    knee_speed_frac: tuple[float, float] = (0.4, 0.6)
    damping: tuple[float, float] = (0.0, 0.0)
    armature: tuple[float, float] = (0.0, 0.0)
    friction_loss: tuple[float, float] = (0.0, 0.0)
    contact_stiffness: tuple[float, float] | None = None
    contact_damping: tuple[float, float] | None = None
    torque_log: str = "applied"
    torque_bias: tuple[float, float] = (0.0, 0.0)
    torque_scale: tuple[float, float] = (1.0, 1.0)
    noise: tuple[float, float, float, float, float, float] = (0.002, 0.05, 0.002, 0.004, 0.02, 0.02)
    drift_vel_std: float = 0.01
    drift_yaw_std: float = 0.005


# The proxy target: a Go1 with the effects that break transfer from an ideal simulator.
# Ranges typical of a 12 kg quadruped's geared motors (joint damping 0.1-0.6 N m s/rad,
# reflected rotor inertia 0.005-0.02 kg m^2, friction 0.05-0.3 N m), a contact far softer
# than the source's rigid one (a rubber foot of 1.7-5 cm/kN), a lower ground friction, and a
# current-sensed torque off by up to 0.3 N m and 10 %.
PROXY_RANGES = ProxyRanges(
    friction=(0.5, 0.75), damping=(0.1, 0.6), armature=(0.005, 0.02), friction_loss=(0.05, 0.3),
    contact_stiffness=(2e4, 6e4), contact_damping=(300.0, 1000.0),
    torque_log="measured", torque_bias=(-0.3, 0.3), torque_scale=(0.9, 1.1))

# Randomised source data: per jump, ranges wider than the proxy's on every side that the
# nominal world has too (rigid contact is approximated by the stiff end).
RANDOMIZED_RANGES = ProxyRanges(
    trunk_mass_scale=(0.9, 1.2), leg_mass_scale=(0.85, 1.15), inertia_scale=(0.8, 1.3),
    friction=(0.45, 1.0), latency=(0.0, 0.008), no_load_speed_scale=(0.85, 1.1), knee_speed_frac=(0.35, 0.7),
    damping=(0.0, 0.9), armature=(0.0, 0.03), friction_loss=(0.0, 0.45),
    contact_stiffness=(1e4, 2e5), contact_damping=(200.0, 2000.0),
    torque_log="measured", torque_bias=(-0.5, 0.5), torque_scale=(0.85, 1.15))


# What is fixed on one robot (drawn once per dataset) and what varies between its jumps.
ROBOT_FIELDS = ("trunk_mass_scale", "leg_mass_scale", "inertia_scale", "no_load_speed", "knee_speed_frac",
                "damping", "armature", "friction_loss", "contact_stiffness", "contact_damping", "torque_log",
                "torque_bias", "torque_scale")
JUMP_FIELDS = ("friction", "latency", "noise_q", "noise_dq", "noise_pos", "noise_rpy", "noise_vel",
               "noise_omega", "drift_vel", "drift_yaw_rate", "seed")


def robot_constants(cfg: ProxyConfig) -> dict:
    """The per-robot fields (``ROBOT_FIELDS``) of ``cfg``, JSON-ready."""
    return {f: (list(v) if isinstance(v := getattr(cfg, f), tuple) else v) for f in ROBOT_FIELDS}


def sample_robot(rng: np.random.Generator, ranges: ProxyRanges = PROXY_RANGES) -> ProxyConfig:
    """Draw one robot from ``ranges``: a ``ProxyConfig`` whose ``ROBOT_FIELDS`` are the robot's
    hardware constants (its other fields are not used: ``sample_proxy(rng, ranges, robot)``
    draws them per jump)."""
    return sample_proxy(rng, ranges)


def sample_proxy(rng: np.random.Generator, ranges: ProxyRanges = PROXY_RANGES,
                 robot: ProxyConfig | None = None) -> ProxyConfig:
    """Draw one jump's perturbations from ``ranges`` (``PROXY_RANGES``: the proxy target).

    robot: the hardware constants (``ROBOT_FIELDS``) of the robot the jump runs on
    (``sample_robot``), kept; None draws them for this jump too (domain randomisation).
    The rng is consumed alike either way."""
    r, u = ranges, rng.uniform
    kinds = lambda lo_hi: tuple(float(v) for v in u(*lo_hi, 3))  # noqa: E731 (one per joint kind)
    cfg = dict(
        trunk_mass_scale=float(u(*r.trunk_mass_scale)),
        leg_mass_scale=float(u(*r.leg_mass_scale)),
        inertia_scale=float(u(*r.inertia_scale)),
        friction=float(u(*r.friction)),
        latency=float(u(*r.latency)),
        no_load_speed=tuple(float(v) for v in u(*r.no_load_speed_scale) * np.array([30.1, 30.1, 20.06])),
        knee_speed_frac=float(u(*r.knee_speed_frac)),
        noise_q=r.noise[0], noise_dq=r.noise[1], noise_pos=r.noise[2], noise_rpy=r.noise[3],
        noise_vel=r.noise[4], noise_omega=r.noise[5],
        drift_vel=tuple(float(v) for v in rng.normal(0.0, r.drift_vel_std, 2)),
        drift_yaw_rate=float(rng.normal(0.0, r.drift_yaw_std)),
        seed=int(rng.integers(2 ** 31 - 1)),
    )
    cfg.update(damping=kinds(r.damping), armature=kinds(r.armature), friction_loss=kinds(r.friction_loss),
               torque_log=r.torque_log, torque_bias=kinds(r.torque_bias), torque_scale=float(u(*r.torque_scale)))
    if r.contact_stiffness is not None:
        cfg.update(contact_stiffness=float(np.exp(u(*np.log(r.contact_stiffness)))),  # log-uniform
                   contact_damping=float(u(*r.contact_damping)))
    if robot is not None:
        cfg.update({f: getattr(robot, f) for f in ROBOT_FIELDS})
    return ProxyConfig(**cfg)


# Engines without armature: a proxy on them simulates none (``for_engine``).
NO_ARMATURE = frozenset({"pybullet"})


def for_engine(cfg: ProxyConfig, engine: str) -> ProxyConfig:
    """``cfg`` as ``engine`` can simulate it: on an engine without armature (PyBullet) the
    armature is zero. Record the returned config, not the drawn one."""
    if engine in NO_ARMATURE and any(cfg.armature):
        return replace(cfg, armature=(0.0, 0.0, 0.0))
    return cfg


def apply_to_world(world, cfg: ProxyConfig) -> None:
    """Scale the robot's link masses and inertias, set the ground friction and contact and the
    joints' damping, armature and friction loss, in place: the proxy's on top of those the
    robot's description states (hardware the controllers do not know of; the built-in robots
    state none).

    world: any engine's world (``symrom.sim.engines.world.World``); an engine without armature
    refuses a non-zero one (``for_engine`` first).
    """
    world.scale_inertia(cfg.trunk_mass_scale, cfg.leg_mass_scale, cfg.inertia_scale)
    world.set_ground_friction(cfg.friction)
    if cfg.contact_stiffness is not None:
        world.set_ground_contact(cfg.contact_stiffness, cfg.contact_damping)
    if not cfg.effects.ideal:
        world.set_actuator_effects(world.spec.actuators + cfg.effects)


class TorqueChannel:
    """Motor model between the controller and the joints: latency, then torque-speed limit.

    torque_limit (12,) N m; dt: physics tick, s.
    """

    def __init__(self, cfg: ProxyConfig, torque_limit: np.ndarray, dt: float):
        self.cfg = cfg
        self.limit = np.asarray(torque_limit, dtype=float)
        self.delay = int(round(cfg.latency / dt))
        self.w0 = np.tile(np.asarray(cfg.no_load_speed, dtype=float), N_JOINTS // 3)
        self._span = self.w0 - cfg.knee_speed_frac * self.w0  # rad/s over which the limit falls
        from symrom.sim.engines.compiled import proxy_motors  # numba: imported where it runs

        self._motors = proxy_motors
        self.reset()

    def reset(self) -> None:
        self.buffer: deque[np.ndarray] = deque([np.zeros(N_JOINTS)] * self.delay)

    def available(self, tau: np.ndarray, joint_vel: np.ndarray) -> np.ndarray:
        """(12,) N m torque limit at joint speeds (12,) rad/s for the requested direction (what
        ``apply`` clips to)."""
        frac = np.clip((self.w0 - np.abs(joint_vel)) / self._span, 0.0, 1.0)
        driving = np.sign(tau) == np.sign(joint_vel)  # braking keeps the full torque
        return np.where(driving, self.limit * frac, self.limit)

    def apply(self, tau_cmd: np.ndarray, joint_vel: np.ndarray) -> np.ndarray:
        """Torque (12,) N m reaching the joints this tick for the command ``tau_cmd`` (12,): the
        delayed command clipped to ``available``, in one compiled call
        (``symrom.sim.engines.compiled.proxy_motors``)."""
        self.buffer.append(np.array(tau_cmd, dtype=float))
        tau, out = self.buffer.popleft(), np.empty(N_JOINTS)
        self._motors(tau, np.asarray(joint_vel, dtype=float), self.w0, self._span, self.limit, out)
        return out


# The readings ``SensorModel`` adds noise to, in the order their noise is drawn: (reading, the
# name of its standard deviation in ``ProxyConfig``, how many numbers). The base's angular rate
# is drawn twice: as the Euler angles' rates in dq and as omega.
NOISE_DRAWS = (("q", "noise_q", N_JOINTS), ("dq", "noise_dq", N_JOINTS), ("pos", "noise_pos", 3),
               ("rpy", "noise_rpy", 3), ("vel", "noise_vel", 3), ("rpy_rate", "noise_omega", 3),
               ("omega", "noise_omega", 3), ("foot_pos", "noise_pos", 3 * N_LEGS),
               ("foot_vel", "noise_vel", 3 * N_LEGS))


class SensorModel:
    """Noisy, drifting readings of a ``RobotState`` (a state estimator's output)."""

    def __init__(self, cfg: ProxyConfig):
        self.cfg = cfg
        self.rng = np.random.default_rng(cfg.seed)
        self._scale = np.concatenate([np.full(n, float(getattr(cfg, sd))) for _, sd, n in NOISE_DRAWS])
        self._drift_dq = np.array([*cfg.drift_vel, 0.0])
        from symrom.sim.engines.compiled import proxy_readings  # numba: imported where it runs

        self._readings = proxy_readings

    def corrupt(self, state: RobotState) -> RobotState:
        """A copy of ``state`` with noise and drift; contact flags are left exact.

        Every reading's noise is one draw per tick, ``NOISE_DRAWS`` in order: the same numbers
        as one normal draw per reading, as the generator's normals come one after another; the
        sums in one compiled call (``symrom.sim.engines.compiled.proxy_readings``)."""
        c, t = self.cfg, state.t
        e = 0.0 + self._scale * self.rng.standard_normal(self._scale.size)  # as normal(0.0, sd) has it
        q, dq, omega, R = np.empty(N_Q), np.empty(N_Q), np.empty(3), np.empty((3, 3))
        foot_pos, foot_vel = np.empty((N_LEGS, 3)), np.empty((N_LEGS, 3))
        self._readings(state.q, state.dq, state.omega, state.foot_pos, state.foot_vel, e, c.drift_vel[0] * t,
                       c.drift_vel[1] * t, c.drift_yaw_rate * t, self._drift_dq, q, dq, omega, R, foot_pos, foot_vel)
        return RobotState(t=t, q=q, dq=dq, omega=omega, R=R, contact=state.contact, foot_pos=foot_pos,
                          foot_vel=foot_vel)


class ProxyWorld:
    """A world seen through the proxy's motors and sensors; the same methods (a
    ``symrom.sim.engines.world.World`` of any engine).

    Construction applies the mass, inertia, friction, contact and actuator perturbations to
    ``world``; ``cfg`` is what the engine simulates of them (``for_engine``; the runner
    records it in place of the drawn one).
    Other attributes (``spec``, ``config``, ``client`` ...) are the wrapped world's.
    """

    def __init__(self, world, cfg: ProxyConfig):
        self.world, self.cfg = world, for_engine(cfg, world.engine)  # what is simulated
        apply_to_world(world, self.cfg)
        self.motors = TorqueChannel(cfg, world.torque_limit, world.config.dt)
        self.sensors = SensorModel(cfg)
        self._bias = np.tile(np.asarray(self.cfg.torque_bias, dtype=float), N_LEGS)  # (12,) N m, once: read every tick

    def __getattr__(self, name):
        return getattr(self.world, name)

    def reset(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        self.world.reset(q, dq)
        self.motors.reset()

    def true_state(self):
        """The simulator's exact ``RobotState``."""
        return self.world.state()

    def state(self):
        """The corrupted ``RobotState`` a controller and a log of the real robot would see."""
        return self.sensors.corrupt(self.world.state())

    def step(self, tau: np.ndarray, report: bool = True) -> np.ndarray | None:
        """Send ``tau`` (12,) N m; returns the torque (12,) the log holds this tick (None with
        ``report=False``, as ``World.step``): by ``torque_log``, the torque actually applied,
        the command, or the measured torque (``logged_torque``)."""
        applied = self.world.step(self.motors.apply(tau, self.world.joint_velocities()), report)
        return None if applied is None else self.logged_torque(tau, applied)

    @property
    def logged_torque_bound(self) -> np.ndarray:
        """(12,) N m: the largest |logged torque| the torque model can give (the limits, or
        for ``measured`` |bias| + scale x limit)."""
        c, limit = self.cfg, self.world.torque_limit
        if c.torque_log == "measured":
            return np.abs(self._bias) + c.torque_scale * limit
        return limit

    def logged_torque(self, tau_cmd: np.ndarray, applied: np.ndarray) -> np.ndarray:
        """(12,) N m the log holds for command ``tau_cmd`` (12,) and ``applied`` (12,): see
        ``ProxyConfig.torque_log``."""
        c = self.cfg
        if c.torque_log == "commanded":
            return np.minimum(np.maximum(np.asarray(tau_cmd, dtype=float), -self.world.torque_limit),
                              self.world.torque_limit)
        if c.torque_log == "measured":
            return self._bias + c.torque_scale * applied
        return applied

    def apply_base_force(self, force_world: np.ndarray) -> None:
        self.world.apply_base_force(force_world)

    def close(self) -> None:
        self.world.close()


@dataclass(frozen=True)
class Disturbances:
    """What a world may differ by from the one a model was learned in, for testing a controller
    (none by default): payload kg fixed to the base at its centre of mass
    (``World.add_payload``); friction: the ground's friction coefficient (None: the engine's);
    motor_scale: the torque each motor delivers per unit of its command (1: all of it)."""

    payload: float = 0.0
    friction: float | None = None
    motor_scale: float = 1.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.payload) and self.payload >= 0):
            raise ValueError(f"payload must be a mass >= 0 kg, got {self.payload}")
        if self.friction is not None and not (np.isfinite(self.friction) and self.friction > 0):
            raise ValueError(f"friction must be a coefficient > 0, got {self.friction}")
        if not (np.isfinite(self.motor_scale) and 0 < self.motor_scale <= 2):
            raise ValueError(f"motor_scale must be in (0, 2], got {self.motor_scale}")

    @property
    def none(self) -> bool:
        return self.payload == 0 and self.friction is None and self.motor_scale == 1

    def to_dict(self) -> dict:
        return {"payload_kg": self.payload, "friction": self.friction, "motor_scale": self.motor_scale}


class DisturbedWorld:
    """A world of any engine with ``Disturbances``: the payload and the friction set at
    construction, and every motor delivering ``motor_scale`` times its command (clipped to the
    limits first, as a motor driver would); the same methods (a
    ``symrom.sim.engines.world.World``). ``step`` returns what the joints got."""

    def __init__(self, world, disturbances: Disturbances):
        self.world, self.disturbances = world, disturbances
        if disturbances.payload:
            world.add_payload(disturbances.payload)
        if disturbances.friction is not None:
            world.set_ground_friction(disturbances.friction)
        self._scale = float(disturbances.motor_scale)

    def __getattr__(self, name):
        return getattr(self.world, name)

    def reset(self, q: np.ndarray, dq: np.ndarray | None = None) -> None:
        self.world.reset(q, dq)

    def state(self):
        return self.world.state()

    def step(self, tau: np.ndarray, report: bool = True) -> np.ndarray | None:
        if self._scale != 1.0:
            limit = self.world.torque_limit
            tau = self._scale * np.minimum(np.maximum(np.asarray(tau, dtype=float), -limit), limit)
        return self.world.step(tau, report)

    def apply_base_force(self, force_world: np.ndarray) -> None:
        self.world.apply_base_force(force_world)

    def close(self) -> None:
        self.world.close()


# ------------------------------------------------------------------ a real log's faults

@dataclass(frozen=True)
class LogFaults:
    """What a real robot's logger does to its log (``symrom generate --log-faults``): the
    faults ``symrom import --repair`` finds from physics (``data.repair``). One robot's
    (drawn once per dataset, ``sample_log_faults``); a jump's own part is its phase.

    clock: true seconds per logged second, the rows written a constant period apart (a
    control loop slower than its nominal rate, > 1); clock_wobble: the loop's rate changes
    within a jump by this fraction (one sine over the jump, its phase per jump);
    velocity_gain: logged over true velocities, every group (a unit, a filter);
    torque_gain: logged over true torques (a current sensor that reads part of the load);
    height_offset: m added to the logged base height (an estimator's offset); contact_lag:
    rows the contact flags are written late. ``LogFaults()`` is a log without faults.
    """

    clock: float = 1.0
    clock_wobble: float = 0.0
    velocity_gain: float = 1.0
    torque_gain: float = 1.0
    height_offset: float = 0.0
    contact_lag: int = 0

    @property
    def none(self) -> bool:
        """Whether the log is written without faults."""
        return self == LogFaults()


@dataclass(frozen=True)
class LogFaultRanges:
    """Uniform ranges (low, high) a robot's ``LogFaults`` are drawn from; contact_lag: the
    largest lag in rows (drawn 0 .. it)."""

    clock: tuple[float, float] = (1.0, 1.0)
    clock_wobble: tuple[float, float] = (0.0, 0.0)
    velocity_gain: tuple[float, float] = (1.0, 1.0)
    torque_gain: tuple[float, float] = (0.5, 0.85)
    height_offset: tuple[float, float] = (-0.03, 0.03)
    contact_lag: int = 1


# A real quadruped's logs, by what is wrong with its time base: ``clock``, a loop 4-8 % slower
# than its nominal rate whose rate changes by 2-6 % within a jump (the real A1 froggy logs: no
# timestamps, a period estimated per jump, a rate drifting 0.93-1.06 within it); ``velocities``,
# a right clock with velocities 4-8 % low (the real Go1 log: 1/1.06). Both: a torque sensor
# reading half to 85 % of the load (the Go1's 0.56), a height estimate off by up to 3 cm (its
# 21.7 mm, the A1's 28 mm), flags up to a row late. Faults of this size are determined by one
# jump's flight (a 3 % clock is not: the flight's g is known to about 2 %).
LOG_FAULTS = {
    "clock": LogFaultRanges(clock=(1.04, 1.08), clock_wobble=(0.02, 0.06)),
    "velocities": LogFaultRanges(velocity_gain=(0.92, 0.96)),
}


def sample_log_faults(rng: np.random.Generator, ranges: LogFaultRanges) -> LogFaults:
    """One robot's log faults drawn from ``ranges`` (``LOG_FAULTS``)."""
    r, u = ranges, rng.uniform
    return LogFaults(clock=float(u(*r.clock)), clock_wobble=float(u(*r.clock_wobble)),
                     velocity_gain=float(u(*r.velocity_gain)), torque_gain=float(u(*r.torque_gain)),
                     height_offset=float(u(*r.height_offset)), contact_lag=int(rng.integers(0, r.contact_lag + 1)))


def logged_times(duration: float, dt: float, faults: LogFaults, phase: float) -> np.ndarray:
    """The true times (n,) s of the rows a faulty loop writes ``dt`` s apart by its clock over a
    jump of ``duration`` true s: row k+1 is taken dt * rate after row k, the rate
    ``clock (1 + clock_wobble sin(2 pi t_k / duration + phase))`` of the logged time t_k = k dt."""
    if faults.clock == 1.0 and faults.clock_wobble == 0.0:
        return np.arange(int(np.floor(duration / dt + 1e-9)) + 1) * dt
    n_max = int(duration / (dt * faults.clock * (1 - faults.clock_wobble))) + 2
    t_log = (np.arange(n_max) + 0.5) * dt
    rate = faults.clock * (1.0 + faults.clock_wobble * np.sin(2 * np.pi * t_log / duration + phase))
    T = np.r_[0.0, np.cumsum(dt * rate)]
    return T[T <= duration + 1e-12]


def apply_log_faults(log: dict[str, np.ndarray], faults: LogFaults, dt: float, phase: float = 0.0
                     ) -> dict[str, np.ndarray]:
    """The log a faulty logger writes of the true jump ``log`` (its rows ``dt`` s apart, keys as
    ``generation.runner.run_jump``'s: t, q, dq, tau, contact, foot_pos, contact_force).

    The rows are taken at ``logged_times`` and written ``dt`` apart (t = k dt): q and dq by a
    cubic spline through the true rows (exact at them), the torques, feet and contact forces
    linearly, the flags as the last true row at or before; then the velocities times
    ``velocity_gain``, the torques times ``torque_gain``, ``height_offset`` added to the base's
    (and the feet's) height, the flags moved ``contact_lag`` rows late. A log without faults
    is returned as it is."""
    if faults.none:
        return log
    t = log["t"]
    if faults.clock == 1.0 and faults.clock_wobble == 0.0:  # the rows as they were taken
        out = {k: v.copy() for k, v in log.items()}
    else:
        from scipy.interpolate import CubicSpline

        T = logged_times(float(t[-1] - t[0]), dt, faults, phase) + t[0]
        out = {"t": t[0] + np.arange(T.size) * dt}
        for k in ("q", "dq"):
            out[k] = CubicSpline(t, log[k], axis=0)(T)
        for k in ("tau", "foot_pos", "contact_force"):
            flat = log[k].reshape(t.size, -1)
            out[k] = np.stack([np.interp(T, t, c) for c in flat.T], axis=1).reshape((T.size,) + log[k].shape[1:])
        prev = np.clip(np.searchsorted(t, T + 1e-9 * dt, side="right") - 1, 0, t.size - 1)
        for k in log:  # the flags (and anything else the log holds): the last true row at or before
            out.setdefault(k, log[k][prev].copy())
    out["dq"] = out["dq"] * faults.velocity_gain
    out["tau"] = out["tau"] * faults.torque_gain
    out["q"][:, BASE_POS.start + 2] += faults.height_offset
    out["foot_pos"][:, :, 2] += faults.height_offset
    if faults.contact_lag:
        lag = faults.contact_lag
        out["contact"] = np.r_[np.repeat(out["contact"][:1], lag, axis=0), out["contact"][:-lag]]
    return out
