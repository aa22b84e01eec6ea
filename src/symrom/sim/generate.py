"""Simulated jump datasets: run jumps in PyBullet, check them, retry, write a dataset file.

One jump: a fresh ``World`` (1 kHz physics), a controller of the motion
(``torque(state)`` -> (12,) N m, ``done(state)``), logged every
``physics_hz / log_hz`` ticks (500 Hz, dt = 0.002 s): t (s), q and dq (18,),
the applied torque tau (12,) N m, contact (4,) and foot_pos (4, 3) m. Every jump
is checked (``JumpChecks``); a failed jump is re-run with a fresh seed derived
from (seed, jump, attempt) and the failures are recorded.

At scale, ``generate`` runs jumps in worker processes. Each jump's seed comes
from ``SeedSequence(seed, spawn_key=(jump, attempt))``, and every jump runs in
its own PyBullet client, so the file does not depend on the worker count.
Each finished jump is written at once to ``OUT.parts/jump_00012.npz`` (no
pickle); ``resume`` reuses those parts. The dataset is assembled with
``symrom.data.preprocess.assemble`` and written atomically; the parts folder
is removed afterwards. The library never prints: progress goes to a callback.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np

from symrom.data.dataset import Dataset
from symrom.data.io import write_dataset
from symrom.data.preprocess import assemble
from symrom.names import BASE_POS, BASE_RPY, JOINTS, N_JOINTS, N_Q
from symrom.robots import get_robot
from symrom.sim.world import RobotState, World, WorldConfig

GENERATOR_VERSION = 1
MOTIONS = ("froggy", "pronk")
ROBOT_OF_MOTION = {"froggy": "a1", "pronk": "go1"}
# Paper's splits (train, val, test) for its dataset sizes.
PAPER_SPLITS: dict[tuple[str, bool], tuple[int, int, int]] = {
    ("go1", False): (120, 30, 6),
    ("a1", False): (100, 40, 10),
    ("go1", True): (12, 2, 1),
}


class GenerationError(RuntimeError):
    """A generation request cannot be carried out (bad options, stale parts, no valid jump)."""


# ------------------------------------------------------------------ configuration
@dataclass(frozen=True)
class NoiseConfig:
    """Noise of the ``--noise`` variant (standard deviations, SI units).

    Initial configuration: q0_joint rad on the joint angles, q0_xy m on base
    x/y, q0_rp rad on roll/pitch (the base is then put back on the ground).
    Readings (what the controller sees and what is logged): q_joint rad,
    q_base_pos m, q_rpy rad, dq_joint rad/s, dq_base_lin m/s, dq_rpy rad/s.
    External push on the CoM: a constant force ~ N(0, force_std) N per world
    axis, held for force_duration s from a start time uniform in force_start s.
    """

    q0_joint: float = 0.02
    q0_xy: float = 0.005
    q0_rp: float = 0.01
    q_joint: float = 0.002
    q_base_pos: float = 0.002
    q_rpy: float = 0.005
    dq_joint: float = 0.05
    dq_base_lin: float = 0.02
    dq_rpy: float = 0.05
    force_std: tuple[float, float, float] = (15.0, 15.0, 10.0)
    force_duration: float = 0.2
    force_start: tuple[float, float] = (0.2, 1.2)


@dataclass(frozen=True)
class JumpChecks:
    """What every kept jump must show (from its logged samples).

    max_tilt: |roll|, |pitch| bound, rad; min_final_height: final base height, m;
    min_flight: longest run with no foot down, s; min_apex_gain: max base height
    minus the first, m; min_travel: final minus first base position along the
    start heading, m; min_rear_only: for froggy, rear-only contact right before
    the flight, s; torques must be within the robot's limits and the jump must
    end (controller ``done``) before its time limit.
    """

    max_tilt: float = 0.8
    min_final_height: float = 0.15
    min_flight: float = 0.12
    min_apex_gain: float = 0.05
    min_travel: float = 0.1
    min_rear_only: float = 0.04


@dataclass(frozen=True)
class GenerateConfig:
    """Everything that determines a generated file (recorded in its ``generator``)."""

    robot: str
    motion: str
    n_jumps: int
    seed: int = 0
    proxy: bool = False
    noise: NoiseConfig | None = None
    world: WorldConfig = field(default_factory=WorldConfig)
    checks: JumpChecks = field(default_factory=JumpChecks)
    max_attempts: int = 8

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["noise"] = None if self.noise is None else asdict(self.noise)
        return d

    def fingerprint(self) -> str:
        """Hash of what makes each jump (not the jump count), to match resumed parts."""
        d = self.to_dict()
        d.pop("n_jumps")
        d["version"] = GENERATOR_VERSION
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]


# ------------------------------------------------------------------ motions
@dataclass
class _Setup:
    """A motion's controller, world and start pose for one jump."""

    controller: Any
    world: Any
    q0: np.ndarray
    params: dict[str, Any]
    max_time: float
    source: str


