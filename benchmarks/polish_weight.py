"""The weight of the flight polish (``Refine.polish_weight``), compared on SIM A1's val jumps.

    python benchmarks/polish_weight.py --run RUN [--out benchmarks/results/polish_weight.json]

RUN is a run directory of ``python benchmarks/sim_experiment.py a1_sim --run RUN --max-terms 60``
(or of ``symrom reproduce --out RUN --max-terms 60``): its SIM A1 data and the budget selection's
chosen candidate. That candidate is refined and pruned to the budget without the polish, then its
flight phase is refined again alone (the polish stage: ``Refine`` on 0.1 s windows and whole jumps,
the other phases held) with the 0.1 s windows weighted by each of ``WEIGHTS``, and every variant is
rolled out on the val jumps and compared with the paper's Table 2. The test split is not read.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from provenance import provenance

from symrom.atomic import write_text_atomic
from symrom.data.io import read_dataset
from symrom.experiments import select
from symrom.experiments.reproduce import ReproduceConfig
from symrom.learn.estimator import phase_data, trajectories
from symrom.learn.regressors.base import Coefficients, RegressionProblem
from symrom.learn.regressors.refine import Refine
from symrom.learn.training import train
from symrom.model.hybrid import HybridModel
from symrom.names import FLIGHT_PHASE

VERSION = 1
WEIGHTS = (1.0, 10.0, 100.0, 1000.0)


def polish_alone(model: HybridModel, ds, weight: float) -> HybridModel:
    """``model`` with its flight phase refined again on the train jumps, the other phases held:
    ``Refine.polish``'s stage with ``polish_weight`` = ``weight``."""
    rows = ds.rows_of("train")
    ae = model.autoencoder
    phases = phase_data(ds, rows, ae, model.library, float(model.estimator.get("decoded_weight", 0.0)),
                        model.phase_names)
    spread = np.maximum(ae.encode_derivative(ds.ddq[rows]).std(axis=0), 1e-12)
    problem = RegressionProblem(model.library, list(model.phase_names), phases, spread, ds.dt,
                                trajectories(ds, rows, ae))
    stage = Refine(polish_weight=weight).polish_stage(FLIGHT_PHASE, list(model.phase_names))
    fit = stage.fit(problem, init=Coefficients(model.Xi.copy(), model.mask.copy()))
    return replace(model, Xi=fit.Xi, mask=fit.mask)


def score_variant(name: str, weight: float | None, model: HybridModel, ds, yardstick: dict, substeps: int,
                  seconds: float) -> dict:
    """One row of the record: the variant, its weight (None: not polished), its terms and its val
    rollouts scored against ``yardstick`` (``select.score_model``: per horizon ``worst`` ratio)."""
    scored = select.score_model(model, ds, yardstick, substeps)
    return {"variant": name, "polish_weight": weight, "active_terms": int(model.mask.sum()),
            "active_per_phase": model.active_terms(), "seconds": round(seconds, 1), **scored}


def worst_ratio(row: dict) -> float:
    """The row's largest val RMSE / yardstick ratio over both horizons; inf if a horizon diverged."""
    ratios = [row["horizons"][h]["worst"] for h in ("full", "0.1")]
    return float("inf") if any(r is None for r in ratios) else max(ratios)


def best_weight(rows: list[dict]) -> float | None:
    """The polish weight whose variant val puts furthest under the yardstick (the smallest
    worst ratio; None: the unpolished variant); on a tie the smaller weight."""
    best = min(rows, key=lambda r: (worst_ratio(r), -1.0 if r["polish_weight"] is None else r["polish_weight"]))
    return best["polish_weight"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True, help="run directory of a budget SIM A1 selection")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/polish_weight.json"))
    args = ap.parse_args()
    data, table = args.run / "data" / "a1_sim.h5", args.run / "a1_sim" / "selection" / "selection.json"
    for path in (data, table):
        if not path.is_file():
            raise SystemExit(f"{path} is missing: make it with `python benchmarks/sim_experiment.py a1_sim --run "
                             f"{args.run} --max-terms 60`")
    sel = json.loads(table.read_text())
    chosen = sel["rows"][sel["chosen"]]
    if not chosen.get("max_terms"):
        raise SystemExit(f"{table}: its chosen candidate was not selected under a term budget (--max-terms)")
    ds = read_dataset(data)
    rc = ReproduceConfig()
    exp = next(e for e in rc.experiments if e.name == "a1_sim")
    cfg = replace(rc.selection_for(exp), max_terms=chosen["max_terms"])
    candidate = {k: chosen[k] for k in ("encoder", "latent_dim", "library", "threshold")}
    t0 = time.perf_counter()
    tc = cfg.train_config(*candidate.values(), refine=True)
    pruned = train(ds, replace(tc, polish=()))
    variants = [("pruned", None, pruned, time.perf_counter() - t0)]
    for w in WEIGHTS:
        t1 = time.perf_counter()
        variants.append((f"flight polished, weight {w:g}", w, polish_alone(pruned, ds, w), time.perf_counter() - t1))
    yardstick = cfg.yardstick(ds)
    rows = []
    for name, w, model, seconds in variants:
        rows.append(score_variant(name, w, model, ds, yardstick, cfg.substeps, seconds))
        h = rows[-1]["horizons"]
        print(f"{name}: val worst ratio to the paper, full {h['full']['worst']}, 0.1 s {h['0.1']['worst']}",
              flush=True)
    print(f"best weight on val: {best_weight(rows)} (the default: {Refine().polish_weight:g})")
    out = {"version": VERSION, "candidate": candidate, "max_terms": chosen["max_terms"],
           "default_polish_weight": Refine().polish_weight, "best_weight": best_weight(rows), "val": rows,
           "seconds": round(time.perf_counter() - t0, 1)}
    write_text_atomic(args.out, json.dumps({**provenance(), **out}, indent=1))
    print(f"record: {args.out} ({out['seconds']:.0f} s)")


if __name__ == "__main__":
    main()
