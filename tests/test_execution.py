"""Execution back ends without Ray: results, worker deaths retried and recorded, errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import _tasks
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom import execution
from symrom.execution import BackendError, LocalBackend, WorkerLostError, make_backend


@pytest.mark.parametrize("workers", [1, 2])
def test_local_map_gives_every_result_once(workers):
    done = list(LocalBackend(workers).map(_tasks.square, [(f"k{x}", (x,)) for x in range(5)], (100,)))
    assert sorted(d.key for d in done) == [f"k{x}" for x in range(5)]
    assert {d.key: d.value for d in done} == {f"k{x}": 100 + x * x for x in range(5)}
    assert all(d.seconds >= 0 and ":" in d.worker and d.retries == [] for d in done)
    if workers == 2:  # in worker processes, not in this one
        assert all(not d.worker.endswith(f":{os.getpid()}") for d in done)


def test_local_worker_that_dies_is_retried_and_recorded(tmp_path):
    done = {d.key: d for d in LocalBackend(2).map(_tasks.die_once, [(x, (x,)) for x in range(3)], (str(tmp_path),),
                                                  label="square")}
    assert {k: d.value for k, d in done.items()} == {0: 0, 1: 10, 2: 20}
    # Every task died once: each lost exactly its running attempt(s), recorded with the cause.
    for d in done.values():
        assert len(d.retries) >= 1 and d.retries[0]["attempt"] == 0
        assert "worker process died" in d.retries[0]["cause"]


def test_local_retries_are_bounded(tmp_path):
    with pytest.raises(WorkerLostError, match=r"doomed [01]: its worker died 2 times, more than the 1 retries allowed"):
        list(LocalBackend(2, max_retries=1).map(_tasks.always_die, [(0, (0,)), (1, (1,))], label="doomed"))


@pytest.mark.parametrize("workers", [1, 2])
def test_a_task_error_is_raised_as_it_was_raised(workers):
    with pytest.raises(ValueError, match="task 2 refuses: a bad input"):
        list(LocalBackend(workers).map(_tasks.refuse, [(x, (x,)) for x in range(4)]))


def test_backends_by_name():
    assert make_backend("local").workers == 1 and make_backend("local", 3).workers == 3
    with pytest.raises(BackendError, match="backend='dask': unknown back end; choose from local, ray"):
        make_backend("dask")
    with pytest.raises(BackendError, match="address= names a Ray cluster: use it with backend='ray'"):
        make_backend("local", address="10.0.0.1:6379")
    with pytest.raises(BackendError, match="workers=0: the number of workers must be at least 1"):
        make_backend("local", 0)
    assert make_backend("local").describe() == {"backend": "local", "workers": 1, "max_retries": 3}


def test_ray_missing_is_one_clear_line(monkeypatch, tmp_path):
    monkeypatch.setattr(execution, "ray_available", lambda: False)
    with pytest.raises(BackendError, match=r"pip install 'symrom\[ray\]'"):
        make_backend("ray")
    from symrom.cli import app

    out = tmp_path / "d.h5"
    r = CliRunner().invoke(app, ["generate", "--robot", "go1", "--motion", "pronk", "--jumps", "1", "--out", str(out),
                                 "--backend", "ray"])
    one_line_error(r, "needs Ray", "symrom[ray]")
    assert not out.exists()


def test_symrom_never_imports_ray_on_the_local_back_end(tmp_path):
    code = ("import sys, symrom, symrom.cli, symrom.execution, symrom.sim.generation.generate, "
            "symrom.experiments.sweep, symrom.experiments.select, symrom.experiments.reproduce\n"
            "from symrom.execution import LocalBackend\n"
            "import _tasks\n"
            "assert [d.value for d in LocalBackend(1).map(_tasks.square, [(0, (3,))], (1,))] == [10]\n"
            "assert 'ray' not in sys.modules, 'ray was imported'\n")
    src = str(Path(execution.__file__).parents[1])  # the symrom under test, whatever the cwd
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       cwd=str(Path(__file__).parent), env=env)
    assert r.returncode == 0, r.stderr


SCRIPT = """import numpy as np
import _tasks
from symrom.execution import LocalBackend

def run():
    big = np.arange(1_000_000.0)  # 8 MB of shared arguments, far more than a pipe holds
    print(sorted(float(d.value[-1]) for d in LocalBackend(2).map(_tasks.square, [(x, (x,)) for x in range(3)], (big,))))

