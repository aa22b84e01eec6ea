"""Whole commands, timed side by side with the previous code (not a test).

Every item is a whole process, as a user runs it, started from clean caches: each run gets
a new, empty numba cache (``NUMBA_CACHE_DIR``) and generated-code cache (``SYMROM_CACHE_DIR``),
unless the item says it runs on filled ones. Each item runs ``--runs`` times on this
checkout's code ("after") and, with ``--before``, on another checkout's ("before"),
interleaved (before, after, then after, before, ...) so that the load of a shared machine
falls on both alike. The record keeps every run's wall time, the CPU time (user + sys) of the
process and its descendants (on Linux the orphans it leaves, such as a pool's fork server, are
adopted and waited for after it ends: ``_adopt_orphans``), and the load average before and
after; the summary gives the medians and the ratio of the medians (after / before), and prints
a Markdown table. The record's ``machine`` holds ``reference_loop_s``, a fixed pure-Python loop
timed before and after the items (``REFERENCE_LOOP``): how fast the machine ran Python then.

Items (``--only`` picks some; ``--reproduce`` and ``--tests`` add the long ones):

- ``version``, ``help``, ``command_help``: ``symrom --version``, ``symrom --help``, ``symrom train --help``;
- ``cold_jump``: ``symrom generate --robot a1 --motion froggy --jumps 3 --engine mujoco`` from
  empty caches, and ``warm_jump``: the same on the caches a first run filled; each run also
  records every jump's own time (``OUT.run.json``);
- ``generate_{pybullet,mujoco}_w{1,2}``: 12 Go1 pronks, ``--workers 1`` and ``2``; the files of
  both sides are compared byte for byte;
- ``randomized_{pybullet,mujoco}``: 6 randomised A1 froggy jumps (``--randomize``: the proxy's
  motors and sensors in every tick), ``--workers 1``, on caches a first run filled; the files of
  both sides are compared byte for byte;
- ``select_{go1_pybullet,go1_mujoco,a1_froggy}``: ``symrom train DATA --select --workers 2`` on 40
  jumps, generated once beforehand by this checkout (not timed); ``..._max10``: the same with
  ``--max-terms 10``;
- ``import_log``, ``import_log_repair``: ``symrom import LOG.csv --robot go1 [--repair]`` of 40 Go1
  pronks written as a plain-layout CSV log (generated once beforehand by this checkout, in
  MuJoCo; not timed);
- ``demo``: ``symrom demo --out DIR``;
- ``rollout``: the default ``rollout()`` of a 3-latent model of 120 planted jumps x 800 samples
  (the median whole call after the first, samples per second), and ``first_calls``: in a new
  process on filled caches, the first ``rollout()`` and ``predict_path()`` against the later
  ones;
- ``tests`` (``--tests``): the README's test command, in each checkout's folder (before:
  ``--before-tests``, default ``python3.11 -m pytest -q``);
- ``reproduce_quick``, ``reproduce`` (``--reproduce``): ``symrom reproduce --out DIR [--quick]``.

    python benchmarks/bench_commands.py --before /path/to/previous/checkout --out benchmarks/results/commands.json
    python benchmarks/bench_commands.py --before-rev HEAD~3 --only version,help,cold_jump
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from provenance import provenance

from symrom.atomic import write_text_atomic

HERE = Path(__file__).resolve().parents[1]
CLI = "import sys; sys.argv[0] = 'symrom'; from symrom.cli import main; main()"
ROLLOUT = r"""
import json, sys, time
import numpy as np
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.testing import make_planted_dataset
runs = int(sys.argv[1])
ds, _ = make_planted_dataset(120, 800, embedding="block", noise=1e-4, seed=0)
model = train(ds, TrainConfig(latent_dim=3, poly_order=1))
if sys.argv[2:] == ["fill"]:  # a build of the model's generated code at hand, as a user's earlier runs leave it
    rollout(model, ds, None, RolloutOptions("rk4", backend="generated"))
opts = RolloutOptions("rk4")
a, b = ds.jump_bounds()[0]
times = {"rollout": [], "predict_path": [], "rollout_cpu": [], "predict_path_cpu": []}
for i in range(runs):
    t, c = time.perf_counter(), time.process_time()
    rollout(model, ds, None, opts)
    times["rollout"].append(time.perf_counter() - t)
    times["rollout_cpu"].append(time.process_time() - c)
    t, c = time.perf_counter(), time.process_time()
    model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=model.phase_index(ds)[a:b])
    times["predict_path"].append(time.perf_counter() - t)
    times["predict_path_cpu"].append(time.process_time() - c)