def _setup_froggy(cfg: GenerateConfig, rng: np.random.Generator) -> _Setup:
    from symrom.sim import froggy

    spec = get_robot(cfg.robot)
    params = froggy.sample_params(rng)
    world = World(cfg.robot, cfg.world)
    ctrl = froggy.FroggyController(spec, params)
    return _Setup(ctrl, world, ctrl.initial_q(world), params.to_dict(), params.max_time, "sim")


def _setup_pronk(cfg: GenerateConfig, rng: np.random.Generator) -> _Setup:
    from symrom.sim import pronk

    spec = get_robot(cfg.robot)
    params = pronk.sample_params(rng, proxy=cfg.proxy)
    world = World(cfg.robot, cfg.world)
    if params.proxy is not None:
        from symrom.sim import proxy

        world = proxy.ProxyWorld(world, params.proxy)
    ctrl = pronk.PronkController(spec, params)
    return _Setup(ctrl, world, pronk.initial_state(spec, params), _jsonable(asdict(params)),
                  float(params.max_time), "proxy" if cfg.proxy else "sim")


SETUPS: dict[str, Callable[[GenerateConfig, np.random.Generator], _Setup]] = {
    "froggy": _setup_froggy, "pronk": _setup_pronk}


def motion_available(motion: str) -> bool:
    """Whether the controller module of ``motion`` can be imported."""
    import importlib.util

    return importlib.util.find_spec(f"symrom.sim.{motion}") is not None


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


