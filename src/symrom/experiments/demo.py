"""The demo: the paper's Go1 pipeline end to end on a small default.

A dozen Go1 pronking jumps are simulated (PyBullet, convex MPC), the model's
settings are selected on the validation jumps (a small grid), the chosen model
is evaluated on the test split at the full horizon and with 0.1 s resets beside
the paper's defaults and the baselines (aSLIP fitted two ways, Newton as it is and fitted), a short
latent-dimension sweep runs, and the report is written. It is ``reproduce``
restricted to SIM Go1, so the layout of the output directory is that of a
reproduction run.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from symrom.experiments.reproduce import (
    QUICK_SELECTION,
    DatasetSpec,
    ExperimentSpec,
    ReproduceConfig,
    reproduce,
    sweep_line,
)

DEMO_JUMPS = 12


def demo_config(jumps: int = DEMO_JUMPS, seed: int = 0, workers: int = 2) -> ReproduceConfig:
    """SIM Go1 only: ``jumps`` jumps, a small selection grid (l = 2, 3), its baselines, a
    sweep over l = 1-4, 6."""
    if jumps < 3:
        raise ValueError(f"jumps={jumps}: the demo needs at least 3 jumps (train, val and test)")
    return replace(ReproduceConfig(), datasets=(DatasetSpec("go1_sim", "go1", "pronk", jumps),),
                   experiments=(ExperimentSpec("go1_sim", "go1_sim", 2, (2, 3)),), selection=QUICK_SELECTION,
                   compare_solvers=False,
                   sweep_dims=(1, 2, 3, 4, 6), sweep_seeds=2, seed=seed, workers=workers)


@dataclass(frozen=True)
class Demo:
    """A finished demo in ``out``: its summary (``summary.json``'s content), the SIM Go1 model's
    equations (``equations.txt``), and where its dataset and model are."""

    out: Path
    summary: dict
    equations: str
    jumps: int

    @property
    def data(self) -> Path:
        return self.out / self.summary["experiments"]["go1_sim"]["data"]

    @property
    def model(self) -> Path:
        return self.out / self.summary["experiments"]["go1_sim"]["model"]

    def text(self) -> str:
        """The model's equations, its Table 2 on the test split and the sweep's best latent
        dimension (told apart from the model's)."""
        from symrom.evaluate.tables import table2

        go1 = self.summary["experiments"]["go1_sim"]
        return "\n".join([self.equations, table2(go1["metrics"], title="SIM Go1, test split"),
                          sweep_line(self.summary["sweep"], {"the model above": go1["latent_dim"]})])


def run_demo(out: str | os.PathLike, jumps: int = DEMO_JUMPS, workers: int = 2, force: bool = False,
             command: str = "", say=None) -> Demo:
    """The demo (``demo_config``) run into the folder ``out`` (atomically: a new folder, or an
    existing one replaced only with ``force``); the finished run."""
    from symrom.atomic import atomic_dir, check_output_file
    from symrom.execution import check_workers

    out = Path(out)
    check_output_file(out, force)
    check_workers(workers)
    cfg = demo_config(jumps, workers=workers)
    with atomic_dir(out, force) as tmp:
        summary = reproduce(tmp, cfg, command=command, say=say)
        text = (tmp / "go1_sim" / "equations.txt").read_text().rstrip("\n")
    return Demo(out, summary, text, cfg.datasets[0].jumps)
