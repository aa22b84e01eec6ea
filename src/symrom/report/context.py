"""What the renderers share while one report is built: the figure folder and rollouts."""

from __future__ import annotations

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


@dataclass
class Context:
    """fig_dir: where the PNG figures go; jumps: the rollouts shared by the figures."""

    run: Run
    fig_dir: Path
    jumps: JumpCache = field(init=False)

    def __post_init__(self) -> None:
        self.jumps = JumpCache(self.run)

    @staticmethod
    def slug(entry: ManifestEntry) -> str:
        """A file-name-safe form of the entry's name."""
        return re.sub(r"[^A-Za-z0-9_.-]+", "_", entry.name)
