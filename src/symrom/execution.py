"""Where the heavy tasks run: local processes or a Ray cluster, behind one small interface.

A back end maps a function over keyed tasks and yields each task's result as it
finishes (a ``Done``: key, value, the attempt's wall time in the worker, the
worker, the attempts lost before it). Every caller (generation, the sweep, the
selection grid) does the rest itself, in the driver: it skips the tasks whose
outputs exist (resume), writes each result atomically as it arrives, and
records the retries. Tasks return arrays and plain data, never paths on a
worker's disk.

- ``LocalBackend(workers)``: today's behaviour. One worker runs the tasks in
  this process; more run them in a process pool (spawn, or forkserver with
  ``preload`` modules imported once), at most ``workers`` at a time.
  ``prestart(preload)`` starts that fork server before the first ``map``, so
  that its imports run beside the caller's work.
- ``RayBackend(address, workers)``: ``ray.remote`` tasks on the cluster at
  ``address`` (or ``$RAY_ADDRESS``, or a cluster started on this machine with
  ``ray start``; else a new Ray instance here). Ray is an optional extra
  (``pip install 'symrom[ray]'``) and is imported only here, only when this
  back end is used.

A worker that dies (a crashed or killed process, a lost node, a task killed
for memory) costs its task one attempt: the task is submitted again, up to
``max_retries`` times, and each lost attempt is recorded with its cause. An
exception raised by the task itself is not retried: it is raised in the
driver as the task raised it. The same task gives the same value on any back
end, so results do not depend on the back end or the worker count.
"""

from __future__ import annotations

import importlib.util
import logging
import os
import platform
import socket
import sys
import time
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

BACKENDS = ("local", "ray")
DEFAULT_MAX_RETRIES = 3
RAY_MISSING = "the ray back end needs Ray, which is not installed: pip install 'symrom[ray]'"

Task = tuple[Hashable, tuple]  # (key, positional arguments after the shared ones)


class BackendError(RuntimeError):
    """A back end cannot be made or reached (unknown name, Ray missing, no cluster)."""


class WorkerLostError(BackendError):
    """A task lost more attempts to dying workers than it may be retried."""


@dataclass
class Done:
    """A finished task: its key and value, the wall time of the attempt that finished (s,
    measured in the worker), the worker (``host:pid``) and every attempt lost before it
    (``{"attempt": k, "cause": ...}``)."""

    key: Hashable
    value: Any
    seconds: float
    worker: str
    retries: list[dict[str, Any]] = field(default_factory=list)


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def run_task(fn: Callable, shared: tuple, args: tuple) -> tuple[Any, float, str]:
    """Run ``fn(*shared, *args)`` and return (value, seconds, worker): the body of every task."""
    t0 = time.perf_counter()
    value = fn(*shared, *args)
    return value, time.perf_counter() - t0, _worker_name()


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return f"{type(e).__name__}: {text.splitlines()[0]}" if text else type(e).__name__


