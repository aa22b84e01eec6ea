"""Benchmark of the execution back ends (not a test): generation with local processes and with Ray.

A Ray instance with ``--workers`` CPUs is started on this machine first (a cluster that is
up, as ``ray start --head`` leaves it; its start-up time is reported but not counted). Then
``symrom generate`` of ``--jumps`` Go1 pronking jumps runs ``--repeats`` times with each back
end, alternating, each run a fresh command (a new process: its imports, its worker
processes, for Ray its connection and its job's workers, all in the wall time):

    symrom generate --robot go1 --motion pronk --jumps 24 --workers 2 --out L.h5
    symrom generate --robot go1 --motion pronk --jumps 24 --backend ray --address HEAD --out R.h5

Every file must be byte-identical to the first. Other work on the machine slows some runs
more than others, so the overhead ratio is given three ways: the median over the runs of the
ratio of each Ray run to the local run beside it in time (the headline), the median Ray wall
time over the median local one, and the fastest over the fastest.

The scaling to N machines is projected from measured quantities only: the per-jump task
times of the Ray runs (``OUT.run.json``), the dispatch cost per task (no-op tasks), the
driver's cost per finished jump (writing its part file), the assembly of the dataset (a
resumed run whose jumps are all done) and the fixed cost (the rest of the measured wall
time). For n jumps on N machines of c cores:

    T = fixed + max(schedule(task times + dispatch, N c workers), n x part write) + n x assembly per jump

where ``schedule`` is the finish time of the tasks handed out in order, each to the first free
worker, and the task times of larger studies repeat the measured ones. One extra Ray run
with a single worker checks the model against a measurement it was not fitted to.

    python benchmarks/bench_backends.py [--jumps 24] [--workers 2] [--repeats 7] \\
        [--out benchmarks/results/backends.json]
"""

from __future__ import annotations

import argparse
import heapq
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Before Ray is imported: no usage reports, and the instance on the loopback interface.
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")

import numpy as np  # noqa: E402
from provenance import provenance  # noqa: E402

CLI = "import sys; from symrom.cli import main; sys.argv[0] = 'symrom'; main()"
MACHINES = (1, 2, 4, 8, 16, 32)


def _noop(x: int) -> int:
    return x


def _generate(out: Path, jumps: int, seed: int, extra: list[str]) -> float:
    """Wall time (s) of one ``symrom generate`` command in a fresh process."""
    args = ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", str(jumps), "--seed", str(seed),
            "--out", str(out), "--force", *extra]
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", CLI, *args], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"symrom {' '.join(args)} failed:\n{r.stderr}")
    return wall


def schedule(durations: list[float], workers: int) -> float:
    """Finish time of tasks handed out in order, each to the first free of ``workers``."""
    free = [0.0] * min(workers, len(durations))
    heapq.heapify(free)
    end = 0.0
    for d in durations:
        t = heapq.heappop(free) + d
        end = max(end, t)
        heapq.heappush(free, t)
    return end


def dispatch_cost(backend, n: int) -> float:
    """Seconds per task beyond its own work: the wall time of ``n`` no-op tasks times the
    number of workers, over ``n``."""
    list(backend.map(_noop, [(i, (i,)) for i in range(8)]))  # warm the workers
    t0 = time.perf_counter()
    list(backend.map(_noop, [(i, (i,)) for i in range(n)]))
    return (time.perf_counter() - t0) * backend.workers / n


