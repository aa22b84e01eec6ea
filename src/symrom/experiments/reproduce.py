"""The paper's experiments end to end, into one run directory.

Layout of ``DIR`` (every step is skipped when its output exists, so an
interrupted run resumes where it stopped and datasets are never regenerated):

    data/go1_sim.h5, a1_sim.h5, go1_noisy.h5, go1_proxy.h5   simulated datasets
    go1_sim/   model.json, eval/, aslip/ (metrics.json, params.json),
               solvers/{exact,adam}/ (model.json, eval/, timing.json),
               paper_defaults/ (model.json, eval/)
    a1_sim/    model.json, eval/, paper_defaults/
    go1_proxy/ base/model.json (trained on the noisy Go1 variant),
               model.json (fine-tuned on the proxy training jumps), eval/
    sweep/     sweep.json, cells/, encoders/W_e_l<k>.json
    summary.json   experiments, sweep, run, and ``manifest``: every experiment with its
                   role and files, which the report renders

Experiments: SIM Go1 pronking (l = 2, p = 1), SIM A1 froggy (l = 4, p = 1,
phases contact / partial / flight), sim-to-real (train on noisy Go1, fine-tune
on the proxy's training jumps, evaluate on its test jump), aSLIP vs learned on
Go1, the latent-dimension trade-off on SIM Go1, and both solvers on SIM Go1.

The SIM experiments use an encoder that reads the floating-base pose, the
latent-acceleration term of the SINDy loss alone and a small standardised ridge
(``ExperimentSpec``). The paper's defaults (encoder over all 18 components,
decoded-acceleration term at weight 1, no ridge) are trained and evaluated
beside them under ``paper_defaults``, so the effect of that choice is measured
in every run (README, "Reproducing the paper").
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from symrom import __version__
from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate
from symrom.evaluate.outputs import write_evaluation
from symrom.evaluate.paper import PAPER_TABLE2
from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, SOLVER, SWEEP, ManifestEntry
from symrom.model.finetune import FineTuneConfig, finetune
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import load_model, save_model
from symrom.model.training import AdamConfig, TrainConfig, train

Say = Callable[..., None]  # say(message, transient=False); transient = a progress count


@dataclass(frozen=True)
class DatasetSpec:
    """One simulated dataset: robot, motion, jumps and variant flags."""

    name: str
    robot: str
    motion: str
    jumps: int
    noise: bool = False
    proxy: bool = False


BASE_POSITION = ("x", "y", "z")
BASE_POSE = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class ExperimentSpec:
    """One learned-model experiment; ``encoder_components``, ``decoded_weight`` and
    ``alpha`` as in ``TrainConfig`` (None, 1 and 0 are the paper's defaults)."""

    name: str
    data: str
    latent_dim: int
    poly_order: int = 1
    encoder_components: tuple[str, ...] | None = None
    decoded_weight: float = 1.0
    alpha: float = 0.0

    def train_config(self, seed: int = 0, **kw) -> TrainConfig:
        return TrainConfig(self.latent_dim, self.poly_order, seed=seed,
                           encoder_components=self.encoder_components,
                           decoded_weight=self.decoded_weight, alpha=self.alpha, **kw)

    @property
    def paper_defaults(self) -> bool:
        return self.encoder_components is None and self.decoded_weight == 1.0 and self.alpha == 0.0


@dataclass
class ReproduceConfig:
    """What ``symrom reproduce`` runs; ``quick()`` gives the reduced version."""

    datasets: tuple[DatasetSpec, ...] = (
        DatasetSpec("go1_sim", "go1", "pronk", 156),
        DatasetSpec("a1_sim", "a1", "froggy", 150),
        DatasetSpec("go1_noisy", "go1", "pronk", 156, noise=True),
        DatasetSpec("go1_proxy", "go1", "pronk", 15, proxy=True),
    )
    experiments: tuple[ExperimentSpec, ...] = (
        ExperimentSpec("go1_sim", "go1_sim", 2, encoder_components=BASE_POSITION, decoded_weight=0.0,
                       alpha=1e-3),
        ExperimentSpec("a1_sim", "a1_sim", 4, encoder_components=BASE_POSE, decoded_weight=0.0, alpha=1e-3),
    )
    finetune: FineTuneConfig = field(default_factory=FineTuneConfig)
    sweep_dims: tuple[int, ...] = tuple(range(1, 19))
    sweep_seeds: int = 5
    sweep_lambda: float = 1e-3
    compare_solvers: bool = True
    adam: AdamConfig = field(default_factory=AdamConfig)
    seed: int = 0
    workers: int = 2
    integrator: str = "lsoda"

    def go1(self) -> ExperimentSpec:
        """The SIM Go1 experiment, whose settings the sim-to-real and solver runs share."""
        return next(e for e in self.experiments if e.name == "go1_sim")

    @classmethod
    def quick(cls) -> ReproduceConfig:
        """A reduced run: few jumps per dataset, a short sweep, a short adam run."""
        return cls(
            datasets=(DatasetSpec("go1_sim", "go1", "pronk", 10), DatasetSpec("a1_sim", "a1", "froggy", 8),
                      DatasetSpec("go1_noisy", "go1", "pronk", 8, noise=True),
                      DatasetSpec("go1_proxy", "go1", "pronk", 5, proxy=True)),
            sweep_dims=(1, 2, 4, 6, 18), sweep_seeds=2,
            adam=AdamConfig(epochs=20, refine_epochs=5, threshold_every=10), integrator="rk4")


# ------------------------------------------------------------------ helpers
def _done(path: Path) -> bool:
    return path.is_file()


def ensure_dataset(run: Path, spec: DatasetSpec, cfg: ReproduceConfig, say: Say) -> Path:
    """The dataset file of ``spec`` in ``run/data``, generated if missing."""
    path = run / "data" / f"{spec.name}.h5"
    if _done(path):
        return path
    from symrom.sim.generate import GenerateConfig, NoiseConfig, generate

    say(f"generating {spec.name} ({spec.jumps} jumps of {spec.robot} {spec.motion})")
    gc = GenerateConfig(spec.robot, spec.motion, spec.jumps, seed=cfg.seed, proxy=spec.proxy,
                        noise=NoiseConfig() if spec.noise else None)
    generate(gc, path, workers=cfg.workers, resume=True,
             progress_callback=lambda done, total, info: say(
                 f"generating {spec.name}: {done}/{total} jumps", transient=True))
    return path


def _evaluate_into(model: HybridModel, ds: Dataset, out: Path, cfg: ReproduceConfig, title: str,
                   split: str = "test") -> dict:
    from symrom.rollout.integrate import RolloutOptions

    metrics, rollouts = evaluate(model, ds, split, (None, 0.1), RolloutOptions(method=cfg.integrator),
                                 model_name=str(out.parent / "model.json"), data_name=title)
    write_evaluation(out, metrics, rollouts, ds, [int(ds.jumps_in(split)[0])], title=title)
    return metrics


def _train_or_load(path: Path, ds: Dataset, tc: TrainConfig) -> tuple[HybridModel, float]:
    if _done(path):
        return load_model(path), float("nan")
    t0 = time.perf_counter()
    model = train(ds, tc)
    wall = time.perf_counter() - t0
    model.info["wall_time_s"] = wall
    save_model(model, path)
    return model, wall


def _experiment_entry(model: HybridModel, metrics: dict, run: Path, data: Path, model_path: Path) -> dict:
    return {"latent_dim": model.latent_dim, "poly_order": model.library.poly_order,
            "n_candidates": model.library.n_features, "active_terms": model.active_terms(),
            "equations": {k: [str(e) for e in v] for k, v in model.equations(3).items()},
            "metrics": metrics, "data": str(data.relative_to(run)), "model": str(model_path.relative_to(run))}


def _train_evaluate(ds: Dataset, d: Path, tc: TrainConfig, cfg: ReproduceConfig, title: str,
                    say: Say) -> tuple[HybridModel, dict]:
    d.mkdir(parents=True, exist_ok=True)
    model, _ = _train_or_load(d / "model.json", ds, tc)
    mpath = d / "eval" / "metrics.json"
    if _done(mpath):
        return model, json.loads(mpath.read_text())
    say(f"{title}: evaluating on the test split")
    return model, _evaluate_into(model, ds, d / "eval", cfg, title)


def run_learned(run: Path, exp: ExperimentSpec, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """Train (exact) and evaluate one experiment, and its paper-default variant; its
    summary entry."""
    ds = read_dataset(data)
    d = run / exp.name
    say(f"{exp.name}: training (l={exp.latent_dim}, p={exp.poly_order})")
    model, metrics = _train_evaluate(ds, d, exp.train_config(cfg.seed), cfg, f"SIM {exp.name}", say)
    entry = _experiment_entry(model, metrics, run, data, d / "model.json")
    entry["config"] = {"encoder_components": exp.encoder_components, "decoded_weight": exp.decoded_weight,
                       "alpha": exp.alpha}
    if not exp.paper_defaults:
        say(f"{exp.name}: training with the paper's defaults")
        base, bm = _train_evaluate(ds, d / "paper_defaults", TrainConfig(exp.latent_dim, exp.poly_order, seed=cfg.seed),
                                   cfg, f"SIM {exp.name} (paper defaults)", say)
        entry["paper_defaults"] = {"active_terms": base.active_terms(), "metrics": bm,
                                   "model": str((d / "paper_defaults" / "model.json").relative_to(run))}
    return entry


def run_aslip(run: Path, data: Path, say: Say) -> dict:
    """Fit the aSLIP on Go1's training split and evaluate it on the test split."""
    from symrom.baselines.aslip import ASlip, fit_aslip
    from symrom.rollout.integrate import RolloutOptions

    d = run / "go1_sim" / "aslip"
    if _done(d / "metrics.json"):
        return json.loads((d / "metrics.json").read_text())
    say("aSLIP: fitting k_s, l_0 on the training split")
    ds = read_dataset(data)
    params = fit_aslip(ds, ds.rows_of("train"))
    metrics, _ = evaluate(ASlip(params), ds, "test", options=RolloutOptions("lsoda"), model_name="aslip")
    d.mkdir(parents=True, exist_ok=True)
    write_text_atomic(d / "params.json", json.dumps(asdict(params), indent=1))
    write_text_atomic(d / "metrics.json", json.dumps(metrics, indent=1))
    return metrics


def run_proxy(run: Path, noisy: Path, proxy: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """Sim-to-real: train on the noisy Go1 variant, fine-tune on the proxy jumps."""
    d = run / "go1_proxy"
    (d / "base").mkdir(parents=True, exist_ok=True)
    say("go1_proxy: training on the noisy Go1 variant")
    base, _ = _train_or_load(d / "base" / "model.json", read_dataset(noisy), cfg.go1().train_config(cfg.seed))
    ds = read_dataset(proxy)
    if _done(d / "model.json"):
        model = load_model(d / "model.json")
    else:
        say("go1_proxy: fine-tuning on the proxy training jumps")
        model = finetune(base, ds, config=cfg.finetune)
        save_model(model, d / "model.json")
    mpath = d / "eval" / "metrics.json"
    metrics = (json.loads(mpath.read_text()) if _done(mpath)
               else _evaluate_into(model, ds, d / "eval", cfg, "proxy Go1 (fine-tuned)"))
    entry = _experiment_entry(model, metrics, run, proxy, d / "model.json")
    bpath = d / "base_eval" / "metrics.json"
    entry["before_finetune"] = (json.loads(bpath.read_text()) if _done(bpath)
                                else _evaluate_into(base, ds, d / "base_eval", cfg, "proxy Go1 (sim model)"))
    entry["finetune"] = asdict(cfg.finetune)
    return entry


def run_solvers(run: Path, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """Both solvers on SIM Go1 (l = 2, p = 1): accuracy, active terms, wall time."""
    ds = read_dataset(data)
    out = {}
    for solver in ("exact", "adam"):
        d = run / "go1_sim" / "solvers" / solver
        d.mkdir(parents=True, exist_ok=True)
        say(f"solvers: training with {solver}")
        tc = cfg.go1().train_config(cfg.seed, solver=solver, adam=cfg.adam)
        model, wall = _train_or_load(d / "model.json", ds, tc)
        wall = model.info.get("wall_time_s", wall)
        mpath = d / "eval" / "metrics.json"
        metrics = (json.loads(mpath.read_text()) if _done(mpath)
                   else _evaluate_into(model, ds, d / "eval", cfg, f"SIM Go1 ({solver})"))
        out[solver] = {"wall_time_s": wall, "active_terms": model.active_terms(), "metrics": metrics,
                       "config": asdict(tc) if solver == "adam" else {"threshold": tc.threshold,
                                                                          "decoded_weight": tc.decoded_weight,
                                                                          "alpha": tc.alpha}}
    return out


def run_sweep_step(run: Path, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """The latent-dimension trade-off on SIM Go1, plus encoders for the heatmaps."""
    from symrom.experiments.sweep import SweepConfig, run_sweep

    d = run / "sweep"
    ds = read_dataset(data)
    sc = SweepConfig(latent_dims=tuple(cfg.sweep_dims), seeds=cfg.sweep_seeds, lam=cfg.sweep_lambda,
                     workers=cfg.workers)
    result = run_sweep(ds, sc, d, progress=lambda done, total, info: say(f"sweep: {done}/{total} cells", transient=True))
    enc = d / "encoders"
    enc.mkdir(parents=True, exist_ok=True)
    for l in sorted({2, max(cfg.sweep_dims)}):
        p = enc / f"W_e_l{l}.json"
        if not _done(p):
            m = train(ds, TrainConfig(l, 1, seed=cfg.seed))
            write_text_atomic(p, json.dumps({"latent_dim": l, "W_e": m.autoencoder.W_e.tolist()}))
    return result


def manifest(run: Path, cfg: ReproduceConfig, summary: dict) -> list[ManifestEntry]:
    """The run's experiments with their roles and files (paths relative to ``run``), for the report."""
    def rel(*parts: str) -> str:
        return str(Path(*parts))

    exps, out = summary["experiments"], []
    for exp in cfg.experiments:
        data = rel("data", f"{exp.data}.h5")
        out.append(ManifestEntry(exp.name, LEARNED, paper=exp.name if exp.name in PAPER_TABLE2 else None,
                                 files={"model": rel(exp.name, "model.json"), "metrics": rel(exp.name, "eval", "metrics.json"),
                                        "data": data}, facts={"config": exps[exp.name]["config"]}))
        if "paper_defaults" in exps[exp.name]:
            d = rel(exp.name, "paper_defaults")
            out.append(ManifestEntry(f"{exp.name}/paper_defaults", LEARNED, f"{exp.name} with the paper's defaults",
                                     files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json"),
                                            "data": data}, of=exp.name,
                                     facts={"config": {"encoder_components": None, "decoded_weight": 1.0, "alpha": 0.0}}))
    go1 = exps.get("go1_sim", {})
    if "aslip" in go1:
        d = rel("go1_sim", "aslip")
        out.append(ManifestEntry("go1_sim/aslip", BASELINE, "aSLIP", of="go1_sim", paper="aslip",
                                 files={"metrics": rel(d, "metrics.json"), "params": rel(d, "params.json"),
                                        "data": rel("data", "go1_sim.h5")}))
    for solver, s in go1.get("solvers", {}).items():
        d = rel("go1_sim", "solvers", solver)
        out.append(ManifestEntry(f"go1_sim/solvers/{solver}", SOLVER, solver, of="go1_sim",
                                 files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json")},
                                 facts={"wall_time_s": s["wall_time_s"]}))
    if "go1_proxy" in exps:
        out.append(ManifestEntry("go1_proxy", FINE_TUNED, "proxy Go1, fine-tuned from the noisy Go1 model",
                                 paper="go1_proxy", files={
                                     "model": rel("go1_proxy", "model.json"), "metrics": rel("go1_proxy", "eval", "metrics.json"),
                                     "data": exps["go1_proxy"]["data"], "source_model": rel("go1_proxy", "base", "model.json"),
                                     "before": rel("go1_proxy", "base_eval", "metrics.json")},
                                 facts={"finetune": exps["go1_proxy"]["finetune"]}))
    out.append(ManifestEntry("sweep", SWEEP, "latent-dimension sweep", of="go1_sim",
                             files={"result": rel("sweep", "sweep.json"), "encoders": rel("sweep", "encoders")}))
    return out


def _versions() -> dict:
    import numpy
    import scipy

    v = {"symrom": __version__, "python": platform.python_version(), "numpy": numpy.__version__,
         "scipy": scipy.__version__}
    from importlib.metadata import PackageNotFoundError, version

    try:
        v["pybullet"] = version("pybullet")
    except PackageNotFoundError:  # optional in a run that reuses datasets
        pass
    return v


def reproduce(run: Path, cfg: ReproduceConfig, command: str = "", say: Say | None = None) -> dict:
    """Run every experiment into ``run``; write and return ``summary.json``'s content."""
    say = say or (lambda msg, transient=False: None)
    t0 = time.perf_counter()
    run.mkdir(parents=True, exist_ok=True)
    data = {spec.name: ensure_dataset(run, spec, cfg, say) for spec in cfg.datasets}
    summary: dict = {"experiments": {}}
    for exp in cfg.experiments:
        summary["experiments"][exp.name] = run_learned(run, exp, data[exp.data], cfg, say)
    go1 = summary["experiments"].get("go1_sim")
    if go1 is not None:
        go1["aslip"] = run_aslip(run, data["go1_sim"], say)
        if cfg.compare_solvers:
            go1["solvers"] = run_solvers(run, data["go1_sim"], cfg, say)
    if "go1_noisy" in data and "go1_proxy" in data:
        summary["experiments"]["go1_proxy"] = run_proxy(run, data["go1_noisy"], data["go1_proxy"], cfg, say)
    summary["sweep"] = run_sweep_step(run, data["go1_sim"], cfg, say)
    summary["manifest"] = [e.to_dict() for e in manifest(run, cfg, summary)]
    summary["run"] = {"command": command, "versions": _versions(), "seeds": {"seed": cfg.seed},
                      "config": json.loads(json.dumps(asdict(cfg), default=str)),
                      "wall_time_s": time.perf_counter() - t0}
    write_text_atomic(run / "summary.json", json.dumps(summary, indent=1, allow_nan=False,
                                                       default=lambda o: o.tolist() if isinstance(o, np.ndarray) else str(o)))
    return summary
