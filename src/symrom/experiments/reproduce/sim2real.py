"""Sim-to-real: sources trained with the settings selected on the target robot's SIM experiment,
fine-tuned onto each hardware-like target and chosen on its val jumps. A target is logged as a
real robot's logs are (``DatasetSpec.log_faults``) and imported through the repair from physics
(``repaired_target``) before anything is fitted to it; the side-by-side table sets out the source
on the target as logged and as repaired, fine-tuned on the repaired jumps and a model of the
repaired jumps alone, and the targets' checks."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from symrom.atomic import write_text_atomic
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.evaluate.records import Metrics
from symrom.experiments.reproduce.config import ReproduceConfig, Say, paper_reference
from symrom.experiments.reproduce.steps import done, evaluated, experiment_entry, train_evaluate, train_or_load
from symrom.experiments.select import SelectionConfig, selection_rule
from symrom.learn.finetune import ROLLOUT_METHODS, FineTuneConfig, finetune
from symrom.learn.training import TrainConfig
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import load_model, write_model_files

# Sim-to-real. Sources: models trained, with the settings selected on the target robot's SIM
# experiment (refined and not), on each of its source datasets; targets: hardware-like datasets
# whose settings no source saw (Go1 pronk: the proxy in PyBullet, and in MuJoCo with armature too;
# A1 froggy in MuJoCo, its jumps holding the rear feet 0.25-0.4 s as a real froggy's do), logged
# with a real robot's log faults and repaired before use. Candidates: every source kept as it
# is or fine-tuned on the target's train jumps by calibration (learn.calibrate), acceleration
# (FineTune), rollout (Refine) or calibration then a rollout refinement of the non-flight phases,
# the flight phase held as calibrated (calibrate_rollout, the default); chosen on the target's
# val jumps.


@dataclass(frozen=True)
class Sim2RealTarget:
    """One sim-to-real target: its dataset (as logged), the SIM experiment whose selected
    settings its sources are trained with, its sources (source key, dataset) and the paper's
    Table 2 row its candidates are scored against on val (None: each component's spread)."""

    name: str
    settings: str
    sources: tuple[tuple[str, str], ...]
    paper: str | None = None


GO1_SOURCES = (("noisy", "go1_noisy"), ("randomized", "go1_randomized"))
SIM2REAL = (Sim2RealTarget("go1_proxy", "go1_sim", GO1_SOURCES, "go1_proxy"),
            Sim2RealTarget("go1_proxy_mujoco", "go1_sim", GO1_SOURCES, "go1_proxy"),
            Sim2RealTarget("a1_proxy_mujoco", "a1_sim", (("a1_randomized", "a1_randomized"),)))
SIM2REAL_SOURCES = {k: v for t in SIM2REAL for k, v in t.sources}  # source -> dataset
SIM2REAL_TARGETS = tuple(t.name for t in SIM2REAL)  # target datasets, one experiment each
PROXY_SOURCES = ("refined", "exact")
PROXY_METHODS = ("none", "calibrate", "acceleration", "rollout", "calibrate_rollout")
# The fine-tuning of the side-by-side table: the default one (``FineTuneConfig``'s, calibrate_rollout),
# whose val score (``symrom finetune``'s check) is below calibrate's from every source on both
# targets (randomised refined source: 0.596 against 0.607 on the PyBullet proxy, 0.467 against
# 0.540 on the MuJoCo proxy)
DEFAULT_METHOD = FineTuneConfig().method
# The sim-to-real targets checked on each target's test jumps (docs/results.md)
SOURCE_Z_MAX = 0.15  # m: the source as it is, full-horizon base-height RMSE
FINETUNED_Z_MAX = 0.05  # m: fine-tuned
CHOICE_VERSION = 2  # finetune_choice.json
GRAVITY_TOLERANCE = 0.05  # fine-tuned flight acceleration within 5 % of -g
SCRATCH_RATIO_MAX = 1.25  # fine-tuned at most this many times the target-alone model's RMSE


def proxy_selection(cfg: ReproduceConfig, paper: str | None = "go1_proxy") -> SelectionConfig:
    """The rule a target's candidates are chosen by: the selection's, against the paper's row
    ``paper`` (the proxy's for the Go1 targets; None: the components' spread)."""
    ref = paper_reference(paper) if cfg.paper_reference and paper is not None else None
    return replace(cfg.selection, reference=ref)


def source_models(run: Path, data: dict[str, Path], target: Sim2RealTarget, settings: TrainConfig,
                  say: Say) -> dict[str, HybridModel]:
    """The sim-to-real source models of ``target`` by key ``<source>/<refined|exact>``, each trained
    on its source dataset (those the run has) into ``run/sources/<source>/<variant>`` (shared
    by the targets that have it)."""
    out = {}
    for src, name in target.sources:
        if name not in data:
            continue
        ds = None
        for variant in PROXY_SOURCES:
            path = run / "sources" / src / variant / "model.json"
            if done(path):
                out[f"{src}/{variant}"] = load_model(path)
                continue
            say(f"sim-to-real: training the {variant} source on {name}")
            ds = ds or read_dataset(data[name])
            tc = settings if variant == "refined" else unrefined(settings)
            path.parent.mkdir(parents=True, exist_ok=True)
            out[f"{src}/{variant}"] = train_or_load(path, ds, tc)[0]
    return out


def transferred(settings: TrainConfig, hard_budget: int | None) -> TrainConfig:
    """The SIM selection's ``settings`` as sim-to-real trains its sources and targets with them.
    Without a hard budget (``hard_budget`` None) the selection's pruning to the soft one
    (``Refine.keep``) is left out: it was chosen because the pruned model stood on the SIM data's
    val against its own unpruned refinement, which no source or target is checked against."""
    return replace(settings, max_terms=None, keep=()) if hard_budget is None else settings


def unrefined(settings: TrainConfig) -> TrainConfig:
    """``settings`` without the refinement and what only the refinement reads (its term budget,
    its polish stages): the exact source's and an unrefined target-alone model's settings."""
    return replace(settings, refine=False, max_terms=None, keep=(), polish=())


def repaired_target(run: Path, name: str, logged: Path, say: Say) -> Path:
    """The target ``name`` as a user would import its logs: its jumps (``logged``, the dataset as
    its logger wrote them) written as a plain CSV log without accelerations
    (``data/<name>.csv``) and imported with the repair from physics (``import_logs(...,
    repair=RepairLimits())``, every check on, nothing of the planted faults known; the jumps
    kept as logged, each in its split) into ``data/<name>_repaired.h5``. Raises the import's
    error where the repair refuses a jump."""
    from symrom.data.importers import import_logs, write_plain_csv
    from symrom.data.io import write_dataset
    from symrom.data.repair import RepairLimits

    out = run / "data" / f"{name}_repaired.h5"
    if done(out):
        return out
    say(f"{name}: importing its logs through the repair from physics")
    ds = read_dataset(logged)
    csv = run / "data" / f"{name}.csv"
    write_plain_csv(ds, csv, accelerations=False)
    rep, _ = import_logs([csv], robot=ds.robot, motion=ds.motion, source=ds.source, segment="off",
                         repair=RepairLimits())
    if rep.n_jumps != ds.n_jumps:
        raise RuntimeError(f"{csv}: the import holds {rep.n_jumps} jumps, the target {ds.n_jumps}")
    write_dataset(replace(rep, split=ds.split.copy()), out)
    return out


def repair_summary(logged: Dataset, repaired: Dataset) -> dict:
    """What the repair found on a target's jumps beside what its logger planted
    (``generator.log_faults``; absent from a target logged without faults): per estimate the
    median and range over the jumps. ``sensor_scale`` beside the planted faults is the proxy's
    own torque sensor's scale (``proxy_robot.torque_scale``), under the logger's gain: the
    weight sees both, and the proxy's joint damping and friction loss besides."""
    jumps = repaired.generator["repairs"]["jumps"]

    def stat(values: list[float]) -> dict | None:
        v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
        return None if v.size == 0 else {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max())}

    clock = [j["clock"] for j in jumps]
    found = {"jumps": len(jumps), "changed": int(sum(j["changed"] for j in jumps)),
             "findings": {f: sum(c["finding"] == f for c in clock) for f in sorted({c["finding"] for c in clock})},
             "clock_scale": stat([c["scale"] if c["applied"] else 1.0 for c in clock]),
             "velocity_gain": stat([j["velocities"][0]["gain"] if j["velocities"][0]["applied"] else 1.0
                                    for j in jumps]),
             "torque_gain": stat([j["gain"]["gain"] if j["gain"]["applied"] else 1.0 for j in jumps]),
             "height_offset": stat([j["height"]["offset"] if j["height"] and j["height"]["applied"] else 0.0
                                    for j in jumps]),
             "contact_lag": stat([j["contacts"]["lag"] for j in jumps])}
    planted = logged.generator.get("log_faults")
    if planted is not None:
        planted = {**planted, "sensor_scale": (logged.generator.get("proxy_robot") or {}).get("torque_scale")}
    return {"planted": planted, "found": found}