def driver_costs(tmp: Path, reference: Path, jumps: int, seed: int) -> dict:
    """The driver's own work: one part file written (s, median of 20), the assembly and the
    atomic write of the dataset from finished parts (s: a resumed run whose every jump is done,
    its parts cut from the ``reference`` dataset; the file it writes must equal it), and a
    jump's result size (bytes)."""
    from symrom.data.io import read_dataset
    from symrom.sim.generation.generate import GenerateConfig, generate, parts_dir
    from symrom.sim.generation.parts import LOG_KEYS, part_path, write_part

    cfg = GenerateConfig("go1", "pronk", jumps, seed=seed)
    ds = read_dataset(reference)
    out = tmp / "assembly.h5"
    parts = parts_dir(out)
    parts.mkdir()
    logs = []
    for j, (a, b) in enumerate(ds.jump_bounds()):
        log = {k: getattr(ds, k)[a:b] for k in LOG_KEYS}
        logs.append(log)
        write_part(part_path(parts, j), log, {**ds.generator["jumps"][j], "diagnostics": {}}, cfg.fingerprint())
    writes = []
    for _ in range(20):
        t0 = time.perf_counter()
        write_part(tmp / "one_part.npz", logs[0], ds.generator["jumps"][0], cfg.fingerprint(),
                   {"seconds": 1.0, "worker": "w", "retries": []})
        writes.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    generate(cfg, out, resume=True)  # reads the parts, assembles, writes
    assembly = time.perf_counter() - t0
    if out.read_bytes() != reference.read_bytes():
        raise SystemExit("the dataset assembled from the parts differs from the reference")
    return {"part_write_s": statistics.median(writes), "assembly_s": assembly,
            "result_bytes_per_jump": int(np.mean([sum(a.nbytes for a in lg.values()) for lg in logs]))}


