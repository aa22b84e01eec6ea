"""Benchmark of the validation selection and of the rollout-aware refinement.

For each dataset given: the wall time of the whole selection of ``symrom
reproduce`` (its grid, the paper's implied RMSE as the reference when the
dataset has a Table 2 row, 2 worker processes), and the wall time of one
refinement of the chosen candidate on its own (median of ``--runs``), with the
number of its active terms. Compilation is done once before timing (a warm-up
refinement of a small model). Prints a Markdown table and writes JSON.

    python benchmarks/bench_selection.py go1_sim=RUN/data/go1_sim.h5 a1_sim=RUN/data/a1_sim.h5 \\
        --out benchmarks/results/selection.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path

from provenance import provenance

from symrom.data.io import read_dataset
from symrom.experiments.reproduce import ExperimentSpec, ReproduceConfig
from symrom.experiments.select import select
from symrom.learn.training import train


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("datasets", nargs="+", help="NAME=PATH; NAME picks the grid of reproduce (go1_sim, a1_sim)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3, help="repeats of the lone refinement")
    ap.add_argument("--out", type=Path, default=Path("benchmarks/results/selection.json"))
    args = ap.parse_args()
    rc = replace(ReproduceConfig(), workers=args.workers)
    results = []
    for item in args.datasets:
        name, path = item.split("=", 1)
        ds = read_dataset(path)
        exp = next((e for e in rc.experiments if e.name == name), ExperimentSpec(name, name, 2))
        cfg = rc.selection_for(exp)
        warm = cfg.train_config("base_position", 2, "poly1+inputs", 0.03, refine=True)
        train(ds, warm)  # compile the kernels (cached on disk afterwards)
        t0 = time.perf_counter()
        sel = select(ds, cfg)
        wall = time.perf_counter() - t0
        r = sel.rows[sel.chosen]
        tc = cfg.train_config(r["encoder"], r["latent_dim"], r["library"], r["threshold"], refine=True)
        times = []
        for _ in range(args.runs):
            t1 = time.perf_counter()
            model = train(ds, tc)
            times.append(time.perf_counter() - t1)
        results.append({"dataset": name, "path": str(path), "train_jumps": int(ds.jumps_in("train").size),
                        "val_jumps": int(ds.jumps_in("val").size), "candidates": len(sel.rows),
                        "selection_wall_s": round(wall, 2),
                        "chosen": {k: r[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine",
                                                     "active_terms", "score")},
                        "refinement_s_median": round(statistics.median(times), 2),
                        "refinement_s": [round(t, 2) for t in times],
                        "refined_terms": int(model.mask.sum())})
    out = {"machine": {"cpus": os.cpu_count(), "python": platform.python_version()},
           "workers": args.workers, "results": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({**provenance(), **out}, indent=1) + "\n")
    print("| dataset | candidates | selection wall time | chosen | refinement of the chosen (median) |")
    print("|---|---|---|---|---|")
    for r in results:
        c = r["chosen"]
        print(f"| {r['dataset']} | {r['candidates']} | {r['selection_wall_s']:.0f} s | {c['encoder']}, l = "
              f"{c['latent_dim']}, {c['library']}, {c['threshold']:g}{', refined' if c['refine'] else ''}; "
              f"{c['active_terms']} terms | {r['refinement_s_median']:.1f} s |")


if __name__ == "__main__":
    main()
