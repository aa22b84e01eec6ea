"""The latent-dimension trade-off on SIM Go1, and the encoders the report's heatmaps show."""

from __future__ import annotations

import json
from pathlib import Path

from symrom.atomic import write_text_atomic
from symrom.data.io import read_dataset
from symrom.experiments.reproduce.config import ReproduceConfig, Say
from symrom.experiments.reproduce.steps import done
from symrom.learn.training import TrainConfig, train


def run_sweep_step(run: Path, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """The latent-dimension trade-off on SIM Go1, plus encoders for the heatmaps."""
    from symrom.experiments.sweep import SweepConfig, run_sweep

    d = run / "sweep"
    ds = read_dataset(data)
    sc = SweepConfig(latent_dims=tuple(cfg.sweep_dims), seeds=cfg.sweep_seeds, lam=cfg.sweep_lambda,
                     workers=cfg.workers)
    result = run_sweep(ds, sc, d,
                       progress=lambda done, total, info: say(f"sweep: {done}/{total} cells", transient=True),
                       backend=cfg.execution())
    enc = d / "encoders"
    enc.mkdir(parents=True, exist_ok=True)
    for l in sorted({2, max(cfg.sweep_dims)}):
        p = enc / f"W_e_l{l}.json"
        if not done(p):
            m = train(ds, TrainConfig(l, 1, seed=cfg.seed))
            write_text_atomic(p, json.dumps({"latent_dim": l, "W_e": m.autoencoder.W_e.tolist()}))
    return result