class Backend(ABC):
    """Maps tasks to results; see the module docstring."""

    name: str = ""

    def __init__(self, workers: int | None, max_retries: int = DEFAULT_MAX_RETRIES) -> None:
        check_workers(workers)
        if max_retries < 0:
            raise BackendError(f"max_retries must be >= 0, got {max_retries}")
        self.workers = workers
        self.max_retries = max_retries

    def start(self) -> Backend:
        """Make the back end ready (a Ray back end connects); ``self``. ``map`` calls it too."""
        return self

    def close(self) -> None:  # noqa: B027 (optional: only back ends that acquire something override it)
        """Release what ``start`` acquired."""

    def prestart(self, preload: Sequence[str] = ()) -> None:  # noqa: B027 (optional, as ``close``)
        """Begin making the workers of a coming ``map`` with ``preload`` now, so that their start
        runs beside the caller's own work before it; nothing where there is nothing to begin."""

    def __enter__(self) -> Backend:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    @abstractmethod
    def map(self, fn: Callable, tasks: Iterable[Task], shared: tuple = (), *, label: str = "task",
            preload: Sequence[str] = ()) -> Iterator[Done]:
        """Run ``fn(*shared, *args)`` for every ``(key, args)`` of ``tasks`` and yield a ``Done``
        per task as it finishes (in any order). ``fn`` must be importable by name (a
        module-level function); ``shared`` is sent once rather than with every task; ``label``
        names the tasks in errors and in the cluster's task list; ``preload``: modules a fresh
        worker process should import before its first task. Closing the iterator early
        cancels the tasks not yet finished."""

    def describe(self) -> dict[str, Any]:
        """What ran the tasks, JSON-ready (for the records of a run)."""
        return {"backend": self.name, "workers": self.workers, "max_retries": self.max_retries}

    def _lose(self, lost: dict[Hashable, list[dict]], key: Hashable, label: str, cause: str) -> None:
        """Record a lost attempt of ``key``; ``WorkerLostError`` once it may not be retried."""
        lost.setdefault(key, []).append({"attempt": len(lost[key]), "cause": cause})
        if len(lost[key]) > self.max_retries:
            causes = "; ".join(r["cause"] for r in lost[key])
            raise WorkerLostError(f"{label} {key}: its worker died {len(lost[key])} times, more than the "
                                  f"{self.max_retries} retries allowed ({causes})")


# ------------------------------------------------------------------ local processes
_SHARED: dict[str, tuple] = {}


THREADS_ENV = "SYMROM_THREADS"
BLAS_ENV = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")  # read by a BLAS library when it loads
_KERNEL_THREADS: list[int] = []  # the limit ``limit_threads`` set last in this process, if any


BLAS_KERNEL_ENV = "OPENBLAS_CORETYPE"  # read by OpenBLAS once, when it loads
BLAS_KERNEL = "Haswell"  # OpenBLAS's kernels for AVX2 and FMA, which the results' records ran


def pin_blas_kernel(environ: dict[str, str] | None = None, cpuinfo: str | Path = "/proc/cpuinfo") -> str | None:
    """Have OpenBLAS use ``BLAS_KERNEL`` in this process and the processes it starts, where
    the CPU runs it; returns the kernel pinned (or the one ``environ`` names already), else None.

    OpenBLAS picks its kernels by the CPU it finds (SkylakeX's on a machine with AVX-512,
    Haswell's on one with AVX2), and they round a product's sums differently. A simulated jump
    runs through them (the froggy controller's products and pseudo-inverse) and amplifies the
    round-off: the 150 SIM A1 jumps of ``reproduce`` came out of different lengths with the two
    kernels, and the selection chose another model from them. With the kernel pinned, every
    x86-64 machine with AVX2 and FMA runs the same kernel.

    It must run before NumPy loads (``symrom.cli.main`` calls it first); where NumPy is loaded
    already it changes nothing, so that the workers this process starts keep its arithmetic.
    A value of ``OPENBLAS_CORETYPE`` in the environment wins. Only on Linux x86-64, whose
    ``cpuinfo`` lists the CPU's flags (elsewhere OpenBLAS's own choice stands).
    """
    env = os.environ if environ is None else environ
    if env.get(BLAS_KERNEL_ENV):
        return env[BLAS_KERNEL_ENV]
    if "numpy" in sys.modules or sys.platform != "linux" or platform.machine() != "x86_64":
        return None
    try:
        text = Path(cpuinfo).read_text()
    except OSError:
        return None
    flags = next((line.split(":", 1)[1].split() for line in text.splitlines() if line.startswith("flags")), [])
    if not {"avx2", "fma"} <= set(flags):
        return None
    env[BLAS_KERNEL_ENV] = BLAS_KERNEL
    return BLAS_KERNEL


