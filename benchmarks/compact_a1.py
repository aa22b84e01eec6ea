"""A compact SIM A1 model (at most 60 active terms), chosen on val and reported on test.

    python benchmarks/compact_a1.py --run RUN [--out benchmarks/results/compact_a1.json]

RUN/data/a1_sim.h5 is the SIM A1 dataset of ``symrom reproduce --out RUN`` (or of
``python benchmarks/sim_experiment.py a1_sim --run RUN``). The steps, every setting fixed
or chosen on the train and val splits:

1. the pose+joints encoder at l = 7, library poly1+inputs, threshold 0.01, the selection's
   other settings, refined and pruned to 60 terms: ``symrom train RUN/data/a1_sim.h5
   --latent-dim 7 --encoder-base-latents 3 --no-trig --measure explained --collinearity
   0.995 --alpha 1e-6 --decoded-weight 0 --threshold 0.01 --refine --max-terms 60``;
2. its flight phase refined again on the training jumps with the other phases held
   (``Refine.hold``), on 0.1 s windows and whole jumps, the 0.1 s windows weighted by each of
   ``SHORT_WEIGHTS`` (``Refine.short_weight``); the support, so the term count, is kept;
3. among the model of step 1 and those of step 2, the selection's rule on val
   (``select.choose`` with the paper's Table 2 as the reference);
4. the chosen model rolled out on the test jumps, once, and compared with the paper.

The chosen model goes to RUN/compact_a1 (model.json, equations.txt), the record to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from symrom.atomic import atomic_dir, write_text_atomic
from symrom.data.io import read_dataset
from symrom.evaluate.metrics import evaluate
from symrom.evaluate.paper import implied_rmse, paper_row
from symrom.experiments import select
from symrom.experiments.reproduce import ReproduceConfig
from symrom.learn.calibrate import FLIGHT_PHASE
from symrom.learn.estimator import phase_data, trajectories
from symrom.learn.regressors.base import Coefficients, RegressionProblem
from symrom.learn.regressors.refine import Refine
from symrom.learn.training import train
from symrom.model.hybrid import HybridModel
from symrom.model.persistence import write_model_files
from symrom.names import TABLE2_COMPONENTS
from symrom.rollout.integrate import RolloutOptions

VERSION = 1
MAX_TERMS = 60
CANDIDATE = ("pose+joints", 7, "poly1+inputs", 0.01)
SHORT_WEIGHTS = (10.0, 100.0)


def refine_flight(model: HybridModel, ds, short_weight: float) -> HybridModel:
    """``model`` with its flight coefficients refined on the train jumps' rollouts (0.1 s
    windows weighted ``short_weight`` times, and whole jumps), the other phases held."""
    rows = ds.rows_of("train")
    ae = model.autoencoder
    phases = phase_data(ds, rows, ae, model.library, float(model.estimator.get("decoded_weight", 0.0)),
                        model.phase_names)
    spread = np.maximum(ae.encode_derivative(ds.ddq[rows]).std(axis=0), 1e-12)
    problem = RegressionProblem(model.library, list(model.phase_names), phases, spread, ds.dt,
                                trajectories(ds, rows, ae))
    hold = tuple(n for n in model.phase_names if n != FLIGHT_PHASE)
    refine = Refine(windows=(0.1, None), hold=hold, short_weight=short_weight)
    fit = refine.fit(problem, init=Coefficients(model.Xi.copy(), model.mask.copy()))
    info = {**model.info, "flight_refinement": {"regressor": refine.to_dict(),
                                                 "stages": fit.report[FLIGHT_PHASE]["refinement"]["stages"]}}
    return replace(model, Xi=fit.Xi, mask=fit.mask, info=info)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="run directory holding data/a1_sim.h5")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/compact_a1.json"))
    args = ap.parse_args()
    data = args.run / "data" / "a1_sim.h5"
    if not data.is_file():
        raise SystemExit(f"{data} is missing: make it with `python benchmarks/sim_experiment.py a1_sim --run "
                         f"{args.run}` or `symrom reproduce --out {args.run}`")
    ds = read_dataset(data)
    rc = ReproduceConfig()
    exp = next(e for e in rc.experiments if e.name == "a1_sim")
    cfg = replace(rc.selection_for(exp), max_terms=MAX_TERMS)
    yardstick = cfg.yardstick(ds)
    encoder, l, library, threshold = CANDIDATE

    t0 = time.perf_counter()
    base = train(ds, cfg.train_config(encoder, l, library, threshold, refine=True))
    variants = [("pruned", base, time.perf_counter() - t0)]
    for w in SHORT_WEIGHTS:
        t1 = time.perf_counter()
        variants.append((f"flight refined, short_weight {w:g}", refine_flight(base, ds, w), time.perf_counter() - t1))
    rows = []
    for name, model, seconds in variants:
        scored = select.score_model(model, ds, yardstick, cfg.substeps)
        rows.append({"variant": name, "active_terms": int(model.mask.sum()), "active_per_phase": model.active_terms(),
                     "seconds": round(seconds, 1), **scored})
        print(f"{name}: {rows[-1]['active_terms']} terms, val worst full {scored['horizons']['full']['worst']}, "
              f"0.1 s {scored['horizons']['0.1']['worst']}", flush=True)
    chosen = select.choose(rows, cfg.tolerance, reference=True, max_terms=MAX_TERMS)
    model = variants[chosen][1]

    metrics, _ = evaluate(model, ds, "test", select.HORIZONS, RolloutOptions("rk4", substeps=cfg.substeps))
    test = {}
    for h, hm in metrics["horizons"].items():
        paper = paper_row("a1_sim", h)
        rmse = {c: hm["components"][c]["rmse"] for c in TABLE2_COMPONENTS}
        ref = {c: implied_rmse(*paper[c]) for c in TABLE2_COMPONENTS}
        test[h] = {"diverged_jumps": hm["diverged_jumps"], "drifted_jumps": hm["drifted_jumps"], "rmse": rmse,
                   "paper_rmse": ref, "at_or_below_paper": [c for c in rmse if rmse[c] <= ref[c]]}
        print(f"test {h}: at or below the paper: {len(test[h]['at_or_below_paper'])}/12, "
              f"diverged {hm['diverged_jumps']}", flush=True)
    with atomic_dir(args.run / "compact_a1", force=True) as tmp:
        write_model_files(model, tmp)
    out = {"version": VERSION, "candidate": dict(zip(("encoder", "latent_dim", "library", "threshold"), CANDIDATE)),
           "max_terms": MAX_TERMS, "val": rows, "chosen": chosen, "chosen_variant": rows[chosen]["variant"],
           "active_terms": int(model.mask.sum()), "active_per_phase": model.active_terms(), "test": test,
           "seconds": round(time.perf_counter() - t0, 1)}
    write_text_atomic(args.out, json.dumps(out, indent=1))
    print(f"record: {args.out} ({out['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