print(json.dumps({"samples": int(ds.n_samples), "times": times}))
"""


# A fixed pure-Python loop, timed in a new process: how fast this machine runs Python while the
# benchmark runs. The 2-core machines these records come from differ by several times in speed,
# and one machine's speed moves within minutes (docs/benchmarks.md, "Machines differ"); this
# figure, taken before and after the items, says what kind of machine a record is from.
REFERENCE_LOOP = """
import time
t = time.perf_counter()
s = 0
for i in range(10_000_000):
    s += i
print(time.perf_counter() - t)
"""


def reference_seconds(runs: int = 3) -> list[float]:
    """Seconds of ``REFERENCE_LOOP`` in ``runs`` new processes, one after the other."""
    return [round(float(subprocess.run([sys.executable, "-c", REFERENCE_LOOP], check=True, capture_output=True,
                                       text=True).stdout), 3) for _ in range(runs)]


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _adopt_orphans() -> bool:
    """Make this process the reaper of its descendants' orphans (Linux): a command's fork server
    outlives the command by a moment, and its CPU (with its workers') counts only where it is
    reaped. Whether it could."""
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0) == 0  # PR_SET_CHILD_SUBREAPER
    except (OSError, AttributeError):
        return False


ADOPTS = _adopt_orphans()


def _reap_orphans() -> None:
    """Wait for the finished command's adopted descendants, so that their CPU time counts."""
    while ADOPTS:
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return


def run(argv: list[str], src: Path, cwd: Path, caches: Path | None, timeout: float) -> dict:
    """One whole process: wall and CPU time, return code, the tail of its output."""
    env = dict(os.environ, PYTHONPATH=str(src), PYTHONDONTWRITEBYTECODE="1")
    if caches is not None:
        env["NUMBA_CACHE_DIR"] = str(caches / "numba")
        env["SYMROM_CACHE_DIR"] = str(caches / "generated")
    load0, cpu0, t0 = os.getloadavg()[0], _cpu(), time.perf_counter()
    try:
        p = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                           stdin=subprocess.DEVNULL)
        code, out = p.returncode, p.stdout + p.stderr
        last = (p.stdout.strip().splitlines() or [""])[-1]
    except subprocess.TimeoutExpired:
        code, out, last = None, "timeout", ""
    wall = time.perf_counter() - t0
    _reap_orphans()
    return {"wall_s": round(wall, 3), "cpu_s": round(_cpu() - cpu0, 3), "returncode": code,
            "load_before": round(load0, 2), "load_after": round(os.getloadavg()[0], 2), "tail": out[-600:],
            "last_line": last}


def symrom(*args: str) -> list[str]:
    return [sys.executable, "-c", CLI, *args]


class Side:
    """One checkout: its ``src`` and the folder its tests run in."""

    def __init__(self, name: str, root: Path) -> None:
        self.name = name
        self.root = root
        self.src = root / "src" if (root / "src" / "symrom").is_dir() else root


class Items(dict):
    """The items measured so far; ``on_set()`` runs after each one is stored (the record is saved)."""

    on_set = staticmethod(lambda: None)

    def __setitem__(self, key, value) -> None:
        super().__setitem__(key, value)
        self.on_set()


def item_runs(name: str, sides: list[Side], n: int, work: Path, make, timeout: float, after_run=None) -> dict:
    """``n`` interleaved runs of ``make(side, folder) -> (argv, cwd, caches)`` on every side."""
    rec = {s.name: [] for s in sides}
    command = None
    for i in range(n):
        order = sides if i % 2 == 0 else sides[::-1]
        for side in order:
            folder = work / f"{name}-{side.name}-{i}"
            folder.mkdir(parents=True)
            argv, cwd, caches = make(side, folder)
            if command is None:
                command = "symrom " + " ".join(argv[3:]) if argv[2:3] == [CLI] else " ".join(argv)
            r = run(argv, side.src, cwd, caches, timeout)
            if after_run is not None:
                r.update(after_run(side, folder, r))
            rec[side.name].append(r)
            print(f"{name:28s} {side.name:6s} run {i}: {r['wall_s']:8.2f} s wall {r['cpu_s']:8.2f} s cpu "
                  f"load {r['load_before']:.1f}-{r['load_after']:.1f} rc {r['returncode']}", flush=True)
    return {"command": command, "runs": rec}


