"""Benchmark of a model whose library has no term table (a custom block): fit and rollouts
(not a test).

The model: l = 2, ``Polynomial(1) + Inputs() + Custom(("xi1*nu1", "exp(-xi2**2)"))`` (the
custom terms are not products of powers, inputs, sines and cosines, so the compiled term table
cannot run it), fitted by ``SymbolicROM`` on the planted dataset of the tests (20 jumps x 400
samples, block embedding, noise 1e-4, seed 2). Each code runs in a fresh process with a new,
empty disk cache of the generated code (``SYMROM_CACHE_DIR``), so nothing is built before it:

- ``fit``: the whole ``SymbolicROM.fit`` (its free predictions level the contact guards);
- ``numpy_step``: one free prediction of a test jump on the NumPy path (``backend="numpy"``),
  per RK4 step;
- ``compile``: the generated code's compile time for the model (``compiled.compile_seconds``,
  with the disk cache off);
- ``rollout_auto``: then ``rollout`` of the test jumps with the default backend, the first call.

With ``--before SRC`` the same runs on the ``src`` folder of another checkout, in the same run,
interleaved. Prints a Markdown table and writes JSON.

    python benchmarks/bench_custom.py --runs 2 --before /tmp/before/src --out benchmarks/results/custom.json
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

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, os, time
from symrom import compiled
from symrom.compiled import codegen
from symrom.learn.estimator import SymbolicROM
from symrom.model.library import Custom, Inputs, Polynomial
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.testing import make_planted_dataset
ds, _ = make_planted_dataset(n_jumps=20, n_samples=400, embedding="block", noise=1e-4, seed=2)
rom = SymbolicROM(2, Polynomial(1) + Inputs() + Custom(("xi1*nu1", "exp(-xi2**2)"), ("xi1 nu1", "bump")))
t = time.perf_counter(); rom.fit(ds); fit = time.perf_counter() - t
m = rom.model
jumps = ds.jumps_in("test")
a, b = ds.jump_bounds()[jumps[0]]
opt = RolloutOptions(method="rk4", backend="numpy")
t = time.perf_counter(); m.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, options=opt)
numpy_step = (time.perf_counter() - t) / ((b - a - 1) * opt.substeps)
t = time.perf_counter(); rollout(m, ds, jumps, RolloutOptions("rk4")); first = time.perf_counter() - t
os.environ[compiled.CACHE_ENV] = "off"
codegen._CACHE.clear()
comp = compiled.compile_seconds(m.dynamics())
print(json.dumps({"fit_s": fit, "numpy_step_s": numpy_step, "compile_s": comp, "rollout_auto_first_s": first}))
"""


def run(src: Path) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "SYMROM_CACHE_DIR": cache, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1"}
        t = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True,
                             text=True, env=env, cwd=str(ROOT), check=True)
        rec = json.loads(out.stdout.strip().splitlines()[-1])
        rec["process_s"] = time.perf_counter() - t
        return rec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--before", type=Path, help="the src folder of the code to compare with")
    ap.add_argument("--out", type=Path)
    a = ap.parse_args()
    codes = {"now": ROOT / "src"} | ({"before": a.before} if a.before else {})
    runs: dict[str, list[dict]] = {k: [] for k in codes}
    for _ in range(a.runs):
        for name, src in codes.items():
            runs[name].append(run(src))
    keys = ("fit_s", "numpy_step_s", "compile_s", "rollout_auto_first_s", "process_s")
    med = {n: {k: statistics.median(r[k] for r in rs) for k in keys} for n, rs in runs.items()}
    print("| code | fit | NumPy RK4 step | compile | first `rollout()` (auto) | whole process |")
    print("|---|---|---|---|---|---|")
    for n, m in med.items():
        print(f"| {n} | {m['fit_s']:.2f} s | {1e3 * m['numpy_step_s']:.2f} ms | {m['compile_s']:.2f} s "
              f"| {m['rollout_auto_first_s']:.3f} s | {m['process_s']:.1f} s |")
    if a.out:
        a.out.write_text(json.dumps({**provenance(), "machine": platform.platform(), "medians": med,
                                     "runs": runs}, indent=1) + "\n")


if __name__ == "__main__":
    main()
