"""Shared fixtures: planted datasets made once per test session."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest

from symrom.execution import THREADS_ENV, limit_threads
from symrom.testing import make_planted_dataset

# Read by Ray when it is imported, so set before any test imports it (and inherited by the
# command-line runs the tests start): no usage reports, and every address of the test
# instance on the loopback interface (Ray's single-machine mode).
os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
# Under pytest-xdist each worker shares the cores with the others: BLAS and symrom's kernels keep
# to its share, in the worker and in the processes its tests start (symrom.execution.limit_threads
# says why).
if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) > 1:
    _share = max(1, (os.cpu_count() or 1) // int(os.environ["PYTEST_XDIST_WORKER_COUNT"]))
    os.environ.setdefault("OPENBLAS_NUM_THREADS", str(_share))
    os.environ.setdefault(THREADS_ENV, str(_share))
    limit_threads(_share)


def _session_folder(env: str, prefix: str) -> None:
    """A temporary folder named by ``env`` for the whole run: made by the process that starts
    the run (pytest-xdist's workers inherit the name) and removed when that process ends."""
    if env not in os.environ:
        os.environ[env] = tempfile.mkdtemp(prefix=prefix)
        atexit.register(shutil.rmtree, os.environ[env], True)


# The generated code's disk cache of the test session, not the user's (symrom.compiled.codegen).
_session_folder("SYMROM_CACHE_DIR", "symrom-tests-cache-")
# The simulated datasets the tests share (tests/_simdata.py), made once for every worker of a run.
_session_folder("SYMROM_TESTS_SHARED", "symrom-simtests-shared-")


@pytest.fixture(scope="session")
def planted_axis():
    """Axis-aligned embedding: the exact solver must recover the planted equations."""
    return make_planted_dataset(n_jumps=24, n_samples=400, embedding="axis", noise=1e-4, seed=1)


@pytest.fixture(scope="session")
def planted_block():
    """Every configuration component driven by a latent: rollouts are checked on all 18."""
    return make_planted_dataset(n_jumps=20, n_samples=400, embedding="block", noise=1e-4, seed=2)


@pytest.fixture(scope="session")
def small_block():
    """``planted_block``'s system on 8 jumps of 0.4 s: for tests that run whole selections on
    it, whose checks do not need more data."""
    return make_planted_dataset(n_jumps=8, n_samples=200, embedding="block", noise=1e-4, seed=2)[0]


def normalised_mae(metrics, ds, split: str = "test") -> dict[str, np.ndarray]:
    """Per horizon of ``Metrics``: MAE / spread of each component over the split (18,)."""
    spread = np.ptp(ds.q[ds.rows_of(split)], axis=0)
    return {h: np.array([s.mae for s in v.components.values()]) / spread for h, v in metrics.horizons.items()}


def one_line_error(result, *needles: str) -> str:
    """Assert a CLI run failed with exactly one line of output, no traceback, naming
    every ``needle``; return that line."""
    out = result.output
    assert result.exit_code != 0, out
    assert "Traceback" not in out
    lines = [line for line in out.splitlines() if line.strip()]
    assert len(lines) == 1, out
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def as_format(d: dict, version: int) -> dict:
    """A model file's dict (``model_to_dict``) as a file of an older ``version`` (1-4) held it:
    the provenance as the untyped ``info`` object (``Provenance.to_info``)."""
    from symrom.model.provenance import Provenance

    d = dict(d)
    if "provenance" in d:
        d["info"] = Provenance.from_dict(d.pop("provenance")).to_info()
    d["format_version"] = version
    return d
