"""Simulated datasets shared by the simulation tests, generated once per test session."""

from __future__ import annotations

import atexit
import fcntl
import os
import shutil
import tempfile
from collections.abc import Callable
from functools import cache
from pathlib import Path

from symrom.sim.generation.generate import GenerateConfig, NoiseConfig, generate

_ROOT = Path(tempfile.mkdtemp(prefix="symrom-simtests-"))
atexit.register(shutil.rmtree, _ROOT, True)
# The datasets every worker of a pytest-xdist run reads are made once for all of them, in the
# folder conftest.py names; a session without it keeps them in _ROOT.
SHARED = Path(os.environ.get("SYMROM_TESTS_SHARED") or _ROOT)

SEED = 3
N_JUMPS = {"froggy": 3, "pronk": 3}  # train, val and test: one jump each
ROBOT = {"froggy": "a1", "pronk": "go1"}


def tmp_path(name: str) -> Path:
    """A fresh path in the session's scratch folder."""
    d = Path(tempfile.mkdtemp(dir=_ROOT))
    return d / name


def shared(name: str, make: Callable[[Path], object]) -> Path:
    """The file ``name`` of the session's shared folder, made by ``make(path)`` if no worker has
    made it yet (one worker makes it while the others wait for it). The makers are seeded, so
    whichever worker makes a file, it is the same file."""
    SHARED.mkdir(exist_ok=True)
    out = SHARED / name
    with open(SHARED / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not out.exists():
            make(out)
    return out


@cache
def reference_file(motion: str, noise: bool = False) -> Path:
    """A small dataset of ``motion`` (one worker, seed ``SEED``)."""
    return shared(f"{motion}{'_noise' if noise else ''}.h5", lambda out: generate(config(motion, noise=noise), out))


def config(motion: str, n_jumps: int | None = None, seed: int = SEED, noise: bool = False,
           robot: str | None = None) -> GenerateConfig:
    """The generation options of the shared datasets (other counts, seeds, robots on request)."""
    return GenerateConfig(robot or ROBOT[motion], motion, N_JUMPS[motion] if n_jumps is None else n_jumps,
                          seed=seed, noise=NoiseConfig() if noise else None)

