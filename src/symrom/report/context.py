"""What the renderers share while one report is built: the figure folder and rollouts."""

from __future__ import annotations

import inspect
import re
from dataclasses import dataclass, field
from pathlib import Path

from symrom.evaluate.records import ManifestEntry
from symrom.report.run import Run


class JumpCache:
    """Rollouts of the first evaluated jump of each model, computed once for the figures."""

    def __init__(self, run: Run):
        self.run = run
        self._cache: dict[str, tuple | None] = {}

    def get(self, entry: ManifestEntry):
        """(dataset, jump index, {"full": Rollout, "0.1": Rollout}) of ``entry``'s model on
        the first jump of its evaluation split; None if its model, data or metrics are missing."""
        if entry.name not in self._cache:
            self._cache[entry.name] = self._roll(entry)
        return self._cache[entry.name]

    def _roll(self, entry: ManifestEntry):
        from symrom.rollout.integrate import RolloutOptions, rollout

        model, ds, metrics = self.run.model(entry), self.run.dataset(entry), self.run.metrics(entry)
        if model is None or ds is None or metrics is None:
            return None
        jumps = ds.jumps_in(metrics.split)
        if jumps.size == 0:
            self.run.note(f"{entry.name}: its dataset has no {metrics.split!r} jumps; no figure")
            return None
        j = int(jumps[0])
        method = metrics.integrator or "lsoda"
        ros = {key: rollout(model, ds, [j], RolloutOptions(method=method, reset=reset))
               for key, reset in (("full", None), ("0.1", 0.1))}
        return ds, j, ros


def _pool_start() -> None:
    from symrom.report import figures

    figures._pyplot()  # matplotlib loaded before the first figure arrives


class Drawing:
    """Where a report's figures are drawn: this process and ``workers - 1`` others, started at
    once so that they are ready when the first figure comes."""

    def __init__(self, workers: int = 1) -> None:
        self.workers, self._pool, self._pending = workers, None, []
        if workers > 1:
            from concurrent.futures import ProcessPoolExecutor

            from symrom.execution import process_context

            self._pool = ProcessPoolExecutor(workers - 1, process_context(), initializer=_pool_start)

    def draw(self, fn, *args, **kwargs) -> Path:
        """``fn(*args, **kwargs)``, a figure of ``symrom.report.figures`` (it writes its ``path``
        argument): in another process while this one goes on when one of them is free
        (``finish`` waits for it), else here; the figure's path. A figure is the same wherever it
        is drawn; if the other processes die (or cannot start), their figures are drawn here."""
        path = Path(inspect.signature(fn).bind(*args, **kwargs).arguments["path"])
        running = []
        for job in self._pending:
            if job[0].done():
                self._collect(job)
            else:
                running.append(job)
        self._pending = running
        if self._pool is not None and len(self._pending) < self.workers - 1:
            self._pending.append((self._pool.submit(fn, *args, **kwargs), fn, args, kwargs))
            return path
        fn(*args, **kwargs)
        return path

    def _collect(self, job) -> None:
        from concurrent.futures.process import BrokenProcessPool

        future, fn, args, kwargs = job
        try:
            future.result()  # an error in a figure drawn elsewhere is raised here
        except BrokenProcessPool:
            self.close()
            fn(*args, **kwargs)

    def finish(self) -> None:
        """Wait for the figures drawn elsewhere (an error in one is raised here)."""
        pending, self._pending = self._pending, []
        for job in pending:
            self._collect(job)

    def close(self) -> None:
        """End the other processes (``finish`` first, or the figures not yet drawn are dropped)."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None


@dataclass
class Context:
    """fig_dir: where the PNG figures go; jumps: the rollouts shared by the figures; drawing:
    where the figures are drawn (``draw``)."""

    run: Run
    fig_dir: Path
    drawing: Drawing = field(default_factory=Drawing)
    jumps: JumpCache = field(init=False)

    def __post_init__(self) -> None:
        self.jumps = JumpCache(self.run)

    @staticmethod
    def slug(entry: ManifestEntry) -> str:
        """A file-name-safe form of the entry's name."""
        return re.sub(r"[^A-Za-z0-9_.-]+", "_", entry.name)

    def draw(self, fn, *args, **kwargs) -> Path:
        """A figure drawn by ``drawing`` (``Drawing.draw``); its path."""
        return self.drawing.draw(fn, *args, **kwargs)