{call}
"""


@pytest.mark.parametrize("guard", [None, 'if __name__ == "__main__":', 'if True and "__main__" == __name__:'])
def test_a_pool_started_from_a_scripts_top_level_is_refused_not_hung(tmp_path, guard):
    """A script that starts workers outside ``if __name__ == "__main__":`` gets one error naming
    its line (a spawned worker runs the script again; with shared arguments larger than a pipe
    holds, the pool's start waited for that worker forever); under the guard it runs."""
    script = tmp_path / "job.py"
    script.write_text(SCRIPT.format(call=f"{guard}\n    run()" if guard else "run()"))
    src = str(Path(execution.__file__).parents[1])
    path = [src, str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env)
    if guard:
        assert r.returncode == 0 and r.stdout.split("\n")[0] == "[999999.0, 1000000.0, 1000003.0]", r.stderr
    else:
        assert r.returncode == 1 and r.stdout == "", r.stderr
        last = r.stderr.strip().splitlines()[-1]
        assert last.startswith(f"symrom.execution.BackendError: {script}, line 9: worker processes started") \
            and "__name__" in last, r.stderr


def test_a_packages_main_starts_workers_from_its_top_level(tmp_path):
    """``python -m PACKAGE`` runs the package's ``__main__``, which multiprocessing's workers do
    not run again (as ``python -m symrom`` runs the command line from its top level): its pool
    starts and answers."""
    pkg = tmp_path / "job"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "__main__.py").write_text(SCRIPT.format(call="run()"))
    src = str(Path(execution.__file__).parents[1])
    path = [src, str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path))
    r = subprocess.run([sys.executable, "-m", "job"], capture_output=True, text=True, timeout=120, env=env,
                       cwd=str(tmp_path))
    assert r.returncode == 0 and r.stdout.split("\n")[0] == "[999999.0, 1000000.0, 1000003.0]", r.stderr


def test_the_reports_drawing_processes_are_refused_from_a_scripts_top_level_too(tmp_path):
    script = tmp_path / "draw.py"
    script.write_text("from symrom.report.context import Drawing\n\nDrawing(2).close()\n")
    src = str(Path(execution.__file__).parents[1])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 1 and f"BackendError: {script}, line 3: worker processes" in r.stderr, r.stderr


PRESTART = """import os, sys, time
import _tasks
from symrom.execution import LocalBackend

if __name__ == "__main__":
    backend = LocalBackend(int(sys.argv[1]))
    backend.prestart(["_marked"])
    deadline = time.monotonic() + float(sys.argv[2])
    while not os.path.exists(os.environ["MARK"]) and time.monotonic() < deadline:
        time.sleep(0.05)
    print(os.path.exists(os.environ["MARK"]))
    print(sorted(d.value for d in backend.map(_tasks.square, [(x, (x,)) for x in range(3)], (1,), preload=["_marked"])))
"""


@pytest.mark.parametrize("workers", [1, 2])
def test_prestart_imports_the_preload_before_the_first_map(tmp_path, workers):
    """``prestart`` starts the workers' fork server at once: it has imported the preload before
    ``map`` is called (the marker module writes its file as it is imported), and the map then
    gives its results. One worker runs the tasks in the caller: nothing is started."""
    (tmp_path / "_marked.py").write_text("import os\nopen(os.environ['MARK'], 'w').close()\n")
    script = tmp_path / "job.py"
    script.write_text(PRESTART)
    mark = tmp_path / "imported"
    src = str(Path(execution.__file__).parents[1])
    path = [src, str(Path(__file__).parent), str(tmp_path), os.environ.get("PYTHONPATH", "")]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path), MARK=str(mark))
    wait = "60" if workers > 1 else "1"  # one worker starts nothing: the wait runs to its end
    r = subprocess.run([sys.executable, str(script), str(workers), wait], capture_output=True, text=True,
                       timeout=120, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(workers > 1), "[1,", "2,", "5]"], r.stdout


def test_pool_workers_keep_their_threads_to_their_share_of_the_cores():
    """Each of n pool workers runs BLAS and symrom's kernels on cores / n threads: threads that
    outnumber the cores wait for each other."""
    share = max(1, execution.available_cores() // 2)
    done = list(LocalBackend(2).map(_tasks.thread_limits, [(x, (x,)) for x in range(2)]))
    assert [d.value for d in done] == [(share, share)] * 2


def test_a_thread_limit_is_undone_in_order(monkeypatch):
    monkeypatch.delenv(execution.THREADS_ENV, raising=False)
    base = execution.kernel_threads()
    outer = execution.limit_threads(3)
    inner = execution.limit_threads(1)
    assert execution.kernel_threads() == 1
    inner.restore_original_limits()
    assert execution.kernel_threads() == 3
    outer.restore_original_limits()
    assert execution.kernel_threads() == base
    monkeypatch.setattr(execution, "_KERNEL_THREADS", [])  # no limit set: the variables decide
    monkeypatch.delenv(execution.THREADS_ENV, raising=False)
    monkeypatch.setenv("OMP_NUM_THREADS", "1")  # as Ray sets it in its workers
    assert execution.kernel_threads() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "3,2")  # OpenMP's nested form: the outer count
    assert execution.kernel_threads() == 3
    monkeypatch.setenv("OMP_NUM_THREADS", "auto")  # not ours to refuse: the cores decide
    assert execution.kernel_threads() == execution.available_cores()
    monkeypatch.setenv(execution.THREADS_ENV, "3")
    assert execution.kernel_threads() == 3
    monkeypatch.setenv(execution.THREADS_ENV, "two")
    with pytest.raises(ValueError, match="SYMROM_THREADS"):
        execution.kernel_threads()
