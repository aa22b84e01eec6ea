"""Benchmark of the default rollout backend (``auto``) across processes (not a test).

The model: l = 3, p = 1 (the paper's library), trained with the exact solver on the
planted dataset of ``bench_rollout.py`` (120 jumps x 800 samples, block embedding,
seed 0); every rollout is ``rollout(model, ds, all jumps, RolloutOptions("rk4"))``
(2 RK4 steps per 2 ms sample, the full horizon), so the default backend decides.

Three fresh processes share one new disk cache of the generated code
(``SYMROM_CACHE_DIR``) and one new numba cache (``NUMBA_CACHE_DIR``):

1. ``cold``: nothing is built: ``auto`` runs the term table (the rollout's 192,000
   steps do not pay for a compilation); then ``generated`` is asked once, which
   compiles the model's code and leaves it in the disk cache;
2. ``warm``: a new process: ``auto`` finds the build on disk and loads it (its first
   call) instead of compiling;
3. ``warm`` again, for the spread between processes.

Each process times, side by side, the whole ``rollout()`` call with ``auto``, ``table``
and ``generated`` (medians of ``--runs``; the first call of each apart), and the
integration alone (``integrate_system`` on the system set up once, as
``bench_rollout.py`` times it), each as samples per second (the 96,000 samples over
the median wall time, and per CPU second of the process, which other jobs on the
machine disturb least). With ``--before SRC`` the same three processes run again on the
``src`` folder of another checkout (say the commit before a change, ``git archive
<commit> src | tar -x -C SRC/..``), with caches of their own, in the same run. Prints a
Markdown table and writes JSON.

    python benchmarks/bench_auto.py --runs 15 --out benchmarks/results/auto.json
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

from provenance import provenance


def child(args: argparse.Namespace) -> dict:
    import numpy as np

    from symrom import compiled
    from symrom.learn.training import TrainConfig, train
    from symrom.rollout.integrate import RolloutOptions, integrate_system, rollout
    from symrom.testing import make_planted_dataset

    ds, _ = make_planted_dataset(args.jumps, args.samples, embedding="block", noise=1e-4, seed=0)
    model = train(ds, TrainConfig(latent_dim=args.latent_dim, poly_order=1))
    samples = ds.n_samples
    out = {"has_build_at_start": compiled.has_build(model.dynamics()), "samples": samples,
           "active_terms": int(model.mask.sum()), "paths": {}}
    order = ["auto", "table", "generated"] if out["has_build_at_start"] else ["auto", "table", "generated", "auto"]
    ref = None
    for i, backend in enumerate(order):
        name = backend if i < 3 else "auto_after_build"
        t0 = time.perf_counter()
        ro = rollout(model, ds, None, RolloutOptions("rk4", backend=backend))
        first = time.perf_counter() - t0
        runs, cpu_runs = [], []
        for _ in range(args.runs):
            t0, c0 = time.perf_counter(), time.process_time()
            ro = rollout(model, ds, None, RolloutOptions("rk4", backend=backend))
            runs.append(time.perf_counter() - t0)
            cpu_runs.append(time.process_time() - c0)
        q = np.concatenate(ro.q_pred)
        ref = q if ref is None else ref
        med = statistics.median(runs)
        sysm, integ, cpu = model.rollout_system(ds, np.arange(ds.n_jumps)), [], []
        for _ in range(args.runs):
            t0, c0 = time.perf_counter(), time.process_time()
            integrate_system(sysm, RolloutOptions("rk4", backend=backend), ds.dt)
            integ.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        cpu_med = statistics.median(cpu_runs)
        out["paths"][name] = {"first_s": first, "median_s": med, "runs": runs, "samples_per_s": samples / med,
                              "cpu_median_s": cpu_med, "cpu_runs": cpu_runs, "samples_per_cpu_s": samples / cpu_med,
                              "integration_median_s": statistics.median(integ), "integration_runs": integ,
                              "integration_samples_per_s": samples / statistics.median(integ),
                              "integration_cpu_median_s": statistics.median(cpu), "integration_cpu_runs": cpu,
                              "integration_samples_per_cpu_s": samples / statistics.median(cpu),
                              "max_diff_vs_first_path": float(np.abs(q - ref).max()),
                              "diverged": int(ro.diverged.sum())}
    out["has_build_at_end"] = compiled.has_build(model.dynamics())
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=120)
    ap.add_argument("--samples", type=int, default=800)
    ap.add_argument("--latent-dim", type=int, default=3)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--before", type=Path, default=None,
                    help="the src folder of another checkout, run the same way for comparison")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(child(args)))
        return
    t_start = time.perf_counter()
    cmd = [sys.executable, __file__, "--child", "--jumps", str(args.jumps), "--samples", str(args.samples),
           "--latent-dim", str(args.latent_dim), "--runs", str(args.runs)]
    procs = {}
    trees = [("", None)] + ([("before_", args.before.resolve())] if args.before else [])
    for prefix, src in trees:
        env = {**os.environ, "SYMROM_CACHE_DIR": tempfile.mkdtemp(prefix="symrom-bench-gen-"),
               "NUMBA_CACHE_DIR": tempfile.mkdtemp(prefix="symrom-bench-numba-")}
        if src is not None:
            env["PYTHONPATH"] = os.pathsep.join([str(src), env.get("PYTHONPATH", "")])
        for name in ("cold", "warm", "warm_again"):
            t0 = time.perf_counter()
            r = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
            procs[prefix + name] = (json.loads(r.stdout.strip().splitlines()[-1])
                                    | {"process_wall_s": time.perf_counter() - t0})
    res = {"dataset": {"jumps": args.jumps, "samples_per_jump": args.samples, "dt": 0.002},
           "model": {"latent_dim": args.latent_dim, "poly_order": 1,
                     "active_terms": procs["cold"]["active_terms"]},
           "substeps": 2, "runs": args.runs, "machine": {"python": platform.python_version(),
                                                         "cpu": platform.machine(), "cpus": os.cpu_count(),
                                                         "load_average": list(os.getloadavg())},
           "before": str(args.before) if args.before else None,
           "processes": procs, "wall_time_s": time.perf_counter() - t_start}
    print("| process | backend | first call | median `rollout()` | samples/s | CPU median `rollout()` | "
          "samples/CPU-s | median integration | samples/s | samples/CPU-s | max diff vs auto |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, p in procs.items():
        for b, r in p["paths"].items():
            print(f"| {name} | {b} | {r['first_s'] * 1e3:.1f} ms | {r['median_s'] * 1e3:.1f} ms | "
                  f"{r['samples_per_s']:.3g} | {r['cpu_median_s'] * 1e3:.1f} ms | {r['samples_per_cpu_s']:.3g} | "
                  f"{r['integration_median_s'] * 1e3:.1f} ms | "
                  f"{r['integration_samples_per_s']:.3g} | {r['integration_samples_per_cpu_s']:.3g} | "
                  f"{r['max_diff_vs_first_path']:.1e} |")
    print(f"\nwall time {res['wall_time_s']:.0f} s")
    if args.out:
        args.out.write_text(json.dumps({**provenance(), **res}, indent=1) + "\n")


if __name__ == "__main__":
    main()
