"""Both solvers on SIM Go1 (exact and adam): accuracy, active terms, wall time."""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

from symrom.data.io import read_dataset
from symrom.experiments.reproduce.config import ReproduceConfig, Say
from symrom.experiments.reproduce.steps import evaluated, train_or_load
from symrom.learn.training import TrainConfig


def run_solvers(run: Path, data: Path, settings: TrainConfig, cfg: ReproduceConfig, say: Say) -> dict:
    """Both solvers on SIM Go1 with its selected encoder, latent dimension and library,
    without the refinement (which applies to the exact solver only): accuracy, active
    terms, wall time. adam thresholds |Xi| at the paper's 0.01."""
    ds = read_dataset(data)
    out = {}
    for solver in ("exact", "adam"):
        d = run / "go1_sim" / "solvers" / solver
        d.mkdir(parents=True, exist_ok=True)
        say(f"solvers: training with {solver}")
        tc = (replace(settings, refine=False) if solver == "exact" else
              replace(settings, solver="adam", refine=False, threshold=0.01, adam=cfg.adam))
        model, wall = train_or_load(d / "model.json", ds, tc)
        wall = model.provenance.training.wall_time_s or wall
        metrics = evaluated(model, ds, d / "eval", cfg, f"SIM Go1 ({solver})")
        out[solver] = {"wall_time_s": wall, "active_terms": model.active_terms(), "metrics": metrics.to_dict(),
                       "config": asdict(tc)}
    return out

