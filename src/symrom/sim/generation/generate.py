"""Simulated jump datasets: run checked jumps on a back end and write a dataset file.

``generate(config, out)`` runs ``config.n_jumps`` jumps (``runner.run_checked_jump``)
as tasks of an execution back end (``symrom.execution``: local processes by
default, or a Ray cluster), each in its own world with the seed
``SeedSequence(seed, spawn_key=(jump, attempt))``, so the file depends neither
on the back end nor on the worker count. A task returns its jump's arrays; the
driver writes each finished jump at once to a part file (``parts``),
and ``resume`` reuses them. The dataset is assembled with
``symrom.data.preprocess.assemble`` and written atomically, beside it the run's
record ``OUT.run.json`` (back end, time per jump, workers lost and retried),
and the parts folder is removed. The library never prints: progress goes to a
callback.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.data.io import write_dataset
from symrom.data.preprocess import assemble
from symrom.execution import Backend, LocalBackend
from symrom.motions import MOTIONS, UnknownMotionError, get_motion
from symrom.names import SPLITS
from symrom.robots import ROBOTS, RobotDescriptionError, get_robot, robot_key
from symrom.sim.controllers.motion import QP_SOLVERS
from symrom.sim.engines.registry import EngineRobotError, UnknownEngineError, check_engine, engine_module
from symrom.sim.generation.config import GENERATOR_VERSION, GenerateConfig, NoiseConfig
from symrom.sim.generation.parts import jsonable, part_path, parts_dir, read_part, write_part
from symrom.sim.generation.runner import GenerationError, jump_seed, log_faults_of, run_checked_jump
from symrom.sim.proxy import LOG_FAULTS, ROBOT_FIELDS

__all__ = ["GenerateConfig", "GenerationError", "NoiseConfig", "build_dataset", "generate", "jump_seed",
           "motion_available", "parts_dir", "run_record_path", "split_counts", "split_labels"]

ProgressCallback = Callable[[int, int, dict], None]
RUN_RECORD_VERSION = 1
GENERATOR_NAME = "symrom.sim.generate"  # the files' ``generator.generator``: the generator's name in the format


def motion_available(motion: str) -> bool:
    """Whether the simulation plug-in of ``motion`` can be imported."""
    module = get_motion(motion).plugin.partition(":")[0]
    return importlib.util.find_spec(module) is not None


# ------------------------------------------------------------------ splits
def split_counts(n: int, motion: str, proxy: bool = False) -> tuple[int, int, int]:
    """(train, val, test) jump counts: the motion's paper splits for their sizes, else scaled
    proportionally.

    Largest remainders, ties to the earlier split; at least one train jump, and from
    two jumps on at least one test jump, from three on at least one val jump, so a
    small dataset can still be evaluated.
    """
    splits = get_motion(motion).splits
    ref = splits.get("proxy" if proxy else "", splits[""])
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


def split_labels(n: int, motion: str, proxy: bool = False) -> np.ndarray:
    """(n,) object array of split names, jumps in order: train, then val, then test."""
    tr, va, te = split_counts(n, motion, proxy)
    return np.array(["train"] * tr + ["val"] * va + ["test"] * te, dtype=object)


# ------------------------------------------------------------------ the whole file
def build_dataset(cfg: GenerateConfig, logs: list[dict[str, np.ndarray]], records: list[dict]) -> Dataset:
    """Stack the jumps' logs into a validated ``Dataset`` with phases, wrench and splits."""
    cat = {k: np.concatenate([lg[k] for lg in logs]) for k in logs[0]}
    jump = np.concatenate([np.full(lg["t"].shape[0], j, np.int32) for j, lg in enumerate(logs)])
    dt = cfg.world.dt * cfg.world.log_every
    counts = cfg.splits or split_counts(cfg.n_jumps, cfg.motion, cfg.proxy)
    generator = {
        "generator": GENERATOR_NAME, "version": GENERATOR_VERSION, "engine": cfg.engine,
        "config": jsonable(cfg.to_dict()), "fingerprint": cfg.fingerprint(),
        "seeds": {"seed": cfg.seed, "rule": "SeedSequence(seed, spawn_key=(jump, attempt))"},
        "splits": dict(zip(SPLITS, counts)),
        "retries": int(sum(len(r["retries"]) for r in records)),
        "jumps": [{k: v for k, v in r.items() if k != "diagnostics"} for r in records],
    }
    split = (split_labels(cfg.n_jumps, cfg.motion, cfg.proxy) if cfg.splits is None
             else np.repeat(np.array(SPLITS, dtype=object), counts))
    if cfg.variant == "proxy":  # one robot: its hardware constants, once (each jump's record has them too)
        generator["proxy_robot"] = proxy_robot(records)
    if cfg.log_faults is not None:  # the robot's logger, once (each jump's record has them with its phase)
        generator["log_faults"] = asdict(log_faults_of(cfg))
    if cfg.robot not in ROBOTS:  # a description file: keep its text with the data
        generator["robot_description"] = get_robot(cfg.robot).source.read_text()
    return assemble(robot=cfg.robot, motion=cfg.motion, source=records[0]["source"], jump=jump,
                    t=cat["t"], q=cat["q"], dq=cat["dq"], tau=cat["tau"], contact=cat["contact"],
                    foot_pos=cat["foot_pos"], contact_force=cat["contact_force"], split=split,
                    dt=dt, generator=generator)


