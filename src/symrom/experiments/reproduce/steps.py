"""The steps every experiment of a run is made of, each skipped when its output exists (a run
resumes where it stopped): a dataset generated, a model trained or read back, an evaluation
made or read back, a summary entry."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from symrom.data.dataset import Dataset
from symrom.evaluate.metrics import evaluate_model
from symrom.evaluate.outputs import write_evaluation
from symrom.evaluate.records import Metrics
from symrom.experiments.reproduce.config import DatasetSpec, ReproduceConfig, Say
from symrom.experiments.select import encoder_name, library_name
from symrom.learn.training import TrainConfig, train
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import load_model, write_model_files


def done(path: Path) -> bool:
    return path.is_file()


def ensure_dataset(run: Path, spec: DatasetSpec, cfg: ReproduceConfig, say: Say) -> Path:
    """The dataset file of ``spec`` in ``run/data``, generated if missing."""
    path = run / "data" / f"{spec.name}.h5"
    if done(path):
        return path
    from symrom.sim.generation.generate import GenerateConfig, NoiseConfig, generate

    say(f"generating {spec.name} ({spec.jumps} jumps of {spec.robot} {spec.motion})")
    gc = GenerateConfig(spec.robot, spec.motion, spec.jumps, seed=cfg.seed + spec.seed, proxy=spec.proxy,
                        randomize=spec.randomize, noise=NoiseConfig() if spec.noise else None,
                        engine=spec.engine or cfg.engine, splits=spec.splits, log_faults=spec.log_faults)
    generate(gc, path, backend=cfg.execution(), resume=True,
             progress_callback=lambda done, total, info: say(
                 f"generating {spec.name}: {done}/{total} jumps", transient=True))
    return path


def evaluated(model: HybridModel, ds: Dataset, out: Path, cfg: ReproduceConfig, title: str,
                   split: str = "test") -> dict:
    """The metrics of ``model`` on ``split`` at both horizons, written into ``out``; read back
    when an earlier run finished them (a run resumes)."""
    from symrom.rollout.integrate import RolloutOptions

    if done(out / "metrics.json"):
        return Metrics.read(out / "metrics.json")
    metrics, rollouts = evaluate_model(model, ds, split, (None, 0.1), RolloutOptions(method=cfg.integrator),
                                 model_name=str(out.parent / "model.json"), data_name=title)
    write_evaluation(out, metrics, rollouts, ds, [int(ds.jumps_in(split)[0])] if cfg.jump_figures else [],
                     title=title)
    return metrics


def train_or_load(path: Path, ds: Dataset, tc: TrainConfig) -> tuple[HybridModel, float]:
    if done(path):
        return load_model(path), float("nan")
    t0 = time.perf_counter()
    model = train(ds, tc)
    wall = time.perf_counter() - t0
    model = replace(model, provenance=model.provenance.with_wall_time(wall))
    write_model_files(model, path.parent)
    return model, wall


def experiment_entry(model: HybridModel, metrics: Metrics, run: Path, data: Path, model_path: Path) -> dict:
    return {"latent_dim": model.latent_dim, "poly_order": model.library.poly_order,
            "n_candidates": model.library.n_features, "active_terms": model.active_terms(),
            "equations": {k: [str(e) for e in v] for k, v in model.equations(3).items()},
            "metrics": metrics.to_dict(), "data": str(data.relative_to(run)),
            "model": str(model_path.relative_to(run))}


def train_evaluate(ds: Dataset, d: Path, tc: TrainConfig, cfg: ReproduceConfig, title: str,
                    say: Say) -> tuple[HybridModel, dict]:
    d.mkdir(parents=True, exist_ok=True)
    model, _ = train_or_load(d / "model.json", ds, tc)
    if not done(d / "eval" / "metrics.json"):
        say(f"{title}: evaluating on the test split")
    return model, evaluated(model, ds, d / "eval", cfg, title)




def selected_config(model: HybridModel, **changes) -> TrainConfig:
    """The training configuration a selected model was made with, ``changes`` applied."""
    return TrainConfig.from_provenance(model.provenance, **changes)



def config_facts(tc: TrainConfig) -> dict:
    """A training configuration in the words of the selection's table (the manifest's facts)."""
    return {"encoder": encoder_name(tc), "latent_dim": tc.latent_dim,
            "library": library_name(tc.poly_order, tc.trig, tc.inputs), "threshold": tc.threshold,
            "measure": tc.measure, "decoded_weight": tc.decoded_weight, "alpha": tc.alpha, "refine": tc.refine}

