"""A new process compiles nothing an earlier one compiled: every numba routine, the term-table
kernels, the autoencoder's passes, the simulation's reads and arithmetic and a model's generated
code are loaded from the disk caches (numba's, keyed by source file; the generated code's, keyed
by the model)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

# Records what numba compiles in a process: the compile event fires only for builds that were
# not found in the disk cache, nested ones included.
LISTENER = """
import json
from numba.core import event

compiled = []


class Compiles(event.Listener):
    def on_start(self, e):
        pass

    def on_end(self, e):
        compiled.append(e.data["dispatcher"].py_func.__qualname__)


event.register("numba:compile", Compiles())
"""

# Runs every compiled path once (l = 1: the generated code's build the cheapest; the kernels are
# typed by the arrays' ranks, not their sizes).
WORK = """
import numpy as np

from symrom import compiled as C
from symrom.learn.training import TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.sim.generation.warm import warm
from symrom.testing import make_planted_dataset

for kind, name in (("engine", "pybullet"), ("engine", "mujoco"), ("engine", "proxy"), ("motion", "pronk"),
                   ("motion", "froggy")):
    warm(kind, name)
ds, _ = make_planted_dataset(n_jumps=3, n_samples=60, seed=1)
model = train(ds, TrainConfig(latent_dim=1, poly_order=1))
for backend in ("table", "generated"):
    rollout(model, ds, None, RolloutOptions("rk4", backend=backend))
j = 0
a, b = ds.jump_bounds()[j]
model.predict_path(ds.q[a], ds.dq[a], ds.u[a:b], ds.dt, phases=model.phase_index(ds)[a:b],
                   options=RolloutOptions("rk4", backend="table"))
dyn = model.dynamics()
P, p, l = model.Xi.shape
win = np.zeros((2, 5, l))
C.rollout_windows(dyn.terms, model.Xi, np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int64),
                  win, win, win, np.zeros((2, 5), np.int64), ds.dt, np.full(2 * l, 1e3))
"""
# ... in a new process, and prints what numba compiled.
CODE = LISTENER + WORK + "print(json.dumps(compiled))\n"


def test_a_new_process_compiles_nothing_an_earlier_one_compiled(tmp_path, monkeypatch):
    from collections import OrderedDict

    from symrom.compiled import codegen

    # The earlier process is this one: it fills the disk caches (compiling what a fresh checkout
    # lacks), the generated code's in a folder of its own and not from this process's memory.
    monkeypatch.setenv(codegen.CACHE_ENV, str(tmp_path / "generated"))
    monkeypatch.setattr(codegen, "_CACHE", OrderedDict())
    exec(WORK, {})
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), *filter(None, [os.environ.get("PYTHONPATH")])]))
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, timeout=900, env=env)
    assert r.returncode == 0, r.stderr
    compiled = json.loads(r.stdout.strip().splitlines()[-1])
    assert compiled == [], compiled


HELPER = LISTENER + """
from symrom.compiled import warm_windows

warm_windows()
print(json.dumps(compiled))
"""


def test_two_window_helpers_at_once_compile_the_kernel_once_into_the_disk_cache(tmp_path):
    # The selection starts a helper beside its grid, and a cold run starts one beside its first
    # simulation: on an empty cache one compiles the refinements' kernel into numba's disk cache
    # while the other waits for it (execution.compile_lock) and loads its build.
    cache = tmp_path / "numba"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join([str(SRC), *filter(None, [os.environ.get("PYTHONPATH")])]))
    procs = [subprocess.Popen([sys.executable, "-c", HELPER], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env) for _ in range(2)]
    outs = [p.communicate(timeout=900) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err[-2000:] for _, err in outs]
    compiled = sorted((json.loads(out.strip().splitlines()[-1]) for out, _ in outs), key=len)
    assert compiled[0] == [] and "rk4_windows" in compiled[1], compiled
    assert [p.name for p in cache.rglob("*rk4_windows*.nbi")]
    assert [p.name for p in cache.rglob("*rk4_windows*.nbc")]