def proxy_robot(records: list[dict]) -> dict:
    """The hardware constants (``proxy.ROBOT_FIELDS``) the proxy jumps ``records`` share, as
    simulated; ``GenerationError`` naming the first jump that differs."""

    def of(r: dict) -> dict:
        return {f: r["params"]["proxy"][f] for f in ROBOT_FIELDS}

    first = of(records[0])
    for r in records[1:]:
        if of(r) != first:
            raise GenerationError(f"jump {r['jump']}: its proxy hardware differs from jump "
                                  f"{records[0]['jump']}'s; a proxy dataset is one robot")
    return first


def _preload(cfg: GenerateConfig) -> list[str]:
    """Modules a fresh local worker imports once: the runner, the motion's plug-in, PyBullet (without
    its banner; the pronk's body model reads the URDF with it on any engine), the engine's world and
    the compiled simulation routines from numba's disk cache (``preload``)."""
    return ["symrom.sim.generation.runner", get_motion(cfg.motion).plugin.partition(":")[0],
            "symrom.sim.engines.bullet", engine_module(cfg.engine), "symrom.sim.generation.preload"]


def _prepare(cfg: GenerateConfig, backend: Backend) -> None:
    """On local processes, the compiled routines of the jumps made ready before the first: in
    this process for one worker, on the disk for the workers (a cold cache compiled once, by two
    processes, rather than by every worker or inside the first jump): their fork server, started
    beside this (``Backend.prestart``), loads what the disk cache held as it started, each worker
    the rest on its first jump."""
    if isinstance(backend, LocalBackend):
        import importlib

        from symrom.sim.generation.warm import prepare

        prepare(cfg.motion, cfg.engine, load=backend.workers == 1, proxy=cfg.proxy or cfg.randomize)
        if backend.workers == 1:  # the tasks run here: what a worker imports before its first (``_preload``)
            for module in _preload(cfg)[:-1]:
                importlib.import_module(module)
        else:  # what the dataset's assembly and writing import, while the workers' server starts
            import h5py  # noqa: F401
            import scipy.linalg  # noqa: F401


def run_record_path(out: str | os.PathLike) -> Path:
    """The run's record beside the dataset ``out``: ``OUT.run.json``."""
    return Path(str(out) + ".run.json")


def check_config(cfg: GenerateConfig) -> GenerateConfig:
    """``cfg`` with its robot as a dataset key; ``GenerationError`` naming a bad option."""
    try:
        entry = get_motion(cfg.motion)
        robot = robot_key(cfg.robot)
        get_robot(robot)
        check_engine(cfg.engine, robot)
    except (UnknownMotionError, RobotDescriptionError, UnknownEngineError, EngineRobotError) as e:
        raise GenerationError(str(e)) from None
    if cfg.proxy and cfg.randomize:
        raise GenerationError("proxy=True and randomize=True are two variants; choose one")
    if cfg.log_faults is not None and cfg.log_faults not in LOG_FAULTS:
        raise GenerationError(f"log_faults={cfg.log_faults!r}: not a kind of log faults; one of: "
                              f"{', '.join(LOG_FAULTS)}")
    for flag, variant in (("proxy=True", "proxy"), ("randomize=True", "randomized")):
        if cfg.variant == variant and variant not in entry.variants:
            offered = [m for m, e in MOTIONS.items() if variant in e.variants]
            raise GenerationError(f"{flag} is not a variant of {cfg.motion!r}; motions with it: {offered}")
    if cfg.n_jumps < 1:
        raise GenerationError(f"need at least one jump, got {cfg.n_jumps}")
    if cfg.mpc_solver not in QP_SOLVERS:
        raise GenerationError(f"unknown MPC solver {cfg.mpc_solver!r}; known: {', '.join(QP_SOLVERS)}")
    if cfg.splits is not None and (len(cfg.splits) != 3 or min(cfg.splits) < 0 or sum(cfg.splits) != cfg.n_jumps):
        raise GenerationError(f"splits {tuple(cfg.splits)} must be three jump counts (train, val, test) "
                              f"summing to the {cfg.n_jumps} jumps")
    if not motion_available(cfg.motion):
        raise GenerationError(f"the {cfg.motion} controller ({entry.plugin}) is not installed")
    return cfg if robot == cfg.robot else replace(cfg, robot=robot)