# ------------------------------------------------------------------ one jump
def jump_seed(seed: int, jump: int, attempt: int) -> np.random.SeedSequence:
    """The seed of attempt ``attempt`` of jump ``jump``: independent of workers and order."""
    return np.random.SeedSequence(seed, spawn_key=(jump, attempt))


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
    applied, contact (n, 4) uint8, foot_pos (n, 4, 3) m. info: params, source,
    push force, whether the controller finished (``done``) in time.
    """
    params_rng, noise_rng = (np.random.default_rng(s) for s in seq.spawn(2))
    setup = SETUPS[cfg.motion](cfg, params_rng)
    world, ctrl = setup.world, setup.controller
    q0 = np.asarray(setup.q0, dtype=float).copy()
    info: dict[str, Any] = {"params": setup.params, "source": setup.source}
    force = None
    if cfg.noise is not None:
        n = cfg.noise
        q0[JOINTS] += noise_rng.normal(0.0, n.q0_joint, N_JOINTS)
        xy = q0[BASE_POS][:2] + noise_rng.normal(0.0, n.q0_xy, 2)
        rpy = q0[BASE_RPY] + np.r_[noise_rng.normal(0.0, n.q0_rp, 2), 0.0]
        q0 = world.standing_q(q0[JOINTS], tuple(xy), tuple(rpy))  # back on the ground
        f = noise_rng.normal(0.0, np.asarray(n.force_std))
        t0 = float(noise_rng.uniform(*n.force_start))
        force = (f, t0, t0 + n.force_duration)
        info["push"] = {"force": f.tolist(), "t_start": t0, "t_end": t0 + n.force_duration}
    log: dict[str, list] = {k: [] for k in ("t", "q", "dq", "tau", "contact", "foot_pos")}
    every = cfg.world.log_every
    finished = False
    try:
        world.reset(q0)
        for tick in range(int(round(setup.max_time * cfg.world.physics_hz)) + 1):
            s = world.state()
            if cfg.noise is not None:
                s = _noisy(s, cfg.noise, noise_rng)
            if ctrl.done(s):
                finished = True
                break
            tau = ctrl.torque(s)
            if force is not None and force[1] <= s.t < force[2]:
                world.apply_base_force(force[0])
            applied = world.step(tau)
            if tick % every == 0:
                log["t"].append(tick * cfg.world.dt)
                log["q"].append(s.q)
                log["dq"].append(s.dq)
                log["tau"].append(applied)
                log["contact"].append(s.contact)
                log["foot_pos"].append(s.foot_pos)
    finally:
        world.close()
    info["finished"] = finished
    arrays = {"t": np.asarray(log["t"], float), "q": np.asarray(log["q"], float).reshape(-1, N_Q),
              "dq": np.asarray(log["dq"], float).reshape(-1, N_Q),
              "tau": np.asarray(log["tau"], float).reshape(-1, N_JOINTS),
              "contact": np.asarray(log["contact"], np.uint8).reshape(-1, 4),
              "foot_pos": np.asarray(log["foot_pos"], float).reshape(-1, 4, 3)}
    if hasattr(ctrl, "mpc_solve_times"):
        info["mpc_solve_times"] = [float(x) for x in ctrl.mpc_solve_times]
    return arrays, info


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of True in a boolean (n,) array."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def check_jump(log: dict[str, np.ndarray], motion: str, robot: str, dt: float,
               checks: JumpChecks = JumpChecks(), finished: bool = True) -> list[str]:
    """Reasons ``log`` (as from ``run_jump``) fails the checks; empty if it passes."""
    q, contact, tau = log["q"], log["contact"], log["tau"]
    bad: list[str] = []
    if q.shape[0] < 2:
        return ["no samples"]
    if not finished:
        bad.append("controller did not finish in time")
    tilt = np.abs(q[:, BASE_RPY][:, :2]).max()
    if tilt >= checks.max_tilt:
        bad.append(f"fell: tilt {tilt:.2f} rad")
    if q[-1, BASE_POS][2] <= checks.min_final_height:
        bad.append(f"fell: final height {q[-1, BASE_POS][2]:.3f} m")
    limit = np.asarray(get_robot(robot).torque_limit)
    if np.any(np.abs(tau) > limit + 1e-9):
        bad.append("torque over the limit")
    airborne = contact.sum(axis=1) == 0
    runs = _runs(airborne)
    if not runs:
        bad.append("no flight")
    else:
        a, b = max(runs, key=lambda r: r[1] - r[0])
        if (b - a) * dt < checks.min_flight - 1e-9:
            bad.append(f"flight {(b - a) * dt:.3f} s")
        if runs[0][0] != a:
            bad.append("a brief flight before the main one")
        if motion == "froggy":
            rear_only = (contact[:, 0] == 0) & (contact[:, 1] == 0) & (contact[:, 2:].sum(axis=1) > 0)
            n = 0
            while a - n - 1 >= 0 and rear_only[a - n - 1]:
                n += 1
            if n * dt < checks.min_rear_only - 1e-9:
                bad.append(f"rear-only contact {n * dt:.3f} s before flight")
    z = q[:, BASE_POS][:, 2]
    if z.max() - z[0] < checks.min_apex_gain:
        bad.append(f"apex gain {z.max() - z[0]:.3f} m")
    yaw0 = q[0, BASE_RPY][2]
    travel = float(np.dot(q[-1, BASE_POS][:2] - q[0, BASE_POS][:2], [np.cos(yaw0), np.sin(yaw0)]))
    if travel < checks.min_travel:
        bad.append(f"travel {travel:.3f} m")
    return bad


def run_checked_jump(cfg: GenerateConfig, jump: int) -> tuple[dict[str, np.ndarray], dict]:
    """Run jump ``jump`` until it passes the checks (at most ``cfg.max_attempts`` tries).

    Returns the log and a JSON-ready record: jump, attempt, spawn_key, failed
    attempts with reasons, params, source.
    """
    failures = []
    for attempt in range(cfg.max_attempts):
        log, info = run_jump(cfg, jump_seed(cfg.seed, jump, attempt))
        bad = check_jump(log, cfg.motion, cfg.robot, cfg.world.dt * cfg.world.log_every,
                         cfg.checks, info["finished"])
        if not bad:
            record = {"jump": jump, "attempt": attempt, "spawn_key": [jump, attempt],
                      "retries": failures, "samples": int(log["t"].shape[0]), **info}
            return log, record
        failures.append({"attempt": attempt, "reasons": bad})
    raise GenerationError(f"jump {jump}: no valid jump in {cfg.max_attempts} attempts "
                          f"(last: {'; '.join(failures[-1]['reasons'])})")


# ------------------------------------------------------------------ part files
def parts_dir(out: str | os.PathLike) -> Path:
    """Sidecar folder of per-jump part files of ``out``."""
    return Path(str(out) + ".parts")


def part_path(parts: Path, jump: int) -> Path:
    return parts / f"jump_{jump:05d}.npz"


def write_part(path: Path, log: dict[str, np.ndarray], record: dict, fingerprint: str) -> None:
    """Write one jump's part atomically (npz, no pickle)."""
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
    meta = json.dumps({"fingerprint": fingerprint, "record": _jsonable(record)}, sort_keys=True)
    np.savez(tmp, meta=np.array(meta), **log)
    os.replace(tmp, path)


