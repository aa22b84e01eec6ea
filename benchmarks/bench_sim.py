"""Benchmark of simulated-data generation (not a test).

For each motion: the real-time factor of generation by one worker (simulated
seconds of kept jumps per wall-clock second, retries included in the wall
time), the same per CPU second of the process (what an otherwise idle core
gives, when other jobs share the machine), the speed-up of two worker
processes over one on the same jumps, and for pronking the median MPC solve
time. The start-up (importing the simulator and compiling, or loading from
numba's disk cache, its compiled routines) is timed apart, before the runs.
Prints a Markdown table and, with ``--out``, writes JSON.

With ``--against SRC`` (the ``src`` folder of another checkout, e.g. a git
worktree of an earlier commit) the same one-worker generations run side by
side, alternating between this code and that one, ``--repeats`` times each,
each in a fresh process after its start-up; the table gives the medians and
their ratio, which a machine shared with other jobs leaves far more stable than
either number.

    python benchmarks/bench_sim.py [--jumps 6] [--seed 0] [--out benchmarks/results/sim.json]
    git worktree add /tmp/ref COMMIT && python benchmarks/bench_sim.py --against /tmp/ref/src
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
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


_CHILD = r"""
import json, sys, tempfile, time
from pathlib import Path
from symrom.sim.controller import load_motion
from symrom.sim.generate import GenerateConfig, generate
motion, robot, n, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
load_motion(motion)
try:
    from symrom.sim.compiled import warm_up
    warm_up()
except ImportError:  # code without compiled routines
    pass
with tempfile.TemporaryDirectory() as d:
    t0, c0 = time.perf_counter(), time.process_time()
    ds = generate(GenerateConfig(robot, motion, n, seed=seed), Path(d) / "x.h5", workers=1)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({"wall_s": wall, "cpu_s": cpu, "simulated_s": ds.n_samples * ds.dt}))
"""


def side_by_side(motion: str, n: int, seed: int, against: Path, repeats: int) -> dict:
    """Real-time factors (wall, per CPU s) of this code and of ``against``, alternating."""
    here = str(Path(__file__).resolve().parents[1] / "src")
    out: dict = {"this": [], "against": []}
    for _ in range(repeats):
        for key, src in (("this", here), ("against", str(against))):
            env = dict(os.environ, PYTHONPATH=src)
            r = subprocess.run([sys.executable, "-c", _CHILD, motion, ROBOT_OF_MOTION[motion], str(n), str(seed)],
                               env=env, check=True, capture_output=True, text=True)
            out[key].append(json.loads(r.stdout.strip().splitlines()[-1]))
    for key in ("this", "against"):
        runs = out[key]
        out[f"{key}_rtf_wall"] = statistics.median(r["simulated_s"] / r["wall_s"] for r in runs)
        out[f"{key}_rtf_cpu"] = statistics.median(r["simulated_s"] / r["cpu_s"] for r in runs)
    out["ratio_wall"] = out["this_rtf_wall"] / out["against_rtf_wall"]
    out["ratio_cpu"] = out["this_rtf_cpu"] / out["against_rtf_cpu"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--against", type=Path, default=None, help="src folder of the code to compare with")
    ap.add_argument("--repeats", type=int, default=3)
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
    if args.against is not None:
        res["against"] = {"src": str(args.against), "repeats": args.repeats, "motions": {}}
        print(f"\nSide by side with {args.against}, one worker, medians of {args.repeats} alternating runs:\n")
        print("| motion | real-time factor, this code (wall / per CPU s) | the other code | ratio (wall / CPU) |")
        print("|---|---|---|---|")
        for motion in ("froggy", "pronk"):
            if not motion_available(motion):
                continue
            r = side_by_side(motion, args.jumps, args.seed, args.against, args.repeats)
            res["against"]["motions"][motion] = r
            print(f"| {ROBOT_OF_MOTION[motion]} {motion} | {r['this_rtf_wall']:.2f} / {r['this_rtf_cpu']:.2f} "
                  f"| {r['against_rtf_wall']:.2f} / {r['against_rtf_cpu']:.2f} "
                  f"| {r['ratio_wall']:.2f} / {r['ratio_cpu']:.2f} |", flush=True)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
