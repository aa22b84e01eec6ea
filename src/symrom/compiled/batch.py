"""A batch of jumps split over threads: the compiled kernels that loop over jumps release
Python's lock (``nogil``), so each thread runs the kernel on its own contiguous run of jumps.

Jumps are independent in every such kernel, so the result is the same, bit for bit, with
any number of threads. The thread count is ``symrom.execution.kernel_threads()``.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from symrom.execution import kernel_threads

# Below this much work (samples x steps per sample) a thread's start-up costs more than it saves.
MIN_SPLIT_WORK = 20_000

_POOL: list[tuple[int, ThreadPoolExecutor]] = []  # (its threads, the pool), made on first use


def split(lens: np.ndarray, parts: int) -> list[slice]:
    """At most ``parts`` contiguous runs of the jumps whose lengths are ``lens`` (J,), each
    with about the same number of samples; every run holds at least one jump."""
    lens = np.asarray(lens, dtype=np.int64)
    J = len(lens)
    parts = max(1, min(int(parts), J))
    if parts == 1:
        return [slice(0, J)]
    ends = np.cumsum(lens)
    cuts = np.searchsorted(ends, ends[-1] * np.arange(1, parts) / parts, side="left") + 1
    bounds = np.unique(np.concatenate([[0], np.clip(cuts, 1, J - 1), [J]]))
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


def over_jumps(run: Callable[[slice], None], lens: np.ndarray, steps_per_sample: int = 1) -> None:
    """Call ``run(jumps)`` on runs of the jumps (J,) whose lengths are ``lens``, in threads
    when the batch is large enough to gain from them; ``run`` writes each jump's results
    in place and must release Python's lock to gain anything. An exception in any run is
    raised here once every run has ended."""
    lens = np.asarray(lens)
    threads = kernel_threads()
    if threads < 2 or len(lens) < 2 or int(lens.sum()) * steps_per_sample < MIN_SPLIT_WORK:
        run(slice(0, len(lens)))
        return
    runs = split(lens, threads)
    pool = _pool(len(runs) - 1)
    futures = [pool.submit(run, r) for r in runs[1:]]
    try:
        run(runs[0])  # this thread takes the first run itself
    finally:
        errors = [f.exception() for f in futures]
    for e in errors:
        if e is not None:
            raise e


def rollout_jumps(kernel: Callable, x_true: np.ndarray, v_true: np.ndarray, drive: dict, lens: np.ndarray,
                  resets: np.ndarray, limit: np.ndarray, dt: float, substeps: int, X: np.ndarray, V: np.ndarray,
                  program: tuple = ()) -> np.ndarray:
    """Run an RK4 rollout kernel ``kernel(x_true, v_true, nu, phase, lens, resets, *program, dt,
    substeps, limit, X, V, div_at)`` (the generated one, or the term table's with its
    ``program``) over the J jumps of the padded arrays (J, n_max, l), in threads
    (``over_jumps``); it writes X, V in place. Returns div_at (J,): each jump's first bad
    sample, -1 if none."""
    J, _, l = x_true.shape
    f = np.ascontiguousarray
    xt, vt, nu = f(x_true, dtype=float), f(v_true, dtype=float), f(drive["nu"], dtype=float)
    ph, lens = f(drive["phase"], dtype=np.int64), f(lens, dtype=np.int64)
    resets, lim = np.asarray(resets, dtype=np.bool_), f(np.broadcast_to(limit, (J, 2 * l)), dtype=float)
    lim.setflags(write=False)  # read-only whatever limit's shape (a view of it is): one numba type, one build
    div_at = np.full(J, -1, dtype=np.int64)
    over_jumps(lambda r: kernel(xt[r], vt[r], nu[r], ph[r], lens[r], resets, *program, float(dt), int(substeps),
                                lim[r], X[r], V[r], div_at[r]), lens, int(substeps))
    return div_at


def _pool(workers: int) -> ThreadPoolExecutor:
    if not _POOL or _POOL[0][0] < workers:
        if _POOL:
            _POOL.pop()[1].shutdown(wait=False)
        _POOL.append((workers, ThreadPoolExecutor(max_workers=workers, thread_name_prefix="symrom-kernel")))
    return _POOL[0][1]
