"""Refine candidates of a finished SIM selection as the selection refines its picks, and record them.

    python benchmarks/refine_candidate.py RUN a1_sim 109 117 --out benchmarks/results/a1_sim_refined_candidates.json

RUN is a ``symrom reproduce`` (or ``benchmarks/sim_experiment.py``) run directory holding the
experiment's dataset and ``selection/selection.json``. Each ROW of that table (an exact candidate)
is refined with the experiment's selection settings (``ReproduceConfig.selection_for``): under the
soft term budget, pruned to it and, beside that, the refinement before the pruning, each assessed
as the selection assesses its rows (val scores, the checks for use). The record gives, per refined
model, its terms, val score, how many of the paper's Table 2 components it meets on val at each
horizon, and every refusal. The selection itself only refines candidates the physics and
integrator checks do not refuse; this tells what refining a refused one would give.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

from provenance import provenance

from symrom.atomic import write_text_atomic
from symrom.data.io import read_dataset
from symrom.experiments.reproduce import ReproduceConfig
from symrom.experiments.reproduce.config import paper_reference
from symrom.experiments.select import REFERENCE_FLOOR, plan_steps, run_refinement

VERSION = 1


def met(row: dict, reference: dict) -> dict[str, int | None]:
    """Per horizon, how many components with a reference (above ``REFERENCE_FLOOR``) the row's val
    RMSE is at or below; None where the horizon has no RMSE (a diverged val jump)."""
    out = {}
    for h, ref in reference.items():
        rmse = row["horizons"][h]["rmse"]
        out[h] = None if rmse is None else sum(rmse[c] <= v for c, v in ref.items() if v >= REFERENCE_FLOOR)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="run directory (reproduce's layout)")
    ap.add_argument("experiment", help="a SIM experiment of reproduce (a1_sim, go1_sim)")
    ap.add_argument("rows", type=int, nargs="+", help="rows of the experiment's selection.json to refine")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    cfg = ReproduceConfig()
    exp = next((e for e in cfg.experiments if e.name == args.experiment), None)
    if exp is None:
        raise SystemExit(f"unknown experiment {args.experiment!r}; choose from {[e.name for e in cfg.experiments]}")
    sel_cfg = replace(cfg.selection_for(exp), workers=1)
    table = json.loads((args.run / exp.name / "selection" / "selection.json").read_text())
    ds = read_dataset(args.run / "data" / f"{exp.data}.h5")
    steps = plan_steps(ds, sel_cfg.substeps)
    reference = paper_reference(exp.name)
    chosen = table["rows"][table["chosen"]]
    record = {"version": VERSION, "experiment": exp.name, "budget": sel_cfg.budget,
              "chosen": {"row": table["chosen"], "latent_dim": chosen["latent_dim"],
                         "active_terms": chosen["active_terms"], "score": chosen["score"],
                         "met_on_val": met(chosen, reference)}, "refined": []}
    for i in args.rows:
        r = table["rows"][i]
        if r["refine"]:
            raise SystemExit(f"row {i} is already a refinement; name an exact candidate")
        prune = sel_cfg.budget is not None and r["active_terms"] > sel_cfg.budget
        t0 = time.perf_counter()
        out = run_refinement(ds, sel_cfg, steps, r["encoder"], r["latent_dim"], r["library"], r["threshold"], prune)
        seconds = time.perf_counter() - t0
        for m in out:
            entry = {"row": i, "latent_dim": m["latent_dim"], "library": m["library"], "threshold": m["threshold"],
                     "exact_terms": r["active_terms"], "exact_refused": [x["check"] for x in r.get("refused", ())],
                     "pruned": m.get("max_terms") is not None, "active_terms": m["active_terms"],
                     "active_per_phase": m["active_per_phase"], "score": m["score"],
                     "horizon_scores": {h: m["horizons"][h]["score"] for h in reference},
                     "met_on_val": met(m, reference), "refused": m.get("refused", []), "seconds": round(seconds, 1)}
            record["refined"].append(entry)
            print(f"row {i} l={entry['latent_dim']} {'pruned' if entry['pruned'] else 'unpruned'}: "
                  f"{entry['active_terms']} terms, score {entry['score']}, met on val {entry['met_on_val']}, "
                  f"refused: {[x['check'] for x in entry['refused']] or 'none'}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out, json.dumps({**record, **provenance()}, indent=1, allow_nan=False) + "\n")


if __name__ == "__main__":
    main()
