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

from dataclasses import replace

from symrom.experiments.reproduce import QUICK_SELECTION, DatasetSpec, ExperimentSpec, ReproduceConfig

DEMO_JUMPS = 12


def demo_config(jumps: int = DEMO_JUMPS, seed: int = 0, workers: int = 2) -> ReproduceConfig:
    """SIM Go1 only: ``jumps`` jumps, a small selection grid (l = 2, 3), its baselines, a
    sweep over l = 1-4, 6."""
    if jumps < 3:
        raise ValueError(f"the demo needs at least 3 jumps (train, val and test), got {jumps}")
    return replace(ReproduceConfig(), datasets=(DatasetSpec("go1_sim", "go1", "pronk", jumps),),
                   experiments=(ExperimentSpec("go1_sim", "go1_sim", 2, (2, 3)),), selection=QUICK_SELECTION,
                   compare_solvers=False,
                   sweep_dims=(1, 2, 3, 4, 6), sweep_seeds=2, seed=seed, workers=workers)