def read_part(path: Path) -> tuple[dict[str, np.ndarray], dict, str]:
    """(log, record, fingerprint) of a part file."""
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        log = {k: z[k] for k in ("t", "q", "dq", "tau", "contact", "foot_pos")}
    return log, meta["record"], meta["fingerprint"]


def _worker(cfg: GenerateConfig, jump: int, parts: str) -> dict:
    log, record = run_checked_jump(cfg, jump)
    write_part(part_path(Path(parts), jump), log, record, cfg.fingerprint())
    return {"jump": jump, "retries": len(record["retries"]), "samples": record["samples"],
            "mpc_solve_times": record.get("mpc_solve_times", [])}


def _mp_context():
    """Fresh worker processes: forkserver (with this module preloaded) where there is one,
    else spawn. Plain fork could inherit locks held by the caller's threads (e.g. a
    progress bar)."""
    import multiprocessing as mp

    if "forkserver" in mp.get_all_start_methods():
        ctx = get_context("forkserver")
        ctx.set_forkserver_preload(["symrom.sim.generate", "symrom.sim.froggy", "pybullet"])
        return ctx
    return get_context("spawn")


# ------------------------------------------------------------------ splits
def split_counts(n: int, robot: str, proxy: bool = False) -> tuple[int, int, int]:
    """(train, val, test) jump counts: the paper's for its sizes, else scaled proportionally.

    Largest remainders, ties to the earlier split; at least one train jump, and from
    two jumps on at least one test jump, from three on at least one val jump, so a
    small dataset can still be evaluated.
    """
    ref = PAPER_SPLITS.get((robot, proxy), PAPER_SPLITS.get((robot, False), (100, 40, 10)))
    if n == sum(ref):
        return ref
    exact = np.asarray(ref, float) * n / sum(ref)
    counts = np.floor(exact).astype(int)
    order = sorted(range(3), key=lambda i: (-(exact[i] - counts[i]), i))
    for i in order[: n - counts.sum()]:
        counts[i] += 1
    kept: list[int] = []
    for need, i in ((1, 0), (2, 2), (3, 1)):  # (from n jumps on, split index) in priority order
        if n >= need and counts[i] == 0:
            # Take from the largest split that can spare one (not below one if already kept).
            donors = [k for k in range(3) if k != i and counts[k] > (1 if k in kept else 0)]
            j = max(donors, key=lambda k: counts[k])
            counts[j] -= 1
            counts[i] += 1
        kept.append(i)
    return int(counts[0]), int(counts[1]), int(counts[2])


def split_labels(n: int, robot: str, proxy: bool = False) -> np.ndarray:
    """(n,) object array of split names, jumps in order: train, then val, then test."""
    tr, va, te = split_counts(n, robot, proxy)
    return np.array(["train"] * tr + ["val"] * va + ["test"] * te, dtype=object)


# ------------------------------------------------------------------ the whole file
ProgressCallback = Callable[[int, int, dict], None]


def build_dataset(cfg: GenerateConfig, logs: list[dict[str, np.ndarray]], records: list[dict]) -> Dataset:
    """Stack the jumps' logs into a validated ``Dataset`` with phases, wrench and splits."""
    cat = {k: np.concatenate([lg[k] for lg in logs]) for k in logs[0]}
    jump = np.concatenate([np.full(lg["t"].shape[0], j, np.int32) for j, lg in enumerate(logs)])
    dt = cfg.world.dt * cfg.world.log_every
    counts = split_counts(cfg.n_jumps, cfg.robot, cfg.proxy)
    generator = {
        "generator": "symrom.sim.generate", "version": GENERATOR_VERSION,
        "config": _jsonable(cfg.to_dict()), "fingerprint": cfg.fingerprint(),
        "seeds": {"seed": cfg.seed, "rule": "SeedSequence(seed, spawn_key=(jump, attempt))"},
        "splits": dict(zip(("train", "val", "test"), counts)),
        "retries": int(sum(len(r["retries"]) for r in records)),
        "jumps": [{k: v for k, v in r.items() if k != "mpc_solve_times"} for r in records],
    }
    return assemble(robot=cfg.robot, motion=cfg.motion, source=records[0]["source"], jump=jump,
                    t=cat["t"], q=cat["q"], dq=cat["dq"], tau=cat["tau"], contact=cat["contact"],
                    foot_pos=cat["foot_pos"], split=split_labels(cfg.n_jumps, cfg.robot, cfg.proxy),
                    dt=dt, generator=generator)