def project(task_s: list[float], dispatch_s: float, fixed_s: float, part_write_s: float,
            assembly_per_jump_s: float, n: int, workers: int) -> float:
    """Projected wall time (s) of ``n`` jumps on ``workers`` workers (module docstring)."""
    times = [task_s[i % len(task_s)] + dispatch_s for i in range(n)]
    return fixed_s + max(schedule(times, workers), n * part_write_s) + n * assembly_per_jump_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=24)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--study", type=int, default=1560, help="jumps of the larger study in the projection")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/backends.json"))
    args = ap.parse_args()

    import ray

    from symrom.execution import RayBackend

    load_start = os.getloadavg()[0]
    t0 = time.perf_counter()
    ray.init(num_cpus=args.workers, include_dashboard=False, logging_level="WARNING", log_to_driver=False)
    ray_start = time.perf_counter() - t0
    head = ray.get_runtime_context().gcs_address
    walls: dict[str, list[float]] = {"local": [], "ray": []}
    inner: dict[str, list[float]] = {"local": [], "ray": []}
    tasks: dict[int, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        extra = {"local": ["--workers", str(args.workers)], "ray": ["--backend", "ray", "--address", head]}
        _generate(tmp / "warm.h5", 2, args.seed, extra["local"])  # disk caches, not timed
        reference = None
        for r in range(args.repeats):
            for name in (("local", "ray") if r % 2 == 0 else ("ray", "local")):
                out = tmp / f"{name}{r}.h5"
                walls[name].append(_generate(out, args.jumps, args.seed, extra[name]))
                record = json.loads(Path(str(out) + ".run.json").read_text())
                inner[name].append(record["wall_time_s"])
                if name == "ray":
                    for t in record["tasks"]:
                        tasks.setdefault(t["jump"], []).append(t["seconds"])
                data = out.read_bytes()
                reference = reference or data
                if data != reference:
                    raise SystemExit(f"{out} differs from the first dataset")
                print(f"{name} run {r + 1}: {walls[name][-1]:.2f} s", file=sys.stderr)
        one = tmp / "ray_one_worker.h5"
        one_wall = _generate(one, args.jumps, args.seed, [*extra["ray"], "--workers", "1"])
        if one.read_bytes() != reference:
            raise SystemExit(f"{one} differs from the first dataset")
        one_tasks = [t["seconds"] for t in json.loads(Path(str(one) + ".run.json").read_text())["tasks"]]
        driver = driver_costs(tmp, tmp / "local0.h5", args.jumps, args.seed)
    dispatch = {"ray": dispatch_cost(RayBackend(), 400)}
    ray.shutdown()

    med = {k: statistics.median(v) for k, v in walls.items()}
    pair_ratios = [r / lo for r, lo in zip(walls["ray"], walls["local"])]  # run r of each, side by side
    task_s = [statistics.median(tasks[j]) for j in sorted(tasks)]
    assembly_per_jump = driver["assembly_s"] / args.jumps
    # The fixed cost: what the measured Ray wall time leaves after the tasks, the parts and the assembly.
    fixed = med["ray"] - max(schedule([t + dispatch["ray"] for t in task_s], args.workers),
                             args.jumps * driver["part_write_s"]) - driver["assembly_s"]
    check = project(one_tasks, dispatch["ray"], fixed, driver["part_write_s"], assembly_per_jump, args.jumps, 1)
    rows = []
    for n in (args.jumps, args.study):
        base = project(task_s, dispatch["ray"], fixed, driver["part_write_s"], assembly_per_jump, n, args.workers)
        for m in MACHINES:
            t = project(task_s, dispatch["ray"], fixed, driver["part_write_s"], assembly_per_jump, n,
                        m * args.workers)
            rows.append({"jumps": n, "machines": m, "cores": m * args.workers, "projected_s": round(t, 2),
                         "speedup": round(base / t, 2), "efficiency": round(base / t / m, 3)})
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "ray": ray.__version__,
                    # other work on the machine: the 1-minute load average before and after
                    "load_average": [round(load_start, 2), round(os.getloadavg()[0], 2)]},
        "jumps": args.jumps, "workers": args.workers, "repeats": args.repeats, "seed": args.seed,
        "ray_instance_start_s": round(ray_start, 2),
        "wall_s": {k: [round(x, 2) for x in v] for k, v in walls.items()},
        "wall_median_s": {k: round(v, 2) for k, v in med.items()},
        "overhead_ratio": round(statistics.median(pair_ratios), 3),
        "pair_ratios": [round(x, 3) for x in pair_ratios],
        "overhead_ratio_of_medians": round(med["ray"] / med["local"], 3),
        "wall_min_s": {k: round(min(v), 2) for k, v in walls.items()},
        "overhead_ratio_of_minima": round(min(walls["ray"]) / min(walls["local"]), 3),
        "generate_wall_s": {k: [round(x, 2) for x in v] for k, v in inner.items()},
        "overhead_ratio_inside_generate": round(statistics.median(inner["ray"]) / statistics.median(inner["local"]), 3),
        "datasets_identical": True,
        "task_s": {"median": round(float(np.median(task_s)), 3), "min": round(min(task_s), 3),
                   "max": round(max(task_s), 3), "sum": round(sum(task_s), 2),
                   "per_jump": [round(t, 3) for t in task_s]},
        "dispatch_s_per_task": {k: round(v, 5) for k, v in dispatch.items()},
        "driver": {k: (round(v, 5) if isinstance(v, float) else v) for k, v in driver.items()},
        "fixed_s": round(fixed, 2),
        "model_check_one_worker": {"measured_s": round(one_wall, 2), "projected_s": round(check, 2)},
        "projection": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({**provenance(), **result}, indent=1) + "\n")
    print(f"| back end | wall time, median of {args.repeats} (s) | fastest (s) | runs (s) |\n|---|---|---|---|")
    for k in ("local", "ray"):
        print(f"| {k} | {med[k]:.2f} | {min(walls[k]):.2f} | {', '.join(f'{x:.2f}' for x in walls[k])} |")
    print(f"\noverhead ratio ray / local: {result['overhead_ratio']:.3f} (median of the side-by-side runs), "
          f"{result['overhead_ratio_of_medians']:.3f} (of the medians), "
          f"{result['overhead_ratio_of_minima']:.3f} (of the fastest runs)")
    print(f"\n| jumps | machines ({args.workers} cores each) | projected wall (s) | speed-up | efficiency |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['jumps']} | {r['machines']} | {r['projected_s']:.1f} | {r['speedup']:.2f} "
              f"| {r['efficiency']:.2f} |")
    print(f"\nresults: {args.out}")


if __name__ == "__main__":
    main()