def choose_proxy(sources: dict[str, HybridModel], ds: Dataset, cfg: ReproduceConfig,
                 say: Say, label: str = "go1_proxy", paper: str | None = "go1_proxy"
                 ) -> tuple[list[dict], list[HybridModel | None], int | None]:
    """Every (source, fine-tuning) candidate scored on the target's val jumps against the paper's
    implied RMSE for its row ``paper`` (``select.score_model``; None: the spread of each
    component), and the index ``select.choose`` picks:
    the sparsest that meets it at both horizons, else the sparsest within the tolerance of the
    best. A fine-tuning that cannot be done is recorded with its reason."""
    from symrom.experiments.select import choose, score_model
    from symrom.model.hybrid import ModelDataError

    scfg = proxy_selection(cfg, paper)
    yardstick = scfg.yardstick(ds)
    rows, models = [], []
    for src in sources:
        for method in PROXY_METHODS:
            say(f"{label}: {src} source, fine-tuning {method}")
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


def _side_entry(model: HybridModel, metrics: Metrics, ds: Dataset) -> dict:
    """One column of the side-by-side table: full-horizon x and z RMSE (m), diverged and drifted
    jumps, and the decoded flight acceleration on the test rows (m/s^2, its ratio to -g)."""
    from symrom.learn.calibrate import flight_gravity

    full = metrics.full
    fg = flight_gravity(model, ds, ds.rows_of("test"))
    return {"x_rmse": full.stat("x", "rmse"), "z_rmse": full.stat("z", "rmse"),
            "diverged_jumps": full.diverged_jumps, "drifted_jumps": full.drifted_jumps or 0,
            "flight_acc": None if fg is None else fg["model"], "flight_acc_data": None if fg is None else fg["data"],
            "flight_ratio": None if fg is None else fg["ratio"], "active_terms": int(model.mask.sum())}