def fresh(folder: Path) -> Path:
    c = folder / "caches"
    c.mkdir(parents=True, exist_ok=True)
    return c


def jump_seconds(out: Path) -> dict:
    try:
        rec = json.loads(Path(str(out) + ".run.json").read_text())
        seconds = [t.get("seconds") or 0.0 for t in rec["tasks"]]
        # tasks running at once on average: the jumps' own times over the generation's wall time
        return {"jump_seconds": seconds, "generate_wall_s": rec.get("wall_time_s"),
                "workers_seen": len({t.get("worker") for t in rec["tasks"]}),
                "concurrency": round(sum(seconds) / rec["wall_time_s"], 2) if rec.get("wall_time_s") else None}
    except (OSError, ValueError, KeyError):
        return {}


def summarise(items: dict) -> dict:
    for it in items.values():
        med = {}
        for side, runs in it["runs"].items():
            ok = [r for r in runs if r["returncode"] == 0]
            med[side] = {"wall_s": statistics.median(r["wall_s"] for r in ok) if ok else None,
                         "cpu_s": statistics.median(r["cpu_s"] for r in ok) if ok else None,
                         "failed": len(runs) - len(ok)}
            for extra in ("samples_per_s", "samples_per_cpu_s", "first_rollout_s", "later_rollout_s",
                          "first_rollout_cpu_s", "later_rollout_cpu_s", "first_predict_path_s",
                          "later_predict_path_s", "first_predict_path_cpu_s", "later_predict_path_cpu_s"):
                vals = [r[extra] for r in ok if extra in r]
                if vals:
                    med[side][extra] = statistics.median(vals)
        it["median"] = med
        b, a = med.get("before", {}).get("wall_s"), med.get("after", {}).get("wall_s")
        it["ratio_wall"] = round(a / b, 3) if a and b else None
    return items


