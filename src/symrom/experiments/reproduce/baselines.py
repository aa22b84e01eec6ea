"""The baselines beside each SIM experiment (``symrom.baselines.BASELINES``: the aSLIP fitted to
acceleration residuals and to rollouts, Newton as it is and with fitted gains), fitted on its
training split and evaluated on its test split, each in its folder (``write_baseline``)."""

from __future__ import annotations

import json
from pathlib import Path

from symrom.baselines import BASELINES, fit_baseline
from symrom.data.dataset import Dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.outputs import write_baseline
from symrom.experiments.reproduce.config import ExperimentSpec, ReproduceConfig, Say
from symrom.experiments.reproduce.steps import done
from symrom.rollout.integrate import RolloutOptions


def run_baselines(run: Path, exp: ExperimentSpec, ds: Dataset, cfg: ReproduceConfig, say: Say) -> dict:
    """Every baseline of ``BASELINES`` beside ``exp``, fitted on its training split and evaluated
    on its test split into ``run/<exp>/<baseline>/``; their metrics by name."""
    out = {}
    for name in BASELINES:
        d = run / exp.name / name
        if done(d / "metrics.json"):
            out[name] = json.loads((d / "metrics.json").read_text())
            continue
        say(f"{exp.name}: baseline {name}")
        model = fit_baseline(name, ds)
        metrics, _ = evaluate_model(model, ds, "test", (None, 0.1), RolloutOptions(cfg.integrator), model_name=name,
                              data_name=f"data/{exp.data}.h5")
        d.mkdir(parents=True, exist_ok=True)
        write_baseline(d, model, metrics, f"{BASELINES[name]}, {exp.name} (test)")
        out[name] = metrics.to_dict()
    return out
