"""Benchmark of the aSLIP's rollout fit (``ASlip.fit(ds, objective="rollout")``), with the compiled
RK4 of ``symrom.baselines.compiled`` (the default) and with the NumPy RK4 every model has, side
by side in one process (not a test). The two must give the same parameters bit for bit; the
script says so. The compiled kernel's first call (numba compiling, or loading its disk cache) is
timed apart.

    symrom generate --robot go1 --motion pronk --jumps 40 --engine mujoco --out go1.h5
    python benchmarks/bench_aslip_fit.py go1.h5 --out benchmarks/results/aslip_fit.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from provenance import provenance

import symrom.baselines.aslip as aslip
from symrom.atomic import write_text_atomic
from symrom.data.io import read_dataset
from symrom.rollout.integrate import RolloutOptions, rollout


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="an HDF5 dataset with a train split")
    ap.add_argument("--repeats", type=int, default=3, help="runs of the compiled fit (the NumPy one runs once)")
    ap.add_argument("--out", type=Path, default=None, help="JSON record of the figures")
    args = ap.parse_args()
    ds = read_dataset(args.data)
    jumps = ds.jumps_in("train")

    t = time.perf_counter()
    rollout(aslip.ASlip(aslip.PAPER_PARAMS), ds, jumps[:1], RolloutOptions("rk4"))
    first = time.perf_counter() - t
    fast, times = None, []
    for _ in range(args.repeats):
        t = time.perf_counter()
        fast = aslip.ASlip.fit(ds, objective="rollout")
        times.append(time.perf_counter() - t)
    compiled = aslip.ASlip.rollout_system
    aslip.ASlip.rollout_system = lambda self, d, j: replace(compiled(self, d, j), compiled=None)
    try:
        t = time.perf_counter()
        slow = aslip.ASlip.fit(ds, objective="rollout")
        numpy_s = time.perf_counter() - t
    finally:
        aslip.ASlip.rollout_system = compiled
    same = fast.params == slow.params and fast.stages == slow.stages
    record = {**provenance(), "data": str(args.data), "train_jumps": int(jumps.size), "first_call_s": first,
              "compiled_s": times, "compiled_median_s": statistics.median(times), "numpy_s": numpy_s,
              "ratio": numpy_s / statistics.median(times), "same_parameters": bool(same),
              "k_s": fast.params.k_s, "l_0": fast.params.l_0, "evaluations": int(np.sum(
                  [s["evaluations"] for s in fast.stages]))}
    print(f"aSLIP rollout fit on {jumps.size} train jumps: compiled {record['compiled_median_s']:.2f} s "
          f"(median of {len(times)}), NumPy {numpy_s:.2f} s ({record['ratio']:.1f}x); first call "
          f"{first:.2f} s; same parameters bit for bit: {same}")
    if args.out:
        write_text_atomic(args.out, json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
