"""Simulated datasets shared by the simulation tests, generated once per test session."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from functools import cache
from pathlib import Path

from symrom.sim.generate import generate, motion_available

_ROOT = Path(tempfile.mkdtemp(prefix="symrom-simtests-"))
atexit.register(shutil.rmtree, _ROOT, True)

SEED = 3
N_JUMPS = {"froggy": 3, "pronk": 2}
ROBOT = {"froggy": "a1", "pronk": "go1"}


def tmp_path(name: str) -> Path:
    """A fresh path in the session's scratch folder."""
    d = Path(tempfile.mkdtemp(dir=_ROOT))
    return d / name


@cache
def reference_file(motion: str, noise: bool = False) -> Path:
    """A small dataset of ``motion`` (one worker, seed ``SEED``)."""
    out = tmp_path(f"{motion}{'_noise' if noise else ''}.h5")
    generate(ROBOT[motion], motion, N_JUMPS[motion], out, seed=SEED, workers=1, noise=noise)
    return out


def have(motion: str) -> bool:
    return motion_available(motion)
