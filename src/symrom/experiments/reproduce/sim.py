"""The SIM experiments of a run (SIM Go1 pronking, SIM A1 froggy): the model chosen by the
validation selection, evaluated on the test split beside the paper's defaults and the baselines."""

from __future__ import annotations

import json
from pathlib import Path

from symrom.baselines import BASELINES
from symrom.data.dataset import Dataset
from symrom.data.io import read_dataset
from symrom.experiments.reproduce.baselines import run_baselines
from symrom.experiments.reproduce.config import ExperimentSpec, ReproduceConfig, Say
from symrom.experiments.reproduce.steps import done, evaluated, experiment_entry, train_evaluate
from symrom.experiments.select import Selection, select, write_selection
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import load_model, write_model_files


def selected(run: Path, exp: ExperimentSpec, ds: Dataset, cfg: ReproduceConfig, say: Say
              ) -> tuple[HybridModel, dict]:
    """The experiment's model chosen by the validation selection, and the selection table."""
    d = run / exp.name
    table = d / "selection" / "selection.json"
    if done(table) and done(d / "model.json"):
        return load_model(d / "model.json"), json.loads(table.read_text())
    sel: Selection = select(ds, cfg.selection_for(exp), progress=lambda done, total, what: say(
        f"{exp.name}: selection {done}/{total} ({what})", transient=True), backend=cfg.execution(),
                            cells_dir=d / "selection" / "cells")
    if sel.model is None:
        raise RuntimeError(f"{exp.name}: no selection candidate could be chosen ({sel.notes[0]})")
    write_selection(sel, d / "selection")
    write_model_files(sel.model, d)
    say(f"{exp.name}: selection done: {len(sel.rows)} candidate models in {sel.seconds:.0f} s")
    return sel.model, sel.to_dict()


def references_done(run: Path, exp: ExperimentSpec) -> bool:
    """Whether ``run_references`` of ``exp`` has finished (a resumed run)."""
    d = run / exp.name
    return done(d / "paper_defaults" / "eval" / "metrics.json") and all(
        done(d / name / "metrics.json") for name in BASELINES)


def run_references(run: Path, exp: ExperimentSpec, data: Path, cfg: ReproduceConfig, say: Say) -> dict:
    """The experiment's references, which the selection does not decide: the model with the
    paper's defaults, trained and evaluated, and the baselines; their summary entries."""
    ds = read_dataset(data)
    d = run / exp.name
    if not done(d / "paper_defaults" / "model.json"):
        say(f"{exp.name}: training with the paper's defaults")
    base, bm = train_evaluate(ds, d / "paper_defaults", exp.paper_config(cfg.seed), cfg,
                              f"SIM {exp.name} (paper defaults)", say)
    return {"paper_defaults": {"active_terms": base.active_terms(), "metrics": bm.to_dict(),
                               "model": str((d / "paper_defaults" / "model.json").relative_to(run))},
            "baselines": run_baselines(run, exp, ds, cfg, say)}


def run_learned(run: Path, exp: ExperimentSpec, data: Path, cfg: ReproduceConfig, say: Say,
                references=None) -> dict:
    """Select, train and evaluate one experiment, with its references (``run_references``:
    the paper-default variant and the baselines); its summary entry. ``references``: where
    they are made (a ``Beside`` of the run, whose ``result`` gives them), else made here after
    the selection."""
    ds = read_dataset(data)
    d = run / exp.name
    d.mkdir(parents=True, exist_ok=True)
    say(f"{exp.name}: selecting the settings on the validation split")
    model, table = selected(run, exp, ds, cfg, say)
    if not done(d / "eval" / "metrics.json"):
        say(f"{exp.name}: evaluating on the test split")
    metrics = evaluated(model, ds, d / "eval", cfg, f"SIM {exp.name}")
    entry = experiment_entry(model, metrics, run, data, d / "model.json")
    chosen = table["rows"][table["chosen"]]
    entry["config"] = {**{k: chosen[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine")},
                       "max_terms": chosen.get("max_terms"), "keep": chosen.get("keep", []),
                       **{k: table["config"][k] for k in ("measure", "collinearity", "alpha", "decoded_weight",
                                                          "checks")},
                       "selection_score": chosen["score"], "candidates": len(table["rows"])}
    entry.update(references.result() if references is not None else run_references(run, exp, data, cfg, say))
    return entry
