"""Costs that choices in the code rest on (not a test); docs/benchmarks.md cites them.

- PyBullet clients: a DIRECT client connected and disconnected anew, against one taken from and
  given back to the process's pool (``symrom.sim.engines.bullet.client`` / ``release``, which
  empties it with ``resetSimulation``); ms per client, median of ``--repeats`` rounds of 20.
- The controllers' compiled routines (``symrom.sim.controllers.compiled.warm_up``): their first
  compilation, in a fresh process with an empty numba cache, without and with the froggy
  controller's; then the same with the cache filled (what every later process pays).

    python benchmarks/bench_costs.py [--repeats 5] [--out benchmarks/results/costs.json]
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

SRC = Path(__file__).resolve().parents[1] / "src"


def bullet_clients(repeats: int, n: int = 20) -> dict[str, float]:
    from symrom.sim.engines.bullet import client, p, release

    def fresh() -> None:
        p.disconnect(p.connect(p.DIRECT))

    def pooled() -> None:
        release(client())

    out = {}
    for name, fn in (("connect_disconnect_ms", fresh), ("pool_client_release_ms", pooled)):
        fn()
        rounds = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            rounds.append((time.perf_counter() - t0) / n * 1e3)
        out[name] = statistics.median(rounds)
    return out


def warm_up_seconds(froggy: bool, cache: str) -> float:
    """Wall time of ``warm_up(froggy)`` in a new process whose numba cache is ``cache``."""
    code = ("import time; from symrom.sim.controllers.compiled import warm_up; t = time.perf_counter(); "
            f"warm_up(froggy={froggy}); print(time.perf_counter() - t)")
    env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": str(SRC)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    return float(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    t0 = time.perf_counter()
    result: dict = {**provenance(), "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                                "load_1min": os.getloadavg()[0]},
                    "bullet": bullet_clients(args.repeats), "warm_up_s": {}}
    for froggy in (False, True):
        with tempfile.TemporaryDirectory() as cache:
            first = warm_up_seconds(froggy, cache)
            cached = warm_up_seconds(froggy, cache)
        result["warm_up_s"]["with_froggy" if froggy else "pronk_and_mpc"] = {"first": first, "cached": cached}
    result["wall_time_s"] = time.perf_counter() - t0
    b, w = result["bullet"], result["warm_up_s"]
    print(f"PyBullet: connect + disconnect {b['connect_disconnect_ms']:.1f} ms, pooled client "
          f"{b['pool_client_release_ms']:.1f} ms")
    for k, v in w.items():
        print(f"warm_up ({k}): first {v['first']:.1f} s, cached {v['cached']:.2f} s")
    if args.out:
        from symrom.atomic import write_text_atomic

        write_text_atomic(args.out, json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