def sim2real_checks(table: dict) -> dict:
    """The sim-to-real targets on one target's side-by-side ``table`` (``run_target``): each a
    bool, None where a column is missing or diverged. ``scratch_ratio_x`` / ``_z``: fine-tuned
    over target-alone full-horizon RMSE; ``vs_target_alone`` needs both within the bound."""
    src, ft, alone = table.get("source"), table.get("fine_tuned"), table.get("target_alone")

    def rmse(e, c):
        return None if e is None or e.get(f"{c}_rmse") is None or e["diverged_jumps"] else e[f"{c}_rmse"]

    out: dict = {"source_z_le": SOURCE_Z_MAX, "fine_tuned_z_le": FINETUNED_Z_MAX,
                 "gravity_within": GRAVITY_TOLERANCE, "scratch_ratio_le": SCRATCH_RATIO_MAX}
    zs, zf = rmse(src, "z"), rmse(ft, "z")
    out["source_z"] = None if zs is None else zs <= SOURCE_Z_MAX
    out["fine_tuned_z"] = None if zf is None else zf <= FINETUNED_Z_MAX
    out["not_above_source"] = None if zf is None or zs is None else zf <= zs
    out["flight_gravity"] = (None if ft is None or ft.get("flight_ratio") is None
                             else abs(ft["flight_ratio"] - 1.0) <= GRAVITY_TOLERANCE)
    for c in ("x", "z"):
        f, a = rmse(ft, c), rmse(alone, c)
        out[f"scratch_ratio_{c}"] = None if f is None or a is None else f / a
    ratios = [out["scratch_ratio_x"], out["scratch_ratio_z"]]
    out["vs_target_alone"] = None if None in ratios else max(ratios) <= SCRATCH_RATIO_MAX
    return out


