"""Benchmark of simulated-data generation (not a test).

For each motion: the real-time factor of generation on one core (simulated
seconds of kept jumps per wall-clock second, retries included in the wall
time), the speed-up of two worker processes over one on the same jumps, and
for pronking the median MPC solve time. Prints a Markdown table.

    python benchmarks/bench_sim.py [--jumps 4] [--seed 0]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from symrom.sim.generate import GenerateConfig, generate, motion_available

ROBOT_OF_MOTION = {"froggy": "a1", "pronk": "go1"}  # the robots of the paper's datasets


def _run(motion: str, n: int, workers: int, seed: int, out: Path) -> tuple[float, float, list[float]]:
    """(wall s, simulated s, MPC solve times s) of one generation run."""
    solves: list[float] = []
    t0 = time.perf_counter()
    ds = generate(GenerateConfig(ROBOT_OF_MOTION[motion], motion, n, seed=seed), out, workers=workers,
                  force=True, progress_callback=lambda d, t, info: solves.extend(info.get("mpc_solve_times", [])))
    wall = time.perf_counter() - t0
    return wall, ds.n_samples * ds.dt, solves


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for motion in ("froggy", "pronk"):
            if not motion_available(motion):
                rows.append(f"| {motion} | - | - | - | - | controller not installed |")
                continue
            w1, sim, solves = _run(motion, args.jumps, 1, args.seed, Path(tmp) / f"{motion}1.h5")
            w2, _, _ = _run(motion, args.jumps, 2, args.seed, Path(tmp) / f"{motion}2.h5")
            mpc = f"{1e3 * np.median(solves):.2f} ms" if solves else "-"
            rows.append(f"| {ROBOT_OF_MOTION[motion]} {motion} | {args.jumps} | {sim:.1f} s | "
                        f"{sim / w1:.2f} ({w1:.1f} s) | {w1 / w2:.2f}x ({w2:.1f} s) | {mpc} |")
    print("| motion | jumps | simulated | real-time factor, 1 worker (wall) "
          "| speed-up, 2 workers (wall) | median MPC solve |")
    print("|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