def markdown(items: dict) -> str:
    lines = ["| item | before: median wall (CPU) | after: median wall (CPU) | after / before | command |",
             "|---|---|---|---|---|"]
    for name, it in items.items():
        cells = []
        for side in ("before", "after"):
            m = it["median"].get(side)
            if not m or m["wall_s"] is None:
                cells.append("-" if not m else f"failed ({m['failed']})")
                continue
            text = f"{m['wall_s']:.2f} s ({m['cpu_s']:.1f} s)"
            if "samples_per_s" in m:
                text += f", {m['samples_per_s']:.3g} samples/s"
            if "first_rollout_s" in m:
                text += (f"; rollout first {1e3 * m['first_rollout_s']:.0f} ms, "
                         f"then {1e3 * m['later_rollout_s']:.1f} ms;"
                         f" predict_path first {1e3 * m['first_predict_path_s']:.0f} ms, then "
                         f"{1e3 * m['later_predict_path_s']:.1f} ms")
            cells.append(text)
        ratio = f"{it['ratio_wall']:.2f}" if it.get("ratio_wall") else "-"
        lines.append(f"| {name} | {cells[0]} | {cells[1]} | {ratio} | `{it['command']}` |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, help="the previous code: a checkout (or its src folder)")
    ap.add_argument("--before-rev", help="the previous code: a git revision of this repository (extracted)")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--only", help="comma-separated items")
    ap.add_argument("--tests", action="store_true", help="time the test command too (long)")
    ap.add_argument("--test-command", default="python3.11 -m pytest -q -n 2", help="this checkout's")
    ap.add_argument("--before-tests", default="python3.11 -m pytest -q", help="the previous code's")
    ap.add_argument("--reproduce", action="store_true", help="time reproduce --quick and the full reproduce (long)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rollout-runs", type=int, default=21)
    ap.add_argument("--timeout", type=float, default=7200.0)
    ap.add_argument("--work", type=Path, help="scratch folder (default: a new temporary one, removed)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/commands.json"))
    args = ap.parse_args()

    work = args.work or Path(tempfile.mkdtemp(prefix="symrom-bench-commands-"))
    work.mkdir(parents=True, exist_ok=True)
    sides = []
    if args.before_rev:
        root = work / "before-checkout"
        root.mkdir()
        archive = subprocess.run(["git", "-C", str(HERE), "archive", args.before_rev, "src", "tests", "pyproject.toml"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(root)], input=archive, check=True)
        sides.append(Side("before", root))
    elif args.before:
        sides.append(Side("before", args.before.resolve()))
    sides.append(Side("after", HERE))
    w = str(args.workers)
    wanted = set(args.only.split(",")) if args.only else None
    T = args.timeout
    items = Items()

    def want(name: str) -> bool:
        return wanted is None or name in wanted

    def save() -> None:  # after every item, so that an interrupted run keeps what it measured
        record = {**provenance(),
                  "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "host": platform.node(),
                              "reference_loop_s": reference},
                  "sides": {s.name: str(s.src) for s in sides}, "runs": args.runs, "items": summarise(items)}
        args.out.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(args.out, json.dumps(record, indent=1) + "\n")

    reference = {"before": reference_seconds()}
    items.on_set = save

    def plain(*cli):
        return lambda side, folder: (symrom(*cli), folder, fresh(folder))

    for name, cli in (("version", ("--version",)), ("help", ("--help",)), ("command_help", ("train", "--help"))):
        if want(name):
            items[name] = item_runs(name, sides, args.runs, work, plain(*cli), T)

    jump = ("generate", "--robot", "a1", "--motion", "froggy", "--jumps", "3", "--engine", "mujoco", "--workers", "1")
    if want("cold_jump"):
        items["cold_jump"] = item_runs(
            "cold_jump", sides, args.runs, work,
            lambda side, folder: (symrom(*jump, "--out", str(folder / "a1.h5")), folder, fresh(folder)), T,
            after_run=lambda side, folder, r: jump_seconds(folder / "a1.h5"))
    if want("warm_jump"):
        filled = {s.name: work / f"filled-{s.name}" for s in sides}
        for s in sides:  # one run fills the caches (not timed)
            run(symrom(*jump, "--out", str(filled[s.name] / "fill.h5")), s.src, fresh(filled[s.name]).parent,
                fresh(filled[s.name]), T)
        items["warm_jump"] = item_runs(
            "warm_jump", sides, args.runs, work,
            lambda side, folder: (symrom(*jump, "--out", str(folder / "a1.h5")), folder, filled[side.name] / "caches"),
            T, after_run=lambda side, folder, r: jump_seconds(folder / "a1.h5"))

    for engine in ("pybullet", "mujoco"):
        for workers in ("1", "2"):
            name = f"generate_{engine}_w{workers}"
            if not want(name):
                continue
            items[name] = item_runs(name, sides, args.runs, work, lambda side, folder, e=engine, k=workers: (
                symrom("generate", "--robot", "go1", "--motion", "pronk", "--jumps", "12", "--engine", e,
                       "--workers", k, "--out", str(folder / "go1.h5")), folder, fresh(folder)), T,
                after_run=lambda side, folder, r: jump_seconds(folder / "go1.h5"))
            files = {s: sorted(work.glob(f"{name}-{s}-*/go1.h5")) for s in ("before", "after")}
            blobs = {p.read_bytes() for s in files for p in files[s]}
            items[name]["files_identical"] = len(blobs) == 1 if blobs else None

    for engine in ("pybullet", "mujoco"):
        name = f"randomized_{engine}"
        if not want(name):
            continue
        def randomized_jumps(n: int, engine: str = engine) -> tuple[str, ...]:
            return ("generate", "--robot", "a1", "--motion", "froggy", "--jumps", str(n), "--randomize", "--seed", "1",
                    "--engine", engine, "--workers", "1")

        randomized = randomized_jumps(6)
        filled = {s.name: work / f"{name}-filled-{s.name}" for s in sides}
        for s in sides:  # one run of one jump fills the caches (not timed)
            run(symrom(*randomized_jumps(1), "--out", str(filled[s.name] / "fill.h5")), s.src,
                fresh(filled[s.name]).parent, fresh(filled[s.name]), T)
        items[name] = item_runs(name, sides, args.runs, work, lambda side, folder, r=randomized, f=filled: (
            symrom(*r, "--out", str(folder / "a1.h5")), folder, f[side.name] / "caches"), T,
            after_run=lambda side, folder, r: jump_seconds(folder / "a1.h5"))
        files = {s: sorted(work.glob(f"{name}-{s}-*/a1.h5")) for s in ("before", "after")}
        blobs = {p.read_bytes() for s in files for p in files[s]}
        items[name]["files_identical"] = len(blobs) == 1 if blobs else None

    selects = {"select_go1_pybullet": ("go1", "pronk", "pybullet"), "select_go1_mujoco": ("go1", "pronk", "mujoco"),
               "select_a1_froggy": ("a1", "froggy", "pybullet")}
    for name, (robot, motion, engine) in selects.items():
        budget = f"{name}_max10"
        if not (want(name) or want(budget)):
            continue
        data = work / f"{name}.h5"
        r = run(symrom("generate", "--robot", robot, "--motion", motion, "--jumps", "40", "--engine", engine,
                       "--workers", w, "--out", str(data)), sides[-1].src, work, fresh(work / f"gen-{name}"), T)
        if r["returncode"] != 0:
            raise SystemExit(f"generating {data} failed: {r['tail']}")
        for item, extra in ((name, ()), (budget, ("--max-terms", "10"))):
            if want(item):
                items[item] = item_runs(item, sides, args.runs, work, lambda side, folder, d=data, x=extra: (
                    symrom("train", str(d), "--out", str(folder / "model"), "--select", "--workers", w, *x), folder,
                    fresh(folder)), T)

    if want("import_log") or want("import_log_repair"):
        data = work / "import-go1.h5"
        r = run(symrom("generate", "--robot", "go1", "--motion", "pronk", "--jumps", "40", "--engine", "mujoco",
                       "--workers", w, "--out", str(data)), sides[-1].src, work, fresh(work / "gen-import"), T)
        if r["returncode"] != 0:
            raise SystemExit(f"generating {data} failed: {r['tail']}")
        from symrom.data.importers import write_plain_csv
        from symrom.data.io import read_dataset

        log = work / "import-go1.csv"
        write_plain_csv(read_dataset(data), log, accelerations=False)
        for item, extra in (("import_log", ()), ("import_log_repair", ("--repair",))):
            if want(item):
                items[item] = item_runs(item, sides, args.runs, work, lambda side, folder, x=extra: (
                    symrom("import", str(log), "--robot", "go1", "--out", str(folder / "go1.h5"), *x), folder,
                    fresh(folder)), T)

    if want("demo"):
        items["demo"] = item_runs("demo", sides, args.runs, work, lambda side, folder: (
            symrom("demo", "--out", str(folder / "demo")), folder, fresh(folder)), T)

    if want("rollout") or want("first_calls"):
        def rollout_stats(side, folder, r):
            try:
                out = json.loads(r.pop("last_line"))
            except (ValueError, KeyError):
                return {}
            t = out["times"]
            later_r, later_p = statistics.median(t["rollout"][1:]), statistics.median(t["predict_path"][1:])
            cpu_r = statistics.median(t["rollout_cpu"][1:])
            return {"samples_per_s": out["samples"] / later_r, "samples_per_cpu_s": out["samples"] / cpu_r,
                    "first_rollout_s": t["rollout"][0], "later_rollout_s": later_r,
                    "first_rollout_cpu_s": t["rollout_cpu"][0], "later_rollout_cpu_s": cpu_r,
                    "first_predict_path_s": t["predict_path"][0], "later_predict_path_s": later_p,
                    "first_predict_path_cpu_s": t["predict_path_cpu"][0],
                    "later_predict_path_cpu_s": statistics.median(t["predict_path_cpu"][1:])}

        filled = {s.name: work / f"rollout-filled-{s.name}" for s in sides}
        for s in sides:  # fill the caches: the generated code built, the kernels compiled (not timed)
            run([sys.executable, "-c", ROLLOUT, "2", "fill"], s.src, work, fresh(filled[s.name]), T)
        items["rollout"] = item_runs("rollout", sides, args.runs, work, lambda side, folder: (
            [sys.executable, "-c", ROLLOUT, str(args.rollout_runs)], folder, filled[side.name] / "caches"), T,
            after_run=rollout_stats)
        items["rollout"]["command"] = "benchmarks/bench_commands.py's ROLLOUT snippet (rollout() and predict_path())"

    if args.tests and want("tests"):
        items["tests"] = item_runs("tests", sides, args.runs, work, lambda side, folder: (
            ["bash", "-c", args.before_tests if side.name == "before" else args.test_command], side.root,
            fresh(folder)), T)

    if args.reproduce:
        for name, extra in (("reproduce_quick", ("--quick",)), ("reproduce", ())):
            if want(name):
                items[name] = item_runs(name, sides, args.runs, work, lambda side, folder, x=extra: (
                    symrom("reproduce", "--out", str(folder / "run"), "--workers", w, *x), folder, fresh(folder)), T)

    reference["after"] = reference_seconds()
    save()
    print(markdown(items))
    print(f"reference loop: {reference['before']} s before the items, {reference['after']} s after")
    if not args.work:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
