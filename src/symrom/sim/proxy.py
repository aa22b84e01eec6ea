"""A hardware-like Go1 (``source = "proxy"``) for the sim-to-real step.

Not hardware: the nominal PyBullet world with the imperfections a real robot
shows, all drawn from an rng into a ``ProxyConfig`` that is recorded with the
data (``dataclasses.asdict(cfg)`` is JSON-ready):

- link masses and inertias off their URDF values (``apply_to_world``, via
  ``changeDynamics``), and a different ground friction;
- motor latency: commanded torques reach the joints ``latency`` s late (a delay
  buffer of whole physics ticks) and torque-speed saturation: while a motor
  drives (torque and speed of the same sign) its limit falls linearly from full
  torque at ``knee_speed_frac * no_load_speed`` to zero at ``no_load_speed``
  (``TorqueChannel``);
- sensor noise on every reading and a slow drift of the estimated base position
  and yaw (``SensorModel``), as a state estimator would give.

Use, in this order (what a runner does)::

    cfg = sample_proxy(rng)                      # or PronkParams.proxy
    world = ProxyWorld(make_world(engine, "go1", config), cfg)  # a World too
    world.reset(q0); s = world.state()           # corrupted readings (what is logged)
    applied = world.step(tau_cmd)                # delayed, saturated torque actually applied
    world.true_state()                           # the simulator's exact state

``apply_to_world(world, cfg)``, ``TorqueChannel`` and ``SensorModel`` are the
parts, usable on their own. Units: s, m, rad, N m; arrays as in
``symrom.sim.world``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS
from symrom.robots.kinematics import rpy_to_matrix


@dataclass
class ProxyConfig:
    """Perturbations of one proxy jump (see the module docstring).

    trunk_mass_scale, leg_mass_scale: factors on the URDF masses (and, with the
    mass, on the inertias); inertia_scale: extra factor on all inertias;
    friction: ground lateral friction; latency: s; no_load_speed (3,) rad/s for
    hx, hy, kn; knee_speed_frac: fraction of no_load_speed up to which the full
    torque is available; noise_*: standard deviations of the readings (rad,
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


def sample_proxy(rng: np.random.Generator) -> ProxyConfig:
    """Draw a hardware-like perturbation set (ranges typical of a small quadruped)."""
    return ProxyConfig(
        trunk_mass_scale=float(rng.uniform(0.95, 1.12)),  # payload: battery, cables, covers
        leg_mass_scale=float(rng.uniform(0.92, 1.08)),
        inertia_scale=float(rng.uniform(0.9, 1.2)),
        friction=float(rng.uniform(0.55, 0.9)),
        latency=float(rng.uniform(0.002, 0.005)),
        no_load_speed=tuple(float(v) for v in rng.uniform(0.9, 1.05) * np.array([30.1, 30.1, 20.06])),
        knee_speed_frac=float(rng.uniform(0.4, 0.6)),
        noise_q=0.002, noise_dq=0.05, noise_pos=0.002, noise_rpy=0.004,
        noise_vel=0.02, noise_omega=0.02,
        drift_vel=tuple(float(v) for v in rng.normal(0.0, 0.01, 2)),
        drift_yaw_rate=float(rng.normal(0.0, 0.005)),
        seed=int(rng.integers(2 ** 31 - 1)),
    )


def apply_to_world(world, cfg: ProxyConfig) -> None:
    """Scale the robot's link masses and inertias and set the ground friction, in place.

    world: any engine's world (``symrom.sim.engine.World``).
    """
    world.scale_inertia(cfg.trunk_mass_scale, cfg.leg_mass_scale, cfg.inertia_scale)
    world.set_ground_friction(cfg.friction)


class TorqueChannel:
    """Motor model between the controller and the joints: latency, then torque-speed limit.

    torque_limit (12,) N m; dt: physics tick, s.
    """

    def __init__(self, cfg: ProxyConfig, torque_limit: np.ndarray, dt: float):
        self.cfg = cfg
        self.limit = np.asarray(torque_limit, dtype=float)
        self.delay = int(round(cfg.latency / dt))
        self.w0 = np.tile(np.asarray(cfg.no_load_speed, dtype=float), N_JOINTS // 3)
        self.reset()

    def reset(self) -> None:
        self.buffer: deque[np.ndarray] = deque([np.zeros(N_JOINTS)] * self.delay)

    def available(self, tau: np.ndarray, joint_vel: np.ndarray) -> np.ndarray:
        """(12,) N m torque limit at joint speeds (12,) rad/s for the requested direction."""
        w_knee = self.cfg.knee_speed_frac * self.w0
        frac = np.clip((self.w0 - np.abs(joint_vel)) / (self.w0 - w_knee), 0.0, 1.0)
        driving = np.sign(tau) == np.sign(joint_vel)  # braking keeps the full torque
        return np.where(driving, self.limit * frac, self.limit)

    def apply(self, tau_cmd: np.ndarray, joint_vel: np.ndarray) -> np.ndarray:
        """Torque (12,) N m reaching the joints this tick for the command ``tau_cmd`` (12,)."""
        self.buffer.append(np.asarray(tau_cmd, dtype=float).copy())
        tau = self.buffer.popleft()
        lim = self.available(tau, joint_vel)
        return np.clip(tau, -lim, lim)


class SensorModel:
    """Noisy, drifting readings of a ``RobotState`` (a state estimator's output)."""

    def __init__(self, cfg: ProxyConfig):
        self.cfg = cfg
        self.rng = np.random.default_rng(cfg.seed)

    def corrupt(self, state):
        """A copy of ``state`` with noise and drift; contact flags are left exact."""
        c, n = self.cfg, self.rng.normal
        q, dq = state.q.copy(), state.dq.copy()
        drift = np.array([c.drift_vel[0] * state.t, c.drift_vel[1] * state.t, 0.0])
        q[JOINTS] += n(0.0, c.noise_q, N_JOINTS)
        dq[JOINTS] += n(0.0, c.noise_dq, N_JOINTS)
        q[BASE_POS] += drift + n(0.0, c.noise_pos, 3)
        q[BASE_RPY] += n(0.0, c.noise_rpy, 3) + np.array([0.0, 0.0, c.drift_yaw_rate * state.t])
        dq[BASE_POS] += n(0.0, c.noise_vel, 3) + np.array([*c.drift_vel, 0.0])
        dq[BASE_RPY] += n(0.0, c.noise_omega, 3)
        R = rpy_to_matrix(q[BASE_RPY])[0]
        omega = state.omega + n(0.0, c.noise_omega, 3)
        return replace(state, q=q, dq=dq, omega=omega, R=R,
                       foot_pos=state.foot_pos + drift + n(0.0, c.noise_pos, (4, 3)),
                       foot_vel=state.foot_vel + n(0.0, c.noise_vel, (4, 3)))


class ProxyWorld:
    """A world seen through the proxy's motors and sensors; the same methods (a
    ``symrom.sim.engine.World`` of any engine).

    Construction applies the mass, inertia and friction perturbations to ``world``.
    Other attributes (``spec``, ``config``, ``client`` ...) are the wrapped world's.
    """

    def __init__(self, world, cfg: ProxyConfig):
        self.world, self.cfg = world, cfg
        apply_to_world(world, cfg)
        self.motors = TorqueChannel(cfg, world.torque_limit, world.config.dt)
        self.sensors = SensorModel(cfg)

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
        """Send ``tau`` (12,) N m; returns the torque (12,) actually applied this tick (None
        with ``report=False``, as ``World.step``)."""
        return self.world.step(self.motors.apply(tau, self.world.joint_velocities()), report)

    def apply_base_force(self, force_world: np.ndarray) -> None:
        self.world.apply_base_force(force_world)

    def close(self) -> None:
        self.world.close()
