"""The paper's experiments end to end, into one run directory.

Layout of ``DIR`` (every step is skipped when its output exists, so an
interrupted run resumes where it stopped and datasets are never regenerated):

    data/go1_sim.h5, a1_sim.h5, go1_noisy.h5, go1_proxy.h5   simulated datasets
    <exp>/     model.json (the selected model), eval/, selection/ (selection.json, cells/),
               paper_defaults/ (model.json, eval/),
               aslip/, aslip_rollout/, newton/, newton_fitted/ (metrics.json, params.json)
    go1_sim/solvers/{exact,adam}/ (model.json, eval/)
    go1_proxy/ base/model.json, base_exact/model.json (trained on the noisy Go1 variant
               with the settings selected on SIM Go1, refined and not), model.json
               (the candidate chosen on the proxy's val jumps), finetune_choice.json,
               eval/, base_eval/
    sweep/     sweep.json, cells/, encoders/W_e_l<k>.json
    summary.json   experiments, sweep, run, and ``manifest``: every experiment with its
                   role and files, which the report renders

Every ``model.json`` has its ``equations.txt`` beside it (``write_model_files``).

Experiments: SIM Go1 pronking, SIM A1 froggy (phases contact / partial /
flight), sim-to-real (train on noisy Go1, fine-tune on the proxy's training
jumps, choose on its val jumps, evaluate on its test jump), the baselines (aSLIP
fitted to acceleration residuals and to rollouts, Newton on the measured force
as it is and with fitted gains) beside each SIM model, the latent-dimension trade-off on SIM Go1, and both solvers on SIM Go1.

Every SIM model's settings are chosen by the validation selection
(``symrom.experiments.select``: encoder, latent dimension, library, sparsity,
refinement; the test split is read only by the evaluation). The paper's
defaults (its latent dimension, encoder over all 18 components,
decoded-acceleration term at weight 1, no ridge, |Xi| < 0.01 dropped) are
trained and evaluated beside each under ``paper_defaults``.
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from symrom import __version__
from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate
from symrom.evaluate.outputs import write_evaluation, write_json
from symrom.evaluate.paper import PAPER_TABLE2, implied_rmse
from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, SELECTION, SOLVER, SWEEP, ManifestEntry
from symrom.execution import Backend, make_backend
from symrom.experiments.select import (Selection, SelectionConfig, encoder_name, library_name, select, selection_rule,
                                      write_selection)
from symrom.learn.finetune import FineTuneConfig, finetune
from symrom.learn.training import AdamConfig, TrainConfig, train
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import load_model, write_model_files
from symrom.rollout.integrate import RolloutOptions

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


@dataclass(frozen=True)
class ExperimentSpec:
    """One learned-model experiment on dataset ``data``: its settings are selected on the
    train/val splits over ``latent_dims`` (and the rest of ``ReproduceConfig.selection``);
    ``paper_latent_dim`` is the l of the paper's defaults, trained beside it."""

    name: str
    data: str
    paper_latent_dim: int
    latent_dims: tuple[int, ...] = (2, 3, 4)

    def paper_config(self, seed: int = 0) -> TrainConfig:
        return TrainConfig(latent_dim=self.paper_latent_dim, poly_order=1, seed=seed)


