"""One SIM experiment of ``symrom reproduce`` on its own, and the record of its result.

    python benchmarks/sim_experiment.py a1_sim go1_sim --run runs/compact --max-terms 60 --workers 1 \\
        --out benchmarks/results/reproduce_summary.json

Runs into ``--run`` what ``symrom reproduce`` runs for the experiment, with the same
functions and settings (``ReproduceConfig``: the dataset's spec and seed, the validation
selection (with ``--max-terms``, as ``reproduce --max-terms``), the evaluation on the test split,
the paper's defaults and the baselines), each step skipped when its output exists, as ``reproduce`` skips it: on a
finished ``reproduce`` run directory it only reads. Then it writes, per experiment, the
facts docs/results.md reports (``tests/test_reproduce_summary.py`` tests ``record``): the selected settings, the
active terms, the test RMSE of the paper's Table 2 components beside the paper's implied
RMSE, how many are at or below it and the diverged test jumps, per horizon. Experiments
already in ``--out`` and not run now are kept.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from provenance import provenance

from symrom.atomic import write_text_atomic
from symrom.evaluate.paper import at_or_below_paper, paper_rmse
from symrom.experiments.reproduce import ReproduceConfig, ensure_dataset, run_learned
from symrom.names import TABLE2_COMPONENTS

VERSION = 1


def record(name: str, entry: dict, selection: dict) -> dict:
    """The facts of one experiment's summary entry (``reproduce.run_learned``) and its
    selection table: settings, active terms and, per horizon, the Table 2 comparison."""
    horizons = {}
    for h, hm in entry["metrics"]["horizons"].items():
        comps = hm["components"]
        rmse = {c: comps[c]["rmse"] for c in TABLE2_COMPONENTS if c in comps}
        horizons[h] = {"diverged_jumps": hm["diverged_jumps"], "drifted_jumps": hm.get("drifted_jumps"),
                       "jumps": entry["metrics"].get("n_jumps"), "rmse": rmse,
                       "paper_rmse": paper_rmse(name, h), "at_or_below_paper": at_or_below_paper(name, h, rmse)}
    chosen = selection["rows"][selection["chosen"]]
    return {"config": {**entry["config"], "max_terms": chosen.get("max_terms")},
            "active_terms": sum(entry["active_terms"].values()), "active_per_phase": entry["active_terms"],
            "selection_seconds": selection.get("seconds"), "candidates": len(selection["rows"]),
            "selection_rule": selection.get("rule"), "selection_notes": selection.get("notes", []),
            "horizons": horizons}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("experiments", nargs="+", help="names of reproduce's SIM experiments (go1_sim, a1_sim)")
    ap.add_argument("--run", type=Path, required=True, help="run directory (reproduce's layout)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--max-terms", type=int, default=None, help="term budget of the selection (reproduce --max-terms)")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/reproduce_summary.json"))
    args = ap.parse_args()
    cfg = replace(ReproduceConfig(), workers=args.workers)
    if args.max_terms is not None:
        cfg = replace(cfg, selection=replace(cfg.selection, max_terms=args.max_terms))
    known = {e.name: e for e in cfg.experiments}
    unknown = [n for n in args.experiments if n not in known]
    if unknown:
        sys.exit(f"unknown experiment(s) {unknown}; choose from {sorted(known)}")
    out = json.loads(args.out.read_text()) if args.out.is_file() else {"version": VERSION, "experiments": {}}
    say = lambda msg, transient=False: print(msg, flush=True)  # noqa: E731
    for name in args.experiments:
        exp = known[name]
        spec = next(s for s in cfg.datasets if s.name == exp.data)
        data = ensure_dataset(args.run, spec, cfg, say)
        entry = run_learned(args.run, exp, data, cfg, say)
        selection = json.loads((args.run / name / "selection" / "selection.json").read_text())
        line = record(name, entry, selection)
        out["experiments"][name] = {**line, "command": " ".join(["python", *sys.argv])}
        print(f"{name}: {line['active_terms']} active terms; " + "; ".join(
            f"{h}: {len(v['at_or_below_paper'] or [])}/12 at or below the paper, {v['diverged_jumps']} diverged"
            for h, v in line["horizons"].items()))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out, json.dumps({**out, **provenance()}, indent=1, allow_nan=False) + "\n")


if __name__ == "__main__":
    main()
