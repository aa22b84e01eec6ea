"""A new process compiles nothing an earlier one compiled: every numba routine, the term-table
kernels, the autoencoder's passes, the simulation's reads and arithmetic and a model's generated
code are loaded from the disk caches (numba's, keyed by source file; the generated code's, keyed
by the model)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

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
from symrom.learn.training import AdamConfig, TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.sim.generation.warm import warm
from symrom.testing import make_planted_dataset

for kind, name in (("engine", "pybullet"), ("engine", "mujoco"), ("engine", "proxy"), ("motion", "pronk"),
                   ("motion", "froggy")):
    warm(kind, name)
ds, _ = make_planted_dataset(n_jumps=3, n_samples=60, seed=1)
model = train(ds, TrainConfig(latent_dim=1, poly_order=1))
train(ds, TrainConfig(latent_dim=1, poly_order=1, solver="adam", adam=AdamConfig(epochs=1, refine_epochs=1)))
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


# A kernel of its own, in a module of the test's folder: compiled in a second, where the
# refinements' window kernel takes fourteen.
TINY = """
import numba


@numba.njit(cache=True)
def tiny(x):
    return x + 1.0
"""

# Says when it starts, holds the lock (the first helper until a line comes on its input),
# compiles or loads the kernel in it, and prints what numba compiled and when it held the lock.
HELPER = LISTENER + """
import sys
import time

from symrom.execution import compile_lock
from tiny_kernel import tiny

print("started", flush=True)
with compile_lock(tiny):
    entered = time.time()
    print("locked", flush=True)
    if sys.argv[1] == "first":
        sys.stdin.readline()
    tiny(1.0)
    done = time.time()
print(json.dumps({"compiled": compiled, "entered": entered, "done": done}))
"""


def test_a_second_helper_waits_for_the_lock_and_loads_the_first_ones_build(tmp_path):
    # The selection starts a helper beside its grid, and a cold run starts one beside its first
    # simulation: on an empty cache one compiles into numba's disk cache while the other waits for
    # it (execution.compile_lock) and loads its build.
    (tmp_path / "tiny_kernel.py").write_text(TINY)
    cache = tmp_path / "numba"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=os.pathsep.join(
        [str(SRC), str(tmp_path), *filter(None, [os.environ.get("PYTHONPATH")])]))
    procs = []
    try:
        for role in ("first", "second"):
            procs.append(subprocess.Popen([sys.executable, "-c", HELPER, role], stdin=subprocess.PIPE,
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env))
            assert procs[-1].stdout.readline() == "started\n", procs[-1].stderr.read()[-2000:]
            if role == "first":
                assert procs[0].stdout.readline() == "locked\n", procs[0].stderr.read()[-2000:]
        time.sleep(0.5)  # the second reaches the lock while the first holds it
        procs[0].stdin.write("go\n")
        procs[0].stdin.flush()
        outs = [p.communicate(timeout=300) for p in procs]
    finally:
        for p in procs:
            p.kill()
    assert [p.returncode for p in procs] == [0, 0], [err[-2000:] for _, err in outs]
    first, second = (json.loads(out.strip().splitlines()[-1]) for out, _ in outs)
    assert second["entered"] >= first["done"]  # it waited for the first's block
    assert (first["compiled"], second["compiled"]) == (["tiny"], [])  # and loaded its build
    assert [p.name for p in cache.rglob("*tiny*.nbc")]


def test_the_window_helper_compiles_the_kernel_under_the_lock(monkeypatch):
    # What the helper runs (warm_windows): the refinements' kernel, called once, inside
    # compile_lock for that kernel (the test above holds the lock to its word).
    import contextlib

    import symrom.execution
    from symrom.compiled import kernel

    events = []

    def fake_kernel(*args):
        events.append(("called", len(args)))

    @contextlib.contextmanager
    def lock(dispatcher):
        events.append(("lock", dispatcher))
        yield
        events.append(("unlock", dispatcher))

    arity = kernel.kernels()["rk4_windows"].py_func.__code__.co_argcount
    monkeypatch.setattr(kernel, "kernels", lambda: {"rk4_windows": fake_kernel})
    monkeypatch.setattr(symrom.execution, "compile_lock", lock)
    kernel.warm_windows()
    assert events == [("lock", fake_kernel), ("called", arity), ("unlock", fake_kernel)], events


def test_the_window_kernel_builds_its_window_routine_for_one_index_type():
    # The parallel loop's index is unsigned and the loop body is also typed as a plain loop's,
    # signed: passed on as it is, the routine of one window was compiled twice (a third of the
    # kernel's cold build). Its entries in numba's disk cache, once the kernel is built or loaded:
    from symrom.compiled import kernel, table_kernels

    kernel.warm_windows()
    index = table_kernels.one_window._cache._cache_file._load_index()
    assert [str(key[0][0]) for key in index] == ["int64"], list(index)


@pytest.mark.parametrize("cpus, cached", [(2, False), (1, False), (2, True)])
def test_a_cold_froggy_generation_compiles_the_force_distribution_beside_first(monkeypatch, cpus, cached):
    # On an empty cache the helper process compiles the froggy controller's force distribution
    # before the engine's reads: the controller reaches it only after its kinematics and products,
    # so that it is in the disk cache by then. With one core everything is compiled here, in order.
    # This process never makes the distribution ready itself: the controller's routines hold it.
    from symrom.sim.generation import warm

    done, helper = [], []
    monkeypatch.setattr(warm, "in_disk_cache", lambda dispatcher: cached)
    monkeypatch.setattr(warm, "warm", lambda kind, name: done.append((kind, name)))
    monkeypatch.setattr(warm, "start_helper", lambda code: helper.append(code) or "proc")
    monkeypatch.setattr(warm, "wait_helper", lambda proc, timeout: done.append(("waited", proc)))
    monkeypatch.setattr(warm.os, "cpu_count", lambda: cpus)
    warm.prepare("froggy", "mujoco", proxy=True)
    engine = [("engine", "mujoco"), ("engine", "proxy")]
    if cpus == 1 or cached:
        assert helper == [] and done == [("motion", "froggy"), *engine]
        return
    assert len(helper) == 1 and helper[0].endswith("; ".join(f"warm{g!r}" for g in [("beside", "froggy"), *engine]))
    # this process: the motion's routines, then the engine's, loaded from the cache the helper filled
    assert done == [("motion", "froggy"), ("waited", "proc"), *engine]
    assert [d.py_func.__name__ for d in warm.routines("beside", "froggy")] == ["distribute"]