# The term budget of every SIM selection (``SelectionConfig.max_terms``): a model whose
# equations one can read, as the paper's (17 terms on Go1).
MAX_TERMS = 60


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
        ExperimentSpec("go1_sim", "go1_sim", 2, (2, 3, 4)),
        ExperimentSpec("a1_sim", "a1_sim", 4, (4, 5, 6)),
    )
    selection: SelectionConfig = field(default_factory=lambda: SelectionConfig(max_terms=MAX_TERMS))
    paper_reference: bool = True
    finetune: FineTuneConfig = field(default_factory=FineTuneConfig)
    sweep_dims: tuple[int, ...] = tuple(range(1, 19))
    sweep_seeds: int = 5
    sweep_lambda: float = 1e-3
    compare_solvers: bool = True
    adam: AdamConfig = field(default_factory=AdamConfig)
    seed: int = 0
    workers: int = 2
    integrator: str = "lsoda"
    backend: str = "local"
    address: str | None = None
    engine: str = "pybullet"  # the physics engine of every generated dataset

    def execution(self) -> Backend:
        """The back end of the heavy steps (generation, selection, sweep): ``backend`` with
        ``workers`` (local processes, or the most Ray tasks at once) at ``address`` (Ray)."""
        return make_backend(self.backend, self.workers, self.address)

    def selection_for(self, exp: ExperimentSpec) -> SelectionConfig:
        """The selection of ``exp``: its latent dimensions and, for an experiment with a row in
        the paper's Table 2 (and ``paper_reference``), the paper's implied RMSE as the bar."""
        ref = paper_reference(exp.name) if self.paper_reference else None
        return replace(self.selection, latent_dims=exp.latent_dims, workers=self.workers, reference=ref)

    @classmethod
    def quick(cls) -> ReproduceConfig:
        """A reduced run: few jumps per dataset, a small selection grid, a short sweep and adam run."""
        return cls(
            datasets=(DatasetSpec("go1_sim", "go1", "pronk", 10), DatasetSpec("a1_sim", "a1", "froggy", 8),
                      DatasetSpec("go1_noisy", "go1", "pronk", 8, noise=True),
                      DatasetSpec("go1_proxy", "go1", "pronk", 5, proxy=True)),
            experiments=(ExperimentSpec("go1_sim", "go1_sim", 2, (2,)), ExperimentSpec("a1_sim", "a1_sim", 4, (3,))),
            selection=QUICK_SELECTION, sweep_dims=(1, 2, 4, 6, 18), sweep_seeds=2,
            adam=AdamConfig(epochs=20, refine_epochs=5, threshold_every=10), integrator="rk4")


def paper_reference(experiment: str) -> dict[str, dict[str, float]] | None:
    """Per horizon and Table 2 component, the RMSE the paper's mean and std imply for
    ``experiment`` (None if it has no row)."""
    if experiment not in PAPER_TABLE2:
        return None
    return {h: {c: implied_rmse(*ms) for c, ms in row.items()} for h, row in PAPER_TABLE2[experiment].items()}


