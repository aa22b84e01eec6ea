"""Shared fixtures: planted datasets made once per test session."""

from __future__ import annotations

import atexit
import json
import os
import shutil
import tempfile
from pathlib import Path

from symrom.execution import THREADS_ENV, limit_threads, pin_blas_kernel

# Before NumPy loads, as the command line does: the tests' own processes and the command-line
# runs they start do the same arithmetic.
pin_blas_kernel()

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from symrom.atomic import write_text_atomic  # noqa: E402
from symrom.testing import make_planted_dataset  # noqa: E402

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


# Seconds each test file took (setup, call and teardown of its tests) on a run of the whole suite:
# pytest-xdist's ``--dist loadfile`` hands the files out in this order, longest first, so that the
# last ones are short and both workers finish together (by default it orders them by their number
# of tests, and a one-test file of eight seconds may come last). Files not listed go first.
# ``pytest --record-file-durations tests/durations.json`` writes it anew.
_DURATIONS = Path(__file__).with_name("durations.json")


def pytest_addoption(parser):
    parser.addoption("--record-file-durations", metavar="FILE", default=None,
                     help="write the seconds each test file took to FILE (JSON), for the order of later runs")


class _FileSeconds:
    """Adds up each test file's seconds from the reports of every worker (in the process that
    starts the run) and writes them to ``out`` at the end."""

    def __init__(self, out: str):
        self.out, self.seconds = Path(out), {}

    def pytest_runtest_logreport(self, report):
        file = report.nodeid.split("::")[0]
        self.seconds[file] = self.seconds.get(file, 0.0) + report.duration

    def pytest_sessionfinish(self):
        seconds = {f: round(s, 1) for f, s in sorted(self.seconds.items())}
        write_text_atomic(self.out, json.dumps(seconds, indent=1) + "\n")


def pytest_configure(config):
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False  # the order below, not xdist's count of tests
    out = config.getoption("--record-file-durations")
    if out and "PYTEST_XDIST_WORKER" not in os.environ:
        config.pluginmanager.register(_FileSeconds(out), "symrom-file-seconds")


def pytest_collection_modifyitems(config, items):
    seconds = json.loads(_DURATIONS.read_text()) if _DURATIONS.is_file() else {}
    items.sort(key=lambda item: -seconds.get(item.nodeid.split("::")[0], float("inf")))


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
