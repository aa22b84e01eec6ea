"""The Ray back end on one local Ray instance (2 CPUs): the same datasets (byte for byte), sweep
and selection tables as the local back end; a worker killed mid-task is retried and recorded;
a run killed midway finishes with --resume."""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import _tasks
import numpy as np
import pytest
from _simdata import SEED
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.execution import RayBackend, WorkerLostError
from symrom.model.persistence import load_model
from symrom.sim.generation.generate import GenerateConfig, generate, parts_dir, run_record_path

# Ray is imported by this file's instance (``ray_address``), not when the file is collected: every
# worker of the suite collects every file, and Ray's import takes most of a second.
if importlib.util.find_spec("ray") is None:
    pytest.skip("could not import 'ray'", allow_module_level=True)

runner = CliRunner()
# Two jumps, the fewest a run killed after one can resume; in MuJoCo, whose pronk jumps are the
# cheapest (the back end does not depend on the engine).
JUMPS = 2
ENGINE = "mujoco"


@pytest.fixture(scope="module")
def ray_address():
    """One local Ray instance with 2 CPUs for this file's tests, shut down after them (its
    daemons would otherwise idle beside the rest of the session); its address."""
    import ray

    # The test helpers are not installed: Ray's workers get them by value.
    ray.cloudpickle.register_pickle_by_value(_tasks)
    ray.init(num_cpus=2, include_dashboard=False, logging_level="WARNING", log_to_driver=False)
    yield ray.get_runtime_context().gcs_address
    ray.shutdown()


def _generate_args(out: Path, *extra: str) -> list[str]:
    return ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", str(JUMPS), "--seed", str(SEED),
            "--engine", ENGINE, "--out", str(out), "--backend", "ray", *extra]


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> bytes:
    """The bytes of the file ``_generate_args`` makes, made on the local back end (one worker)."""
    out = tmp_path_factory.mktemp("ray_reference") / "pronk.h5"
    generate(GenerateConfig("go1", "pronk", JUMPS, seed=SEED, engine=ENGINE), out)
    return out.read_bytes()