# A small grid for quick runs and the demo: the two encoders that matter most on
# jumping data, two sparsity levels, one refined candidate.
QUICK_SELECTION = SelectionConfig(encoders=("base_position", "standardised"), libraries=("poly1+inputs",),
                                  thresholds=(1e-3, 1e-2), refine_top=1)


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
                        noise=NoiseConfig() if spec.noise else None, engine=cfg.engine)
    generate(gc, path, backend=cfg.execution(), resume=True,
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
    write_model_files(model, path.parent)
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


def _selected(run: Path, exp: ExperimentSpec, ds: Dataset, cfg: ReproduceConfig, say: Say
              ) -> tuple[HybridModel, dict]:
    """The experiment's model chosen by the validation selection, and the selection table."""
    d = run / exp.name
    table = d / "selection" / "selection.json"
    if _done(table) and _done(d / "model.json"):
        return load_model(d / "model.json"), json.loads(table.read_text())
    sel: Selection = select(ds, cfg.selection_for(exp), progress=lambda done, total, what: say(
        f"{exp.name}: selection {done}/{total} ({what})", transient=True), backend=cfg.execution(),
                            cells_dir=d / "selection" / "cells")
    if sel.model is None:
        raise RuntimeError(f"{exp.name}: every selection candidate diverged on a validation jump")
    write_selection(sel, d / "selection")
    write_model_files(sel.model, d)
    say(f"{exp.name}: selection done: {len(sel.rows)} candidate models in {sel.seconds:.0f} s")
    return sel.model, sel.to_dict()


def run_learned(run: Path, exp: ExperimentSpec, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """Select, train and evaluate one experiment, and its paper-default variant and
    baselines; its summary entry."""
    ds = read_dataset(data)
    d = run / exp.name
    d.mkdir(parents=True, exist_ok=True)
    say(f"{exp.name}: selecting the settings on the validation split")
    model, table = _selected(run, exp, ds, cfg, say)
    mpath = d / "eval" / "metrics.json"
    if _done(mpath):
        metrics = json.loads(mpath.read_text())
    else:
        say(f"{exp.name}: evaluating on the test split")
        metrics = _evaluate_into(model, ds, d / "eval", cfg, f"SIM {exp.name}")
    entry = _experiment_entry(model, metrics, run, data, d / "model.json")
    chosen = table["rows"][table["chosen"]]
    entry["config"] = {**{k: chosen[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine")},
                       "max_terms": chosen.get("max_terms"),
                       **{k: table["config"][k] for k in ("measure", "collinearity", "alpha", "decoded_weight")},
                       "selection_score": chosen["score"], "candidates": len(table["rows"])}
    say(f"{exp.name}: training with the paper's defaults")
    base, bm = _train_evaluate(ds, d / "paper_defaults", exp.paper_config(cfg.seed), cfg,
                               f"SIM {exp.name} (paper defaults)", say)
    entry["paper_defaults"] = {"active_terms": base.active_terms(), "metrics": bm,
                               "model": str((d / "paper_defaults" / "model.json").relative_to(run))}
    entry["baselines"] = run_baselines(run, exp, ds, cfg, say)
    return entry


BASELINES = ("aslip", "aslip_rollout", "newton", "newton_fitted")


def run_baselines(run: Path, exp: ExperimentSpec, ds: Dataset, cfg: ReproduceConfig, say: Say) -> dict:
    """The aSLIP (residual fit and rollout fit), Newton and Newton with fitted gains beside ``exp``, fitted on its
    training split and evaluated on its test split; their metrics by name."""
    from symrom.baselines.aslip import ASlip, fit_aslip, fit_aslip_rollout
    from symrom.baselines.newton import AffineForce, Newton

    out = {}
    residual = None
    for name in BASELINES:
        d = run / exp.name / name
        if _done(d / "metrics.json"):
            out[name] = json.loads((d / "metrics.json").read_text())
            continue
        say(f"{exp.name}: baseline {name}")
        if name == "newton":
            model = Newton.of(ds)
            params = {"model": "newton", "m": model.m, "source": "the robot's total mass; nothing fitted"}
        elif name == "newton_fitted":
            model = AffineForce.fit(ds, ds.rows_of("train"))
            params = {**model.to_dict(), "source": "fitted on the train split (least squares on the base accelerations)"}
        else:
            residual = residual or fit_aslip(ds, ds.rows_of("train"))
            p, extra = residual, {"source": "fitted on the train split (acceleration residual)"}
            if name == "aslip_rollout":
                p, fit = fit_aslip_rollout(ds, m=residual.m, start=residual)
                extra = {"source": "fitted on the train split (CoM rollout error, multiple shooting)",
                         "stages": fit.stages}
            model, params = ASlip(p), {"model": "aslip", **asdict(p), **extra}
        metrics, _ = evaluate(model, ds, "test", (None, 0.1), RolloutOptions(cfg.integrator), model_name=name,
                              data_name=f"data/{exp.data}.h5")
        d.mkdir(parents=True, exist_ok=True)
        write_json(d / "params.json", params)
        write_json(d / "metrics.json", metrics)
        out[name] = metrics
    return out


def selected_config(model: HybridModel, **changes) -> TrainConfig:
    """The training configuration a selected model was made with, ``changes`` applied."""
    return replace(TrainConfig(**model.info["training"]), **changes)


# Sim-to-real candidates: the source trained on the noisy variant with the selected
# settings, with and without its refinement, each kept as it is or fine-tuned on the
# proxy's train jumps by calibration (learn.calibrate), acceleration (FineTune) or rollout (Refine).
PROXY_SOURCES = ("refined", "exact")
PROXY_METHODS = ("none", "calibrate", "acceleration", "rollout")


def proxy_selection(cfg: ReproduceConfig) -> SelectionConfig:
    """The rule the proxy's candidates are chosen by: the selection's, against the paper's proxy row."""
    return replace(cfg.selection, reference=paper_reference("go1_proxy") if cfg.paper_reference else None)


def choose_proxy(sources: dict[str, HybridModel], ds: Dataset, cfg: ReproduceConfig,
                 say: Say) -> tuple[list[dict], list[HybridModel | None], int | None]:
    """Every (source, fine-tuning) candidate scored on the proxy's val jumps against the paper's
    implied RMSE for the proxy (``select.score_model``), and the index ``select.choose`` picks:
    the sparsest that meets it at both horizons, else the sparsest within the tolerance of the
    best. A fine-tuning that cannot be done is recorded with its reason."""
    from symrom.experiments.select import choose, score_model
    from symrom.model.hybrid import ModelDataError

    scfg = proxy_selection(cfg)
    yardstick = scfg.yardstick(ds)
    rows, models = [], []
    for src in PROXY_SOURCES:
        for method in PROXY_METHODS:
            say(f"go1_proxy: {src} source, fine-tuning {method}")
            row: dict = {"source": src, "finetune": method}
            try:
                model = (sources[src] if method == "none" else
                         finetune(sources[src], ds, config=replace(cfg.finetune, method=method)))
            except ModelDataError as e:
                rows.append({**row, "refused": str(e), "score": None, "active_terms": None})
                models.append(None)
                continue
            rows.append({**row, "active_terms": int(model.mask.sum()),
                         **score_model(model, ds, yardstick, scfg.substeps)})
            models.append(model)
    return rows, models, choose(rows, scfg.tolerance, reference=scfg.reference is not None)


def run_proxy(run: Path, noisy: Path, proxy: Path, settings: TrainConfig, cfg: ReproduceConfig, say: Say) -> dict:
    """Sim-to-real: train on the noisy Go1 variant with the ``settings`` selected on SIM Go1
    (refined and not), fine-tune on the proxy's train jumps, choose on its val jumps
    (``choose_proxy``), report on its test jumps."""
    d = run / "go1_proxy"
    (d / "base").mkdir(parents=True, exist_ok=True)
    say("go1_proxy: training on the noisy Go1 variant")
    noisy_ds = read_dataset(noisy)
    sources = {"refined": _train_or_load(d / "base" / "model.json", noisy_ds, settings)[0],
               "exact": _train_or_load(d / "base_exact" / "model.json", noisy_ds, replace(settings, refine=False))[0]}
    ds = read_dataset(proxy)
    cpath = d / "finetune_choice.json"
    if _done(d / "model.json") and _done(cpath):
        model, choice = load_model(d / "model.json"), json.loads(cpath.read_text())
    else:
        rows, models, k = choose_proxy(sources, ds, cfg, say)
        if k is None:  # every candidate diverged on val: keep the source as trained
            k = 0
        model = models[k]
        choice = {"version": 1, "rows": rows, "chosen": k, "split": "val",
                  "rule": selection_rule(proxy_selection(cfg))}
        write_model_files(model, d)
        write_text_atomic(cpath, json.dumps(choice, indent=1, allow_nan=False))
    mpath = d / "eval" / "metrics.json"
    metrics = (json.loads(mpath.read_text()) if _done(mpath)
               else _evaluate_into(model, ds, d / "eval", cfg, "proxy Go1 (chosen on val)"))
    entry = _experiment_entry(model, metrics, run, proxy, d / "model.json")
    bpath = d / "base_eval" / "metrics.json"
    entry["before_finetune"] = (json.loads(bpath.read_text()) if _done(bpath)
                                else _evaluate_into(sources["refined"], ds, d / "base_eval", cfg,
                                                    "proxy Go1 (sim model)"))
    chosen = choice["rows"][choice["chosen"]]
    entry["finetune"] = {**asdict(cfg.finetune), "source": chosen["source"], "method": chosen["finetune"]}
    entry["finetune_choice"] = choice
    return entry


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
        model, wall = _train_or_load(d / "model.json", ds, tc)
        wall = model.info.get("wall_time_s", wall)
        mpath = d / "eval" / "metrics.json"
        metrics = (json.loads(mpath.read_text()) if _done(mpath)
                   else _evaluate_into(model, ds, d / "eval", cfg, f"SIM Go1 ({solver})"))
        out[solver] = {"wall_time_s": wall, "active_terms": model.active_terms(), "metrics": metrics,
                       "config": asdict(tc)}
    return out


def run_sweep_step(run: Path, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """The latent-dimension trade-off on SIM Go1, plus encoders for the heatmaps."""
    from symrom.experiments.sweep import SweepConfig, run_sweep

    d = run / "sweep"
    ds = read_dataset(data)
    sc = SweepConfig(latent_dims=tuple(cfg.sweep_dims), seeds=cfg.sweep_seeds, lam=cfg.sweep_lambda,
                     workers=cfg.workers)
    result = run_sweep(ds, sc, d, progress=lambda done, total, info: say(f"sweep: {done}/{total} cells", transient=True),
                       backend=cfg.execution())
    enc = d / "encoders"
    enc.mkdir(parents=True, exist_ok=True)
    for l in sorted({2, max(cfg.sweep_dims)}):
        p = enc / f"W_e_l{l}.json"
        if not _done(p):
            m = train(ds, TrainConfig(l, 1, seed=cfg.seed))
            write_text_atomic(p, json.dumps({"latent_dim": l, "W_e": m.autoencoder.W_e.tolist()}))
    return result


def config_facts(tc: TrainConfig) -> dict:
    """A training configuration in the words of the selection's table (the manifest's facts)."""
    return {"encoder": encoder_name(tc), "latent_dim": tc.latent_dim,
            "library": library_name(tc.poly_order, tc.trig, tc.inputs), "threshold": tc.threshold,
            "measure": tc.measure, "decoded_weight": tc.decoded_weight, "alpha": tc.alpha, "refine": tc.refine}


def manifest(run: Path, cfg: ReproduceConfig, summary: dict) -> list[ManifestEntry]:
    """The run's experiments with their roles and files (paths relative to ``run``), for the report."""
    def rel(*parts: str) -> str:
        return str(Path(*parts))

    exps, out = summary["experiments"], []
    for exp in cfg.experiments:
        data = rel("data", f"{exp.data}.h5")
        entry = exps[exp.name]
        out.append(ManifestEntry(exp.name, LEARNED, paper=exp.name if exp.name in PAPER_TABLE2 else None,
                                 files={"model": rel(exp.name, "model.json"), "metrics": rel(exp.name, "eval", "metrics.json"),
                                        "data": data}, facts={"config": entry["config"]}))
        out.append(ManifestEntry(f"{exp.name}/selection", SELECTION, f"{exp.name}: selection on the validation split",
                                 of=exp.name, files={"table": rel(exp.name, "selection", "selection.json")}))
        d = rel(exp.name, "paper_defaults")
        out.append(ManifestEntry(f"{exp.name}/paper_defaults", LEARNED, f"{exp.name} with the paper's defaults",
                                 files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json"),
                                        "data": data}, of=exp.name,
                                 facts={"config": config_facts(exp.paper_config(cfg.seed))}))
        for name in entry.get("baselines", {}):
            d = rel(exp.name, name)
            out.append(ManifestEntry(f"{exp.name}/{name}", BASELINE, BASELINE_TITLES[name], of=exp.name,
                                     paper="aslip" if name.startswith("aslip") and exp.name == "go1_sim" else None,
                                     files={"metrics": rel(d, "metrics.json"), "params": rel(d, "params.json"),
                                            "data": data}))
    go1 = exps.get("go1_sim", {})
    for solver, s in go1.get("solvers", {}).items():
        d = rel("go1_sim", "solvers", solver)
        out.append(ManifestEntry(f"go1_sim/solvers/{solver}", SOLVER, solver, of="go1_sim",
                                 files={"model": rel(d, "model.json"), "metrics": rel(d, "eval", "metrics.json")},
                                 facts={"wall_time_s": s["wall_time_s"]}))
    if "go1_proxy" in exps:
        out.append(ManifestEntry("go1_proxy", FINE_TUNED, "proxy Go1, adapted from the noisy Go1 model",
                                 paper="go1_proxy", files={
                                     "model": rel("go1_proxy", "model.json"), "metrics": rel("go1_proxy", "eval", "metrics.json"),
                                     "data": exps["go1_proxy"]["data"], "source_model": rel("go1_proxy", "base", "model.json"),
                                     "before": rel("go1_proxy", "base_eval", "metrics.json"),
                                     "choice": rel("go1_proxy", "finetune_choice.json")},
                                 facts={"finetune": exps["go1_proxy"]["finetune"]}))
    out.append(ManifestEntry("sweep", SWEEP, "latent-dimension sweep", of="go1_sim",
                             files={"result": rel("sweep", "sweep.json"), "encoders": rel("sweep", "encoders")}))
    return out


BASELINE_TITLES = {"aslip": "aSLIP (residual fit)", "aslip_rollout": "aSLIP (rollout fit)",
                   "newton": "Newton, b'' = g + F/m",
                   "newton_fitted": "Newton fitted, b'' = c + A F/m"}


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
    settings = selected_config(load_model(run / "go1_sim" / "model.json")) if go1 is not None else None
    if go1 is not None and cfg.compare_solvers:
        go1["solvers"] = run_solvers(run, data["go1_sim"], settings, cfg, say)
    if settings is not None and "go1_noisy" in data and "go1_proxy" in data:
        summary["experiments"]["go1_proxy"] = run_proxy(run, data["go1_noisy"], data["go1_proxy"], settings,
                                                         cfg, say)
    summary["sweep"] = run_sweep_step(run, data["go1_sim"], cfg, say)
    summary["manifest"] = [e.to_dict() for e in manifest(run, cfg, summary)]
    summary["run"] = {"command": command, "versions": _versions(), "seeds": {"seed": cfg.seed},
                      "config": json.loads(json.dumps(asdict(cfg), default=str)),
                      "wall_time_s": time.perf_counter() - t0}
    write_text_atomic(run / "summary.json", json.dumps(summary, indent=1, allow_nan=False,
                                                       default=lambda o: o.tolist() if isinstance(o, np.ndarray) else str(o)))
    return summary
