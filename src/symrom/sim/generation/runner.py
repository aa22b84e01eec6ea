"""Running one jump: a fresh world and controller of the motion, logged, checked, retried.

One jump: the motion's world (1 kHz physics) and controller (``Controller``:
``reset``, ``torque``, ``done``) run by the episode loop (``episode.run_episode``),
logged every ``physics_hz / log_hz`` ticks (500 Hz, dt = 0.002 s): t (s), q and dq
(18,), the applied torque tau (12,) N m, contact (4,), foot_pos (4, 3) m and the
engine's contact forces (4, 3) N. A failed jump is re-run with a fresh seed derived
from (seed, jump, attempt), so a file never depends on the order or the number of
workers.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

import numpy as np

from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_Q
from symrom.sim.controllers.motion import load_motion
from symrom.sim.engines.world import RobotState
from symrom.sim.generation.checks import check_jump
from symrom.sim.generation.config import GenerateConfig, NoiseConfig
from symrom.sim.generation.episode import BasePush, run_episode
from symrom.sim.generation.parts import LOG_KEYS, jsonable
from symrom.sim.proxy import LOG_FAULTS, LogFaults, ProxyWorld, apply_log_faults, sample_log_faults


class GenerationError(RuntimeError):
    """A generation request cannot be carried out (bad options, stale parts, no valid jump)."""


def jump_seed(seed: int, jump: int, attempt: int) -> np.random.SeedSequence:
    """The seed of attempt ``attempt`` of jump ``jump``: independent of workers and order."""
    return np.random.SeedSequence(seed, spawn_key=(jump, attempt))


def dataset_seed(seed: int) -> np.random.SeedSequence:
    """The seed of what all jumps of a file share (the proxy's robot): the generation seed
    alone (a spawn key of one entry, never a jump's)."""
    return np.random.SeedSequence(seed, spawn_key=(0,))


def faults_seed(seed: int) -> np.random.SeedSequence:
    """The seed of a file's log faults (one robot's, ``log_faults_of``): the generation seed
    alone, apart from the proxy robot's (``dataset_seed``), so drawing them changes nothing else."""
    return np.random.SeedSequence(seed, spawn_key=(1,))


def log_faults_of(cfg: GenerateConfig) -> LogFaults:
    """The log faults of ``cfg``'s robot (``LOG_FAULTS[cfg.log_faults]``, drawn once from its
    seed), or none."""
    if cfg.log_faults is None:
        return LogFaults()
    return sample_log_faults(np.random.default_rng(faults_seed(cfg.seed)), LOG_FAULTS[cfg.log_faults])


def _noisy(s: RobotState, noise: NoiseConfig, rng: np.random.Generator) -> RobotState:
    """A reading of ``s`` with Gaussian noise on q and dq (other fields exact)."""
    q, dq = s.q.copy(), s.dq.copy()
    q[JOINTS] += rng.normal(0.0, noise.q_joint, N_JOINTS)
    q[BASE_POS] += rng.normal(0.0, noise.q_base_pos, 3)
    q[BASE_RPY] += rng.normal(0.0, noise.q_rpy, 3)
    dq[JOINTS] += rng.normal(0.0, noise.dq_joint, N_JOINTS)
    dq[BASE_POS] += rng.normal(0.0, noise.dq_base_lin, 3)
    dq[BASE_RPY] += rng.normal(0.0, noise.dq_rpy, 3)
    return RobotState(t=s.t, q=q, dq=dq, omega=s.omega, R=s.R, contact=s.contact,
                      foot_pos=s.foot_pos, foot_vel=s.foot_vel)


def run_jump(cfg: GenerateConfig, seq: np.random.SeedSequence) -> tuple[dict[str, np.ndarray], dict]:
    """Simulate one jump; return its log and a JSON-ready info dict.

    Log arrays (n rows at log_hz): t (n,) s, q, dq (n, 18), tau (n, 12) N m
    applied, contact (n, 4) uint8, foot_pos (n, 4, 3) m, contact_force (n, 4, 3) N. info: params, source,
    push force, whether the controller finished (``done``) in time, and the
    controller's diagnostics (not stored in the file).
    """
    params_rng, noise_rng = (np.random.default_rng(s) for s in seq.spawn(2))
    motion = load_motion(cfg.motion)
    params = motion.sample_params(params_rng, cfg.robot, cfg.variant, np.random.default_rng(dataset_seed(cfg.seed)))
    world = motion.make_world(cfg.robot, cfg.world, params, cfg.engine)
    ctrl = motion.make_controller(cfg.robot, params, mpc_solver=cfg.mpc_solver)
    q0 = np.asarray(ctrl.reset(world), dtype=float).copy()
    info: dict[str, Any] = {"params": jsonable(asdict(params)), "source": motion.source(params)}
    if isinstance(world, ProxyWorld):  # what the engine simulates of the drawn perturbations
        info["params"]["proxy"] = jsonable(asdict(world.cfg))
        bound = world.logged_torque_bound  # a measured torque may pass the limits
        if not np.array_equal(bound, world.torque_limit):
            info["torque_bound"] = np.asarray(bound).tolist()
    push = reading = None
    if cfg.noise is not None:
        n = cfg.noise
        q0[JOINTS] += noise_rng.normal(0.0, n.q0_joint, N_JOINTS)
        xy = q0[BASE_POS][:2] + noise_rng.normal(0.0, n.q0_xy, 2)
        rpy = q0[BASE_RPY] + np.r_[noise_rng.normal(0.0, n.q0_rp, 2), 0.0]
        q0 = world.standing_q(q0[JOINTS], tuple(xy), tuple(rpy))  # back on the ground
        f = noise_rng.normal(0.0, np.asarray(n.force_std))
        t0 = float(noise_rng.uniform(*n.force_start))
        push = BasePush(f, t0, t0 + n.force_duration)
        info["push"] = {"force": f.tolist(), "t_start": t0, "t_end": t0 + n.force_duration}

        def reading(s: RobotState) -> RobotState:
            return _noisy(s, n, noise_rng)

    log: dict[str, list] = {k: [] for k in LOG_KEYS}
    dt = cfg.world.dt

    def on_sample(tick: int, s: RobotState, applied: np.ndarray) -> None:
        log["t"].append(tick * dt)
        log["q"].append(s.q)
        log["dq"].append(s.dq)
        log["tau"].append(applied)
        log["contact"].append(s.contact)
        log["foot_pos"].append(s.foot_pos)
        log["contact_force"].append(world.contact_forces())  # the engine's, during this tick

    watch = motion.watch() if hasattr(motion, "watch") else None  # the motion's own watcher
    try:
        end = run_episode(world, ctrl, q0, params.max_time, on_sample=on_sample, watch=watch, reading=reading,
                          push=push)
    finally:
        world.close()
    if end.stopped_at is not None:  # fails whatever would follow
        info["stopped"] = f"{watch.reason} (stopped at {end.stopped_at * dt:.3f} s)"
    info["finished"] = end.finished
    info["diagnostics"] = ctrl.diagnostics()
    arrays = {"t": np.asarray(log["t"], float), "q": np.asarray(log["q"], float).reshape(-1, N_Q),
              "dq": np.asarray(log["dq"], float).reshape(-1, N_Q),
              "tau": np.asarray(log["tau"], float).reshape(-1, N_JOINTS),
              "contact": np.asarray(log["contact"], np.uint8).reshape(-1, 4),
              "foot_pos": np.asarray(log["foot_pos"], float).reshape(-1, 4, 3),
              "contact_force": np.asarray(log["contact_force"], float).reshape(-1, 4, 3)}
    return arrays, info


# A drawn jump (the ``randomized`` and ``proxy`` variants draw the motion's parameters and the
# world from ranges) that the controller cannot land is replaced by a fresh draw from the same
# ranges, each recorded as a retry: at least this many draws, so that a run of them never stops
# at the ranges' landing rates (docs/simulation.md: at the lowest, 0.35 of the randomised froggy's
# draws land, in MuJoCo; 100 failures in a row then have a chance of about 1e-19).
DRAWN_ATTEMPTS = 100


def attempts(cfg: GenerateConfig) -> int:
    """The most tries of one jump: ``cfg.max_attempts``, at least ``DRAWN_ATTEMPTS`` for a drawn variant."""
    return cfg.max_attempts if cfg.variant is None else max(cfg.max_attempts, DRAWN_ATTEMPTS)


def run_checked_jump(cfg: GenerateConfig, jump: int) -> tuple[dict[str, np.ndarray], dict]:
    """Run jump ``jump`` until it passes the checks (at most ``attempts(cfg)`` tries).

    Returns the log and a JSON-ready record: jump, attempt, spawn_key, failed
    attempts with reasons, params, source. With ``cfg.log_faults`` the checked jump is
    returned as a faulty logger writes it (``proxy.apply_log_faults``; its wobble's phase
    drawn from the jump seed's third child), the faults in the record's ``log_faults``.
    """
    motion = load_motion(cfg.motion)
    dt = cfg.world.dt * cfg.world.log_every
    failures = []
    tries = attempts(cfg)
    for attempt in range(tries):
        log, info = run_jump(cfg, jump_seed(cfg.seed, jump, attempt))
        if "stopped" in info:  # failed for certain while it ran; the other checks were not run
            bad = [info["stopped"]]
        else:
            bad = (check_jump(log, cfg.robot, dt, cfg.checks, info["finished"], info.get("torque_bound"))
                   + motion.check(log, dt, cfg.checks))
        if not bad:
            record = {"jump": jump, "attempt": attempt, "spawn_key": [jump, attempt],
                      "retries": failures, "samples": int(log["t"].shape[0]), **info}
            if cfg.log_faults is not None:  # the checked true jump, as a faulty logger writes it
                faults = log_faults_of(cfg)
                phase = float(np.random.default_rng(np.random.SeedSequence(
                    cfg.seed, spawn_key=(jump, attempt, 2))).uniform(0.0, 2 * np.pi))
                log = apply_log_faults(log, faults, dt, phase)
                record["log_faults"] = {**asdict(faults), "phase": phase, "true_samples": record["samples"]}
                record["samples"] = int(log["t"].shape[0])
            return log, record
        failures.append({"attempt": attempt, "reasons": bad})
    raise GenerationError(f"jump {jump}: no valid jump in {tries} attempts "
                          f"(last: {'; '.join(failures[-1]['reasons'])})")
