"""Randomised generation over many seeds (not a test): does ``--randomize`` finish, and how often
do its draws land?

For each motion (Go1 pronk, A1 froggy), engine and seed, ``symrom generate --randomize`` of
``--jumps`` jumps, as the command runs it: a draw the controller cannot land is replaced by a
fresh draw from the same ranges (``generation.runner.DRAWN_ATTEMPTS``). Per run it records
whether it finished, its wall time, the draws tried and landed (each failed one with its
reasons), the most draws one jump needed; per motion and engine the landing rate, the failed
draws' reasons by kind and, for froggy, the rear-only phase of the kept jumps (s, right
before the flight) by kind of push. Prints a Markdown table and, with ``--out``, writes JSON.

    python benchmarks/bench_randomized.py --seeds 10 --jumps 40 --workers 2 \\
        --out benchmarks/results/randomized.json            # 1,600 jumps
    python benchmarks/bench_randomized.py --seeds 2 --jumps 5 --engines mujoco   # a look
"""

from __future__ import annotations

import argparse
import json
import platform
import re
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np
from provenance import commit

from symrom.atomic import write_text_atomic
from symrom.sim.controllers.flight import longest_run
from symrom.sim.generation.generate import GenerateConfig, GenerationError, generate

MOTIONS = {"pronk": "go1", "froggy": "a1"}


def rear_only(contact: np.ndarray, dt: float) -> float:
    """s on the rear feet alone right before the longest flight, of one jump's flags (n, 4)."""
    air = contact.sum(axis=1) == 0
    a = longest_run(air)[0]
    rear = (contact[:, 0] == 0) & (contact[:, 1] == 0) & (contact[:, 2:].sum(axis=1) > 0)
    n = 0
    while a - n - 1 >= 0 and rear[a - n - 1]:
        n += 1
    return n * dt


def reason_kind(reason: str) -> str:
    """A failed draw's reason without its figures ('apex gain 0.022 m' -> 'apex gain')."""
    return re.sub(r"\s*\(stopped at.*\)", "", re.sub(r"[-+]?\d+(\.\d+)?( m| s| rad)?", "", reason)).strip(" :")


def one_run(motion: str, engine: str, seed: int, jumps: int, workers: int, folder: Path) -> dict:
    """One ``--randomize`` generation: its record (finished, wall time, draws, reasons, rear-only)."""
    out = folder / f"{motion}_{engine}_{seed}.h5"
    cfg = GenerateConfig(MOTIONS[motion], motion, jumps, seed=seed, randomize=True, engine=engine)
    t0 = time.perf_counter()
    try:
        ds = generate(cfg, out, workers=workers, force=True)
    except GenerationError as e:
        return {"motion": motion, "engine": engine, "seed": seed, "finished": False, "error": str(e),
                "wall_time_s": time.perf_counter() - t0}
    wall = time.perf_counter() - t0
    records = ds.generator["jumps"]
    failed = [r for rec in records for f in rec["retries"] for r in f["reasons"]]
    rec = {"motion": motion, "engine": engine, "seed": seed, "finished": True, "wall_time_s": wall,
           "jumps": ds.n_jumps, "draws": int(sum(len(r["retries"]) + 1 for r in records)),
           "most_draws_one_jump": int(max(len(r["retries"]) + 1 for r in records)),
           "failed_reasons": dict(Counter(reason_kind(r) for r in failed))}
    if motion == "froggy":
        rear = [rear_only(ds.contact[a:b], ds.dt) for a, b in ds.jump_bounds()]
        long_push = [r["params"]["t_push_rear"] >= 0.2 for r in records]
        rec["rear_only_s"] = {"quick": [x for x, k in zip(rear, long_push) if not k],
                              "long": [x for x, k in zip(rear, long_push) if k]}
    out.unlink(missing_ok=True)
    Path(str(out) + ".run.json").unlink(missing_ok=True)
    return rec


def summary(runs: list[dict]) -> list[dict]:
    """Per motion and engine: runs finished, jumps, draws, landing rate, reasons, rear-only."""
    rows = []
    for motion in MOTIONS:
        for engine in sorted({r["engine"] for r in runs}):
            rs = [r for r in runs if r["motion"] == motion and r["engine"] == engine]
            if not rs:
                continue
            done = [r for r in rs if r["finished"]]
            draws, jumps = sum(r["draws"] for r in done), sum(r["jumps"] for r in done)
            reasons: Counter = Counter()
            for r in done:
                reasons.update(r["failed_reasons"])
            row = {"motion": motion, "engine": engine, "runs": len(rs), "finished": len(done), "jumps": jumps,
                   "draws": draws, "landing_rate": jumps / draws if draws else None,
                   "most_draws_one_jump": max((r["most_draws_one_jump"] for r in done), default=None),
                   "wall_time_s": sum(r["wall_time_s"] for r in rs), "failed_reasons": dict(reasons.most_common())}
            if motion == "froggy" and done:
                for kind in ("quick", "long"):
                    xs = [x for r in done for x in r["rear_only_s"][kind]]
                    row[f"rear_only_{kind}"] = (None if not xs else
                                                {"jumps": len(xs), "median": float(np.median(xs)),
                                                 "min": float(min(xs)), "max": float(max(xs))})
            rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--jumps", type=int, default=40)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--engines", default="pybullet,mujoco")
    ap.add_argument("--motions", default="pronk,froggy")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    t0 = time.perf_counter()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for motion in args.motions.split(","):
            for engine in args.engines.split(","):
                for seed in range(args.seeds):
                    runs.append(one_run(motion, engine, seed, args.jumps, args.workers, Path(tmp)))
                    r = runs[-1]
                    print(f"{motion} {engine} seed {seed}: " + (f"{r['jumps']} jumps from {r['draws']} draws in "
                          f"{r['wall_time_s']:.0f} s" if r["finished"] else f"STOPPED: {r['error']}"), flush=True)
    rows = summary(runs)
    print("\n| motion | engine | runs finished | jumps | draws | landing rate | most draws, one jump | wall time |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        rate = "-" if r["landing_rate"] is None else f"{r['landing_rate']:.2f}"
        print(f"| {r['motion']} | {r['engine']} | {r['finished']}/{r['runs']} | {r['jumps']} | {r['draws']} | {rate} | "
              f"{r['most_draws_one_jump']} | {r['wall_time_s']:.0f} s |")
    record = {"command": " ".join(["python benchmarks/bench_randomized.py", f"--seeds {args.seeds}",
                                   f"--jumps {args.jumps}", f"--workers {args.workers}",
                                   f"--engines {args.engines}", f"--motions {args.motions}"]),
              "commit": commit(),
              "machine": {"python": platform.python_version(), "cpus": __import__("os").cpu_count()},
              "wall_time_s": time.perf_counter() - t0, "summary": rows, "runs": runs}
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.out, json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