def table_source(choice: dict, tolerance: float) -> str:
    """The source of the side-by-side table, from the target's val scores (``finetune_choice.json``'s
    rows): among the sources whose ``DEFAULT_METHOD`` fine-tuning scores within ``tolerance`` (a
    fraction) of the best, the one that scores best as it is (``none``; when fine-tuning leaves the
    sources indistinguishable on val, the one that needs it least); else the chosen row's."""
    rows = [r for r in choice["rows"] if r["finetune"] == DEFAULT_METHOD and r["score"] is not None]
    if not rows:
        return choice["rows"][choice["chosen"]]["source"]
    best = min(r["score"] for r in rows)
    near = [r["source"] for r in rows if r["score"] <= (1 + tolerance) * best]
    as_is = {r["source"]: r["score"] for r in choice["rows"] if r["finetune"] == "none" and r["score"] is not None}
    scored = [s for s in near if s in as_is]
    return (min(scored, key=as_is.get) if scored else
            min((r for r in rows if r["source"] in near), key=lambda r: r["score"])["source"])


def run_target(run: Path, target: Sim2RealTarget, logged: Path, repaired: Path, sources: dict[str, HybridModel],
               settings: TrainConfig, cfg: ReproduceConfig, say: Say) -> tuple[dict, dict]:
    """Sim-to-real onto one target, fitted and judged on its ``repaired`` jumps
    (``repaired_target``): every (source, fine-tuning) candidate chosen on its val jumps
    (``choose_proxy``), reported on its test jumps; beside it the side-by-side table of the source
    chosen on val by ``table_source`` as it is on the test jumps as ``logged`` and as repaired,
    fine-tuned by the default method (checked on val) and a model trained on the target's train
    jumps alone with the same settings (refined if the source or the default fine-tuning is),
    and what the repair found beside what the logger planted. Returns (the experiment's
    summary entry, the table)."""
    name = target.name
    d = run / name
    d.mkdir(parents=True, exist_ok=True)
    ds = read_dataset(repaired)
    cpath = d / "finetune_choice.json"
    tuned: dict[str, HybridModel] = {}  # source -> its DEFAULT_METHOD candidate, where fitted in this call
    if done(d / "model.json") and done(cpath):
        model, choice = load_model(d / "model.json"), json.loads(cpath.read_text())
    else:
        rows, models, k = choose_proxy(sources, ds, cfg, say, name, target.paper)
        tuned = {r["source"]: m for r, m in zip(rows, models) if r["finetune"] == DEFAULT_METHOD and m is not None}
        if k is None:  # every candidate diverged on val: keep the first source as trained
            k = 0
        model = models[k]
        choice = {"version": CHOICE_VERSION, "rows": rows, "chosen": k, "split": "val",
                  "rule": selection_rule(proxy_selection(cfg, target.paper))}
        write_model_files(model, d)
        write_text_atomic(cpath, json.dumps(choice, indent=1, allow_nan=False))
    title = {"go1_proxy": "proxy Go1"}.get(name, name.replace("_", " "))
    metrics = evaluated(model, ds, d / "eval", cfg, f"{title} (chosen on val)")
    entry = experiment_entry(model, metrics, run, repaired, d / "model.json")
    chosen = choice["rows"][choice["chosen"]]

    def as_is(key: str) -> Metrics:  # a source evaluated on the test jumps as it was trained
        return evaluated(sources[key], ds, d / "sources_eval" / key, cfg, f"{title} ({key} source as is)")

    entry["before_finetune"] = as_is(chosen["source"]).to_dict()
    entry["finetune"] = {**asdict(cfg.finetune), "source": chosen["source"], "method": chosen["finetune"]}
    entry["finetune_choice"] = choice
    src_key = table_source(choice, proxy_selection(cfg, target.paper).tolerance)
    source = sources[src_key]
    as_logged = read_dataset(logged)
    table = {"source_model": src_key, "method": DEFAULT_METHOD, "chosen_method": chosen["finetune"],
             "chosen_source": chosen["source"], "chosen": _side_entry(model, metrics, ds),
             "engine": ds.generator.get("engine") or as_logged.generator.get("engine"),
             "robot": ds.robot, "motion": ds.motion,
             "data": str(repaired.relative_to(run)), "data_logged": str(logged.relative_to(run)),
             "jumps": {s: int(len(ds.jumps_in(s))) for s in ("train", "val", "test")},
             "repair": repair_summary(as_logged, ds),
             "logged": _side_entry(source, evaluated(source, as_logged, d / "sources_eval_logged" / src_key, cfg,
                                                     f"{title} as logged ({src_key} source as is)"), as_logged),
             "source": _side_entry(source, as_is(src_key), ds)}
    fdir = d / "fine_tuned"
    if done(fdir / "model.json"):
        ft = load_model(fdir / "model.json")
    elif done(fdir / "refused.json"):
        ft = None
        table["fine_tuned"] = json.loads((fdir / "refused.json").read_text())
    else:
        ft = _default_finetune(source, ds, fdir, cfg, table, f"{name}: fine-tuning the {src_key} source", say,
                               tuned.get(src_key))
    if ft is not None:
        table["prior_weight"] = ft.provenance.finetune.config["prior_weight"]  # accepted on val
        fm = evaluated(ft, ds, fdir / "eval", cfg, f"{title} (fine-tuned, {DEFAULT_METHOD})")
        table["fine_tuned"] = _side_entry(ft, fm, ds)
    say(f"{name}: training on the target's train jumps alone")
    # refined on rollouts if the source or its default fine-tuning was: the same care as the fine-tuned model
    refined = src_key.endswith("/refined") or DEFAULT_METHOD in ROLLOUT_METHODS
    tc = settings if refined else unrefined(settings)
    alone, am = train_evaluate(ds, d / "target_alone", tc, cfg, f"{title} (target alone)", say)
    table["target_alone"] = _side_entry(alone, am, ds)
    table["checks"] = sim2real_checks(table)
    return entry, table


