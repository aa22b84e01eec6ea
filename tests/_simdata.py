"""Simulated datasets shared by the simulation tests, generated once per test session."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from functools import cache
from pathlib import Path

from symrom.sim.generation.generate import GenerateConfig, NoiseConfig, generate

_ROOT = Path(tempfile.mkdtemp(prefix="symrom-simtests-"))
atexit.register(shutil.rmtree, _ROOT, True)

SEED = 3
N_JUMPS = {"froggy": 3, "pronk": 3}  # train, val and test: one jump each
ROBOT = {"froggy": "a1", "pronk": "go1"}


def tmp_path(name: str) -> Path:
    """A fresh path in the session's scratch folder."""
    d = Path(tempfile.mkdtemp(dir=_ROOT))
    return d / name


@cache
def reference_file(motion: str, noise: bool = False) -> Path:
    """A small dataset of ``motion`` (one worker, seed ``SEED``)."""
    out = tmp_path(f"{motion}{'_noise' if noise else ''}.h5")
    generate(config(motion, noise=noise), out)
    return out


def config(motion: str, n_jumps: int | None = None, seed: int = SEED, noise: bool = False,
           robot: str | None = None) -> GenerateConfig:
    """The generation options of the shared datasets (other counts, seeds, robots on request)."""
    return GenerateConfig(robot or ROBOT[motion], motion, N_JUMPS[motion] if n_jumps is None else n_jumps,
                          seed=seed, noise=NoiseConfig() if noise else None)