def generate(robot: str, motion: str, n_jumps: int, out: str | os.PathLike, seed: int = 0,
             workers: int = 1, noise: bool | NoiseConfig = False, resume: bool = False,
             progress_callback: ProgressCallback | None = None, *, proxy: bool = False,
             force: bool = False, world: WorldConfig | None = None,
             checks: JumpChecks | None = None, max_attempts: int = 8,
             stop_after: int | None = None) -> Dataset | None:
    """Generate ``n_jumps`` checked jumps of ``robot``/``motion`` into the HDF5 file ``out``.

    workers: processes (1 runs in this process); noise: True or a ``NoiseConfig``
    for the noisy variant; resume: reuse the part files of an interrupted run;
    force: overwrite an existing ``out`` and discard stale parts;
    progress_callback(done, total, info) after each jump (info: jump, retries,
    resumed). ``stop_after``: stop once that many jumps exist as parts and
    return None without writing the file (what an interrupted run leaves).
    Returns the written dataset.
    """
    if motion not in MOTIONS:
        raise GenerationError(f"unknown motion {motion!r}; choose from {list(MOTIONS)}")
    get_robot(robot)  # raises ValueError on an unknown robot
    if ROBOT_OF_MOTION[motion] != robot:
        raise GenerationError(f"motion {motion!r} is implemented for robot "
                              f"{ROBOT_OF_MOTION[motion]!r}, not {robot!r}")
    if proxy and motion != "pronk":
        raise GenerationError("--proxy is only available for go1 pronking")
    if n_jumps < 1:
        raise GenerationError(f"need at least one jump, got {n_jumps}")
    if workers < 1:
        raise GenerationError(f"need at least one worker, got {workers}")
    if not motion_available(motion):
        raise GenerationError(f"the {motion} controller (symrom.sim.{motion}) is not installed")
    noise_cfg = NoiseConfig() if noise is True else (noise or None)
    cfg = GenerateConfig(robot=robot, motion=motion, n_jumps=int(n_jumps), seed=int(seed),
                         proxy=proxy, noise=noise_cfg, world=world or WorldConfig(),
                         checks=checks or JumpChecks(), max_attempts=max_attempts)
    out = Path(out)
    if out.exists() and not force:
        raise GenerationError(f"{out} exists; use --force to overwrite it")
    parts = parts_dir(out)
    if parts.exists() and not resume:
        if not force:
            raise GenerationError(f"{parts} holds an interrupted run; use --resume to continue "
                                  f"it or --force to start over")
        shutil.rmtree(parts)
    parts.mkdir(parents=True, exist_ok=True)
    fingerprint = cfg.fingerprint()
    have = []
    for j in range(cfg.n_jumps):
        pp = part_path(parts, j)
        if pp.exists():
            try:
                _, _, fp = read_part(pp)
            except (OSError, ValueError, KeyError):
                pp.unlink()  # a truncated part: run that jump again
                continue
            if fp != fingerprint:
                raise GenerationError(f"{pp} was made with other options; resume with the "
                                      f"same options or use --force to start over")
            have.append(j)
    todo = [j for j in range(cfg.n_jumps) if j not in set(have)]
    if stop_after is not None:
        todo = todo[: max(0, stop_after - len(have))]
    done = len(have)
    total = cfg.n_jumps
    if progress_callback is not None:
        progress_callback(done, total, {"resumed": len(have)})
    if workers == 1 or len(todo) <= 1:
        for j in todo:
            res = _worker(cfg, j, str(parts))
            done += 1
            if progress_callback is not None:
                progress_callback(done, total, res)
    else:
        with ProcessPoolExecutor(max_workers=min(workers, len(todo)),
                                 mp_context=_mp_context()) as pool:
            futures = [pool.submit(_worker, cfg, j, str(parts)) for j in todo]
            try:
                for fut in as_completed(futures):
                    res = fut.result()
                    done += 1
                    if progress_callback is not None:
                        progress_callback(done, total, res)
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
    if done < total:
        return None
    logs, records = [], []
    for j in range(total):
        lg, rec, _ = read_part(part_path(parts, j))
        logs.append(lg)
        records.append(rec)
    ds = build_dataset(cfg, logs, records)
    write_dataset(ds, out)
    shutil.rmtree(parts, ignore_errors=True)
    return ds