def blas_kernels() -> list[str]:
    """The BLAS libraries loaded in this process, each as "name version (kernel)"."""
    from threadpoolctl import threadpool_info

    return sorted({f"{i.get('internal_api')} {i.get('version')} ({i.get('architecture')})"
                   for i in threadpool_info() if i.get("user_api") == "blas"})


def kernel_threads() -> int:
    """Threads symrom's own compiled kernels may split a batch of jumps over: the limit
    ``limit_threads`` set, else ``$SYMROM_THREADS``, else ``$OMP_NUM_THREADS`` (what schedulers
    and Ray's workers set for a process's share), else the cores this process may run on."""
    if _KERNEL_THREADS:
        return _KERNEL_THREADS[-1]
    env = os.environ.get(THREADS_ENV, "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            raise ValueError(f"${THREADS_ENV}: {env!r} is not a whole number of threads") from None
    omp = os.environ.get("OMP_NUM_THREADS", "").split(",")[0].strip()  # OpenMP's "outer,inner" form too
    if omp.isdigit() and int(omp) > 0:
        return int(omp)
    return available_cores()


def available_cores() -> int:
    """The cores this process may run on."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


class ThreadLimit:
    """The limit ``limit_threads`` set; ``restore_original_limits()`` undoes it."""

    def __init__(self, threads: int) -> None:
        from threadpoolctl import threadpool_limits

        # the BLAS libraries loaded now, and (by their variables) those loaded later
        self._env = {name: os.environ.get(name) for name in BLAS_ENV}
        os.environ.update({name: str(threads) for name in BLAS_ENV})
        self._blas = threadpool_limits(limits=threads, user_api="blas")
        _KERNEL_THREADS.append(threads)
        self._mark = len(_KERNEL_THREADS)

    def restore_original_limits(self) -> None:
        self._blas.restore_original_limits()
        for name, value in self._env.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        del _KERNEL_THREADS[self._mark - 1:]


def limit_threads(threads: int) -> ThreadLimit:
    """Let BLAS and symrom's compiled kernels use at most ``threads`` threads in this process
    from now on, until the returned limit's ``restore_original_limits()``.

    Processes that share the cores each keep to their share: threads that outnumber the
    cores wait for each other, and the same work then costs several times the CPU time
    (docs/benchmarks.md)."""
    return ThreadLimit(max(1, int(threads)))


def _init_local(shared: tuple, threads: int) -> None:
    _SHARED["args"] = shared
    limit_threads(threads)


def _local_task(fn: Callable, args: tuple) -> tuple[Any, float, str]:
    return run_task(fn, _SHARED["args"], args)


def _guarded_lines(path: str) -> list[tuple[int, int]] | None:
    """The line ranges of ``path``'s blocks under an ``if`` that reads ``__name__`` (``if __name__
    == "__main__":`` and its variants); None if the file cannot be read or parsed."""
    import ast

    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return None
    return [(node.lineno, node.end_lineno or node.lineno) for node in ast.walk(tree)
            if isinstance(node, ast.If) and any(isinstance(n, ast.Name) and n.id == "__name__"
                                                for n in ast.walk(node.test))]


def check_main_guarded() -> None:
    """``BackendError`` if this process's main script reaches here from its top level outside
    ``if __name__ == "__main__":``. A spawned or forkserver worker runs the main script again as
    it starts, so there the same call would start workers of its own: multiprocessing stops
    that worker, but the pool's start, which writes the shared arguments to it, would wait for it
    forever. Nothing is checked where there is no main script file (an interactive session,
    ``-c``), where the script's code is not its file's (``exec``), or where the main module is a
    package's ``__main__`` (``python -m symrom``), which multiprocessing's workers do not run
    again."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path:
        return
    name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if name == "__main__" or name.endswith(".__main__"):
        return
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_globals is main.__dict__ and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None or os.path.abspath(frame.f_code.co_filename) != os.path.abspath(path):
        return
    line, guarded = frame.f_lineno, _guarded_lines(path)
    if guarded is not None and not any(a <= line <= b for a, b in guarded):
        raise BackendError(
            f"{path}, line {line}: worker processes started from the script's top level, outside "
            "'if __name__ == \"__main__\":'. Each worker runs the script again as it starts; put the "
            "script's work under that guard, or run with one worker")