def _symrom(*args: str) -> subprocess.Popen:
    """``symrom ARGS`` in a new process (a driver of its own, connecting to the test instance)."""
    code = "import sys; from symrom.cli import main; sys.argv[0] = 'symrom'; main()"
    return subprocess.Popen([sys.executable, "-c", code, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_for(found, timeout: float, what: str):
    t0 = time.monotonic()
    while not (value := found()):
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"no {what} within {timeout} s")
        time.sleep(0.02)
    return value


def _descends_from_me(pid: int) -> bool:
    """Whether process ``pid`` was started (through any chain) by this test process."""
    me = os.getpid()
    while pid > 1:
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return False
        pid = int(stat.rpartition(")")[2].split()[1])  # the parent's pid
        if pid == me:
            return True
    return False


def _task_processes(title: str) -> list[int]:
    """Ray worker processes of this test's instance now running a task named ``title ...``."""
    pids = []
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                cmd = (p / "cmdline").read_bytes()
            except OSError:
                continue
            if cmd.startswith(f"ray::{title}".encode()) and _descends_from_me(int(p.name)):
                pids.append(int(p.name))
    return pids


# ---------------------------------------------------------------- the back end itself
def test_ray_map_results_retries_and_errors(ray_address, tmp_path):
    be = RayBackend()
    done = {d.key: d for d in be.map(_tasks.square, [(x, (x,)) for x in range(4)], (100,), label="square")}
    assert {k: d.value for k, d in done.items()} == {x: 100 + x * x for x in range(4)}
    assert all(d.retries == [] and not d.worker.endswith(f":{os.getpid()}") for d in done.values())
    assert be.describe()["backend"] == "ray" and be.describe()["cpus"] == 2 and be.workers == 2
    # Before any worker dies: the tasks below wait for Ray to start new ones, this one does not.
    with pytest.raises(ValueError, match="task 2 refuses: a bad input"):  # raised as the task raised it
        list(RayBackend().map(_tasks.refuse, [(x, (x,)) for x in range(4)]))

    # A worker that dies mid-task: the task runs again, and the lost attempt is recorded.
    done = {d.key: d for d in RayBackend().map(_tasks.die_once, [(x, (x,)) for x in range(2)], (str(tmp_path),))}
    assert {k: d.value for k, d in done.items()} == {0: 0, 1: 10}
    for d in done.values():
        # One lost attempt each, or two where Ray had queued a task's first attempt on the other
        # task's worker as it died (that attempt is lost without having run): numbered in order.
        assert [r["attempt"] for r in d.retries] in ([0], [0, 1]), d.retries
        assert all(r["cause"].startswith("WorkerCrashedError") for r in d.retries)
    assert sum(len(d.retries) for d in done.values()) <= 3

    with pytest.raises(WorkerLostError, match="doomed 0: its worker died 2 times, more than the 1 retries allowed"):
        list(RayBackend(max_retries=1).map(_tasks.always_die, [(0, (0,))], label="doomed"))


def test_unreachable_address_is_one_clear_line(tmp_path):
    # A fresh process: this one is already connected to the test instance.
    proc = _symrom(*_generate_args(tmp_path / "d.h5", "--address", "127.0.0.1:1"))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 1
    lines = [ln for ln in (out + err).splitlines() if ln.strip()]
    assert lines == ["error: cannot reach the Ray cluster at 127.0.0.1:1: Connection refused (is its head running? "
                     "see ray start --head)"]
    assert not (tmp_path / "d.h5").exists()
    one_line_error(runner.invoke(app, _generate_args(tmp_path / "d.h5", "--address", "nowhere")),
                   "'nowhere': expected host:port")


# ---------------------------------------------------------------- generation
@pytest.mark.slow
def test_generate_on_ray_is_byte_identical(ray_address, reference, tmp_path):
    out = tmp_path / "ray.h5"
    r = runner.invoke(app, _generate_args(out))
    assert r.exit_code == 0, r.output
    assert "ray: 1 node(s), 2 CPUs, 2 tasks at once" in r.output
    assert out.read_bytes() == reference
    record = json.loads(run_record_path(out).read_text())
    assert record["execution"]["backend"] == "ray" and record["worker_retries"] == 0
    assert [t["jump"] for t in record["tasks"]] == list(range(JUMPS))
    assert all(t["seconds"] > 0 and t["worker"] for t in record["tasks"])
    assert not parts_dir(out).exists()


@pytest.mark.slow
def test_a_worker_killed_mid_jump_is_retried_and_recorded(ray_address, reference, tmp_path):
    out = tmp_path / "killed_worker.h5"
    # The driver runs in a thread of this process, on the workers the session has started.
    with ThreadPoolExecutor(1) as pool:
        run = pool.submit(runner.invoke, app, _generate_args(out))
        pids = _wait_for(lambda: _task_processes("symrom generate jump"), 120, "running generation task")
        os.kill(pids[0], signal.SIGKILL)
        result = run.result(timeout=300)
    assert result.exit_code == 0, result.output
    assert out.read_bytes() == reference
    record = json.loads(run_record_path(out).read_text())
    lost = [r for t in record["tasks"] for r in t["retries"]]
    assert record["worker_retries"] == len(lost) >= 1
    assert all(r["cause"].startswith("WorkerCrashedError") for r in lost)
    assert "lost to dying workers, run again" in result.output


@pytest.mark.slow
def test_a_run_killed_midway_resumes_to_the_same_file(ray_address, reference, tmp_path):
    out = tmp_path / "resumed.h5"
    # One task at a time: the driver is killed after its first jump, before its second can finish.
    proc = _symrom(*_generate_args(out, "--address", ray_address, "--workers", "1"))
    try:
        _wait_for(lambda: list(parts_dir(out).glob("jump_*.npz")), 180, "finished jump")
    finally:
        proc.kill()  # the driver dies with tasks still running
        proc.wait()
    assert not out.exists()
    kept = len(list(parts_dir(out).glob("jump_*.npz")))
    assert 1 <= kept < JUMPS
    one_line_error(runner.invoke(app, _generate_args(out)), "--resume")
    r = runner.invoke(app, _generate_args(out, "--resume"))
    assert r.exit_code == 0, r.output
    assert out.read_bytes() == reference
    record = json.loads(run_record_path(out).read_text())
    assert record["resumed"] == kept == sum(t["resumed"] for t in record["tasks"])


# ---------------------------------------------------------------- sweep and selection
@pytest.fixture(scope="module")
def planted_file(small_block, tmp_path_factory):
    path = tmp_path_factory.mktemp("ray_data") / "planted.h5"
    write_dataset(small_block, path)
    return path


def test_sweep_on_ray_gives_the_local_table(ray_address, planted_file, tmp_path):
    args = ["sweep", str(planted_file), "--latent-dims", "1-3", "--seeds", "2"]
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "local")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "ray"), "--backend", "ray"])
    assert r.exit_code == 0, r.output
    local, on_ray = (json.loads((tmp_path / d / "sweep.json").read_text()) for d in ("local", "ray"))
    assert on_ray == local
    for cell in (tmp_path / "ray" / "cells").iterdir():
        c = json.loads(cell.read_text())
        assert c["execution"]["backend"] == "ray" and c["execution"]["retries"] == []
        same = json.loads((tmp_path / "local" / "cells" / cell.name).read_text())
        assert {k: v for k, v in c.items() if k not in ("seconds", "execution")} == \
               {k: v for k, v in same.items() if k not in ("seconds", "execution")}


def test_train_select_on_ray_gives_the_local_table(ray_address, planted_file, tmp_path):
    args = ["train", str(planted_file), "--select", "--select-dims", "2"]
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "local")])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, [*args, "--out", str(tmp_path / "ray"), "--backend", "ray"])
    assert r.exit_code == 0, r.output
    local, on_ray = (json.loads((tmp_path / d / "selection.json").read_text()) for d in ("local", "ray"))
    strip = lambda rows: [{k: v for k, v in row.items() if k != "seconds"} for row in rows]  # noqa: E731
    assert len(on_ray["rows"]) > 10 and strip(on_ray["rows"]) == strip(local["rows"])
    assert on_ray["chosen"] == local["chosen"]
    assert on_ray["execution"]["backend"] == "ray" and local["execution"]["backend"] == "local"
    a, b = load_model(tmp_path / "local" / "model.json"), load_model(tmp_path / "ray" / "model.json")
    np.testing.assert_array_equal(a.Xi, b.Xi)
    np.testing.assert_array_equal(a.autoencoder.W_e, b.autoencoder.W_e)