def _default_finetune(source: HybridModel, ds: Dataset, fdir: Path, cfg: ReproduceConfig, table: dict,
                      what: str, say: Say, first: HybridModel | None = None) -> HybridModel | None:
    """The default fine-tuning, as ``symrom finetune`` does it: ``DEFAULT_METHOD`` on the train
    jumps, checked on the val jumps (the prior weight raised tenfold while the val score rises
    more than the tolerance; ``experiments.finetune.run_finetune``), its first attempt ``first``
    where ``choose_proxy`` fitted it. Writes ``fdir`` (the model and ``finetune.json``, or
    ``refused.json``); None if refused (the reason in ``table``)."""
    from symrom.experiments.finetune import FineTuneCheck, FineTuneRefused, run_finetune, write_finetune
    from symrom.model.hybrid import ModelDataError

    say(f"{what} by {DEFAULT_METHOD}, checked on val")
    try:
        result = run_finetune(source, ds, FineTuneCheck(config=replace(cfg.finetune, method=DEFAULT_METHOD)),
                              first=first)
    except (FineTuneRefused, ModelDataError) as e:
        table["fine_tuned"] = {"refused": str(e)}
        fdir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(fdir / "refused.json", json.dumps(table["fine_tuned"]))
        return None
    fdir.mkdir(parents=True, exist_ok=True)
    write_finetune(fdir, result)
    return result.model


def run_sim2real(run: Path, data: dict[str, Path], settings: dict[str, TrainConfig], cfg: ReproduceConfig,
                 say: Say) -> tuple[dict[str, dict], dict[str, dict]]:
    """Sim-to-real on every target the run has (``SIM2REAL``) whose SIM settings it has
    (``settings``: experiment -> its selected configuration), from every source of it the run
    has, each target repaired first (``repaired_target``): the experiments' entries and the
    side-by-side tables by target."""
    entries, tables = {}, {}
    for target in SIM2REAL:
        if target.name not in data or target.settings not in settings:
            continue
        tc = transferred(settings[target.settings], cfg.selection.max_terms)
        sources = source_models(run, data, target, tc, say)
        if not sources:
            continue
        repaired = repaired_target(run, target.name, data[target.name], say)
        entries[target.name], tables[target.name] = run_target(run, target, data[target.name], repaired, sources,
                                                               tc, cfg, say)
    return entries, tables