def process_context(preload: Sequence[str] = ()):
    """The multiprocessing context of fresh worker processes: forkserver with ``preload``
    imported once where there is one (and something to preload), else spawn, safe with threaded
    BLAS and numba (plain fork could inherit locks held by the caller's threads, e.g. a progress
    bar). Either runs the main script again in each worker, so a call from its unguarded top
    level is refused first (``check_main_guarded``)."""
    import multiprocessing as mp

    check_main_guarded()
    if preload and "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(list(preload))
        return ctx
    return mp.get_context("spawn")


class LocalBackend(Backend):
    """Processes on this machine: one worker runs the tasks in this process, more in a process
    pool with at most ``workers`` tasks at once (so a pool that breaks when a worker dies
    loses exactly the tasks that were running; they are run again in a new pool)."""

    name = "local"

    def __init__(self, workers: int = 1, max_retries: int = DEFAULT_MAX_RETRIES) -> None:
        super().__init__(int(workers), max_retries)

    def prestart(self, preload: Sequence[str] = ()) -> None:
        """Start the workers' fork server now, importing ``preload``: a pool's first worker
        otherwise waits for those imports after the caller's own work. Nothing for one worker,
        without ``preload`` or where there is no fork server (the pool then starts as before)."""
        if self.workers > 1 and preload:
            ctx = process_context(preload)
            if ctx.get_start_method() == "forkserver":
                from multiprocessing import forkserver

                forkserver.ensure_running()

    def map(self, fn: Callable, tasks: Iterable[Task], shared: tuple = (), *, label: str = "task",
            preload: Sequence[str] = ()) -> Iterator[Done]:
        tasks = list(tasks)
        if self.workers == 1 or len(tasks) <= 1:
            for key, args in tasks:
                value, seconds, worker = run_task(fn, tuple(shared), tuple(args))
                yield Done(key, value, seconds, worker)
            return
        yield from self._pool_map(fn, tasks, tuple(shared), label, preload)

    def _pool_map(self, fn: Callable, tasks: list[Task], shared: tuple, label: str,
                  preload: Sequence[str]) -> Iterator[Done]:
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
        from concurrent.futures.process import BrokenProcessPool

        pending: deque[Task] = deque(tasks)
        lost: dict[Hashable, list[dict]] = {}
        ctx = process_context(preload)
        while pending:
            n = min(self.workers, len(pending))
            with ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_init_local,
                                     initargs=(shared, available_cores() // n)) as pool:
                running: dict = {}
                broken: list[Task] = []
                try:
                    while (pending and not broken) or running:
                        while pending and not broken and len(running) < n:
                            key, args = pending.popleft()
                            running[pool.submit(_local_task, fn, tuple(args))] = (key, args)
                        finished, _ = wait(running, return_when=FIRST_COMPLETED)
                        for fut in finished:
                            key, args = running.pop(fut)
                            try:
                                value, seconds, worker = fut.result()
                            except BrokenProcessPool:
                                broken.append((key, args))
                                continue
                            yield Done(key, value, seconds, worker, list(lost.get(key, [])))
                finally:
                    for fut in running:
                        fut.cancel()
                # A dead worker breaks the whole pool: every task that was running lost its
                # attempt. They go first into a new pool.
                for key, _ in broken:
                    self._lose(lost, key, label, "a worker process died (the process pool broke "
                                                 "and was started again)")
                pending.extendleft(reversed(broken))


# ------------------------------------------------------------------ Ray
def ray_available() -> bool:
    """Whether the optional Ray extra is installed."""
    return importlib.util.find_spec("ray") is not None


class RayBackend(Backend):
    """``ray.remote`` tasks on a Ray cluster (one CPU each). ``address``: the cluster's
    address (``host:port``, ``ray://host:10001``, ``auto`` or ``local``); None: ``$RAY_ADDRESS``,
    else the cluster last started on this machine with ``ray start``, else a new Ray instance
    on this machine (Ray's own rule; ``local`` always starts a new one). If this process is
    already connected to Ray, that connection is used. ``workers``: at most this many tasks
    at once (None: as many as the cluster has CPUs when the back end starts). Ray's own
    retries are off, so that every lost attempt is counted and recorded here."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None,
                 max_retries: int = DEFAULT_MAX_RETRIES) -> None:
        if not ray_available():
            raise BackendError(RAY_MISSING)
        super().__init__(workers, max_retries)
        self.address = address or os.environ.get("RAY_ADDRESS") or None
        _host_port(self.address)  # a malformed address fails here, before any work
        self._owner = False  # whether start() made the connection (and close() ends it)
        self.cluster: dict[str, Any] = {}

    def start(self) -> RayBackend:
        import ray

        if not ray.is_initialized():
            where = f"the Ray cluster at {self.address}" if self.address else "a local Ray instance"
            _check_reachable(self.address)
            try:
                ray.init(address=self.address, logging_level=logging.WARNING, log_to_driver=False)
            except Exception as e:  # noqa: BLE001 - Ray raises many kinds; name the address
                raise BackendError(f"cannot start or reach {where}: {_first_line(e)}") from e
            self._owner = True
        cpus = int(ray.cluster_resources().get("CPU", 0))
        if cpus < 1:
            raise BackendError("the Ray cluster has no CPU to run tasks on")
        self.cluster = {"nodes": sum(1 for n in ray.nodes() if n.get("Alive")), "cpus": cpus}
        if self.workers is None:
            self.workers = cpus
        return self

    def close(self) -> None:
        if self._owner:
            import ray

            ray.shutdown()
            self._owner = False

    def describe(self) -> dict[str, Any]:
        return {**super().describe(), "address": self.address, **self.cluster}

    def map(self, fn: Callable, tasks: Iterable[Task], shared: tuple = (), *, label: str = "task",
            preload: Sequence[str] = ()) -> Iterator[Done]:
        import ray
        from ray import exceptions as rx

        self.start()
        # A dead worker or node, a lost result, a task killed for memory: run it again.
        lost_kinds = (rx.WorkerCrashedError, rx.NodeDiedError, rx.ObjectLostError, rx.OutOfMemoryError,
                      rx.LocalRayletDiedError)
        remote = ray.remote(num_cpus=1, max_retries=0, retry_exceptions=False)(run_task)
        shared_ref = ray.put(tuple(shared))
        pending: deque[Task] = deque(tasks)
        lost: dict[Hashable, list[dict]] = {}
        running: dict = {}
        try:
            while pending or running:
                while pending and len(running) < self.workers:
                    key, args = pending.popleft()
                    ref = remote.options(name=f"symrom {label} {key}").remote(fn, shared_ref, tuple(args))
                    running[ref] = (key, args)
                ready, _ = ray.wait(list(running), num_returns=1)
                for ref in ready:
                    key, args = running.pop(ref)
                    try:
                        value, seconds, worker = ray.get(ref)
                    except rx.RayTaskError as e:  # the task raised: raise it here as it was raised
                        cause = e.cause if isinstance(getattr(e, "cause", None), BaseException) else None
                        if cause is None:
                            raise
                        raise cause from e
                    except lost_kinds as e:
                        self._lose(lost, key, label, _first_line(e))
                        pending.appendleft((key, args))
                        continue
                    yield Done(key, value, seconds, worker, list(lost.get(key, [])))
        finally:
            for ref in running:
                ray.cancel(ref, force=True)


def _host_port(address: str | None) -> tuple[str, int] | None:
    """(host, port) of a ``host:port`` or ``ray://host:port`` address; None for ``auto``,
    ``local`` or none; ``BackendError`` for anything else."""
    if not address or address in ("auto", "local"):
        return None
    host, sep, port = address.removeprefix("ray://").rstrip("/").rpartition(":")
    if not sep or not host or not port.isdigit():
        raise BackendError(f"Ray address {address!r}: expected host:port, ray://host:port or auto")
    return host.strip("[]"), int(port)


def _check_reachable(address: str | None, timeout: float = 5.0) -> None:
    """``BackendError`` unless something accepts connections at ``address`` (Ray itself would
    keep retrying for minutes)."""
    hp = _host_port(address)
    if hp is None:
        return
    try:
        socket.create_connection(hp, timeout=timeout).close()
    except OSError as e:
        raise BackendError(f"cannot reach the Ray cluster at {address}: {e.strerror or e} "
                           f"(is its head running? see ray start --head)") from None


# ------------------------------------------------------------------ compiled routines
HELPER_TIMEOUT = 600.0  # s: a helper still compiling then is left behind; its callers compile themselves


def in_disk_cache(dispatcher) -> bool:
    """Whether numba's disk cache holds a build of ``dispatcher`` (a ``numba.njit`` function with
    ``cache=True``) for its present source; False where the cache cannot be read."""
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba's cache internals; any failure means "compile"
        return False


@contextmanager
def compile_lock(dispatcher):
    """Held while ``dispatcher`` is compiled into numba's disk cache, by one process at a time
    for one cache file (an exclusive lock on a file beside the system's temporary files): a
    second helper waits for the first and then loads its build instead of compiling it again.
    Where files cannot be locked, nothing is held."""
    import hashlib
    import tempfile

    try:
        import fcntl

        where = str(dispatcher._cache._cache_path) + dispatcher.py_func.__qualname__
        path = os.path.join(tempfile.gettempdir(),
                            f"symrom-compile-{hashlib.sha256(where.encode()).hexdigest()[:16]}.lock")
        handle = open(path, "a")  # noqa: SIM115 - held for the block
    except (ImportError, OSError, AttributeError):
        yield
        return
    try:
        fcntl.flock(handle, fcntl.LOCK_EX)
        yield
    finally:
        handle.close()  # releases the lock


def start_helper(code: str):
    """A Python process running ``code`` (its output discarded) with the symrom this process
    runs first on its path, as a ``subprocess.Popen``; None if no process can be started. The
    compiled routines' helpers fill numba's disk cache this way, beside the work that needs them."""
    import subprocess

    root = str(Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([root, *filter(None, [os.environ.get("PYTHONPATH")])]))
    try:
        return subprocess.Popen([sys.executable, "-c", code], env=env, stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None


def wait_helper(proc, timeout: float) -> None:
    """Wait for a helper (``start_helper``; None: nothing to wait for) at most ``timeout`` s; one
    still running then is left behind (it only fills a cache)."""
    import subprocess

    if proc is None:
        return
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        pass


# ------------------------------------------------------------------ by name
def check_workers(workers: int | None) -> None:
    """``BackendError`` unless ``workers`` is None (the default) or at least 1."""
    if workers is not None and workers < 1:
        raise BackendError(f"workers={workers}: the number of workers must be at least 1")


def make_backend(name: str = "local", workers: int | None = None, address: str | None = None,
                 max_retries: int = DEFAULT_MAX_RETRIES) -> Backend:
    """The back end called ``name`` (``local`` or ``ray``). ``workers``: local processes
    (default 1), or for Ray the most tasks at once (default: the cluster's CPUs);
    ``address``: the Ray cluster (Ray only)."""
    if name not in BACKENDS:
        raise BackendError(f"backend={name!r}: unknown back end; choose from {', '.join(BACKENDS)}")
    check_workers(workers)
    if name == "local":
        if address:
            raise BackendError("address= names a Ray cluster: use it with backend='ray'")
        return LocalBackend(1 if workers is None else workers, max_retries)
    return RayBackend(address, workers, max_retries)