def check_output(out: str | os.PathLike, resume: bool, force: bool) -> Path:
    """``out`` as a path; ``GenerationError`` if it exists (without ``force``) or if an
    interrupted run left parts beside it (without ``resume`` or ``force``)."""
    out = Path(out)
    if out.exists() and not force:
        raise GenerationError(f"{out} exists; pass force=True to overwrite it")
    parts = parts_dir(out)
    if parts.exists() and not resume and not force:
        raise GenerationError(f"{parts} holds an interrupted run; use resume=True to continue "
                              f"it or force=True to start over")
    return out


def _resumable_parts(cfg: GenerateConfig, parts: Path) -> list[int]:
    """Jumps whose part files exist and match ``cfg`` (truncated ones are removed)."""
    fingerprint = cfg.fingerprint()
    have = []
    for j in range(cfg.n_jumps):
        pp = part_path(parts, j)
        if pp.exists():
            try:
                fp = read_part(pp)[2]
            except (OSError, ValueError, KeyError):
                pp.unlink()  # a truncated part: run that jump again
                continue
            if fp != fingerprint:
                raise GenerationError(f"{pp} was made with other options; resume with the "
                                      f"same options or use force=True to start over")
            have.append(j)
    return have


def generate(config: GenerateConfig, out: str | os.PathLike, *, workers: int = 1, resume: bool = False,
             force: bool = False, progress_callback: ProgressCallback | None = None,
             stop_after: int | None = None, backend: Backend | None = None) -> Dataset | None:
    """Generate the jumps of ``config`` into the HDF5 file ``out``; the written dataset.

    backend: where the jumps run (``symrom.execution``; default: ``workers`` local
    processes, 1 running them in this process); resume: reuse the part files of an
    interrupted run; force: overwrite an existing ``out`` and discard stale parts;
    progress_callback(done, total, info) after each jump (info: jump, retries (failed
    attempts of the jump), worker_retries (attempts lost to a dying worker), seconds,
    worker, resumed, the controller's diagnostics). ``stop_after``: stop once that many
    jumps exist as parts and return None without writing the file (what an interrupted
    run leaves). Beside ``out`` goes its run record ``OUT.run.json`` (``run_record_path``).
    """
    cfg = check_config(config)
    if backend is None:
        if workers < 1:
            raise GenerationError(f"need at least one worker, got {workers}")
        backend = LocalBackend(workers)
    out = check_output(out, resume, force)
    parts = parts_dir(out)
    if parts.exists() and not resume:
        shutil.rmtree(parts)  # --force: start over
    parts.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    have = _resumable_parts(cfg, parts)
    todo = [j for j in range(cfg.n_jumps) if j not in set(have)]
    if stop_after is not None:
        todo = todo[: max(0, stop_after - len(have))]
    done, total = len(have), cfg.n_jumps
    say = progress_callback or (lambda d, t, info: None)
    say(done, total, {"resumed": len(have)})
    fingerprint = cfg.fingerprint()
    tasks = [(j, (j,)) for j in todo]
    preload = _preload(cfg)
    if len(tasks) > 1:
        backend.prestart(preload)
    if tasks:
        _prepare(cfg, backend)
    for task in backend.map(run_checked_jump, tasks, (cfg,), label="generate jump", preload=preload):
        log, record = task.value
        execution = {"seconds": round(task.seconds, 4), "worker": task.worker, "retries": task.retries}
        write_part(part_path(parts, task.key), log, record, fingerprint, execution)
        done += 1
        say(done, total, {"jump": task.key, "retries": len(record["retries"]), "samples": record["samples"],
                          "worker_retries": len(task.retries), "seconds": task.seconds, "worker": task.worker,
                          **record["diagnostics"]})
    if done < total:
        return None
    logs, records, runs = [], [], []
    for j in range(total):
        lg, rec, _, execution = read_part(part_path(parts, j))
        logs.append(lg)
        records.append(rec)
        runs.append({"jump": j, **(execution or {}), "resumed": j in have})
    ds = build_dataset(cfg, logs, records)
    write_dataset(ds, out)
    write_text_atomic(run_record_path(out), json.dumps(
        {"version": RUN_RECORD_VERSION, "dataset": out.name, "fingerprint": fingerprint, "engine": cfg.engine,
         "execution": backend.describe(), "jumps": total, "resumed": len(have),
         "wall_time_s": round(time.perf_counter() - t0, 3),
         "worker_retries": sum(len(r.get("retries", [])) for r in runs), "tasks": runs}, indent=1) + "\n")
    shutil.rmtree(parts, ignore_errors=True)
    return ds
