"""Benchmark of simulated-data generation (not a test).

For each motion: the real-time factor of generation by one worker (simulated
seconds of kept jumps per wall-clock second, retries included in the wall
time), the same per CPU second of the process (what an otherwise idle core
gives, when other jobs share the machine), the speed-up of two worker
processes over one on the same jumps, and for pronking the median MPC solve
time. The start-up (importing the simulator and compiling, or loading from
numba's disk cache, its compiled routines) is timed apart, before the runs.
Prints a Markdown table and, with ``--out``, writes JSON.

    python benchmarks/bench_sim.py [--jumps 6] [--seed 0] [--out benchmarks/results/sim.json]
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from symrom.sim.generate import GenerateConfig, generate, motion_available

ROBOT_OF_MOTION = {"froggy": "a1", "pronk": "go1"}  # the robots of the paper's datasets


def _run(motion: str, n: int, workers: int, seed: int, out: Path) -> dict:
    """Wall and CPU seconds, simulated seconds, retries and MPC solve times of one generation run."""
    solves: list[float] = []
    t0, c0 = time.perf_counter(), time.process_time()
    ds = generate(GenerateConfig(ROBOT_OF_MOTION[motion], motion, n, seed=seed), out, workers=workers,
                  force=True, progress_callback=lambda d, t, info: solves.extend(info.get("mpc_solve_times", [])))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "simulated_s": ds.n_samples * ds.dt,
            "retries": int(ds.generator["retries"]), "mpc_solves": len(solves),
            "mpc_solve_median_s": float(np.median(solves)) if solves else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    t0 = time.perf_counter()
    from symrom.sim.compiled import warm_up
    from symrom.sim.controller import load_motion

    for motion in ROBOT_OF_MOTION:
        if motion_available(motion):
            load_motion(motion)
    warm_up()
    res = {"jumps": args.jumps, "seed": args.seed, "startup_s": time.perf_counter() - t0,
           "machine": {"python": platform.python_version(), "cpu": platform.processor() or platform.machine()},
           "motions": {}}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for motion in ("froggy", "pronk"):
            if not motion_available(motion):
                rows.append(f"| {motion} | - | - | - | - | - | controller not installed |")
                continue
            one = _run(motion, args.jumps, 1, args.seed, Path(tmp) / f"{motion}1.h5")
            two = _run(motion, args.jumps, 2, args.seed, Path(tmp) / f"{motion}2.h5")
            res["motions"][motion] = {"robot": ROBOT_OF_MOTION[motion], "one_worker": one, "two_workers": two,
                                      "rtf_one_worker": one["simulated_s"] / one["wall_s"],
                                      "rtf_per_cpu_s": one["simulated_s"] / one["cpu_s"],
                                      "speedup_two_workers": one["wall_s"] / two["wall_s"]}
            r = res["motions"][motion]
            mpc = f"{1e3 * one['mpc_solve_median_s']:.2f} ms" if one["mpc_solve_median_s"] else "-"
            rows.append(f"| {ROBOT_OF_MOTION[motion]} {motion} | {args.jumps} ({one['retries']} retries) "
                        f"| {one['simulated_s']:.1f} s | {r['rtf_one_worker']:.2f} ({one['wall_s']:.1f} s) "
                        f"| {r['rtf_per_cpu_s']:.2f} | {r['speedup_two_workers']:.2f}x ({two['wall_s']:.1f} s) | {mpc} |")
    print("| motion | jumps | simulated | real-time factor, 1 worker (wall) | per CPU second "
          "| speed-up, 2 workers (wall) | median MPC solve |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\nStart-up (imports, compiled routines compiled or loaded from the cache): {res['startup_s']:.1f} s")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
