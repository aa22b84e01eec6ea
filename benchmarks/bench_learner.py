"""Benchmark of the learner on a planted dataset (120 jumps x 800 samples, l = 2, p = 1).

Reports medians over repeated runs, measured side by side in one process:
training time of the ``exact`` vs the ``adam`` solver (the paper's settings:
501 epochs, batch 100, lr 1e-3), and rollout time of LSODA vs batch RK4 over
all jumps, full horizon and 0.1 s resets; plus the accuracy each reaches on
the test split. Prints a Markdown table and writes JSON next to it.

    python benchmarks/bench_learner.py --out benchmarks/results/learner.json
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

import numpy as np
from provenance import provenance

from symrom.evaluate.metrics import evaluate_model
from symrom.learn.training import AdamConfig, TrainConfig, train
from symrom.rollout.integrate import RolloutOptions, rollout
from symrom.testing import make_planted_dataset


def timed(fn, runs: int) -> tuple[float, list[float], object]:
    times, result = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, result


def worst_nmae(model, ds) -> dict[str, float]:
    """Per horizon, the largest MAE / spread over the 18 components on the test split."""
    metrics, _ = evaluate_model(model, ds, "test", options=RolloutOptions(method="rk4"))
    spread = np.ptp(ds.q[ds.rows_of("test")], axis=0)
    out = {}
    for h, v in metrics.horizons.items():
        mae = np.array([c.mae for c in v.components.values()])
        out[h] = float(np.max(mae / spread)) if mae.size else float("inf")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jumps", type=int, default=120)
    ap.add_argument("--samples", type=int, default=800)
    ap.add_argument("--exact-runs", type=int, default=7)
    ap.add_argument("--adam-runs", type=int, default=3)
    ap.add_argument("--adam-epochs", type=int, default=501)
    ap.add_argument("--rollout-runs", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()

    ds, _ = make_planted_dataset(args.jumps, args.samples, embedding="block", noise=1e-4, seed=0)
    # Paper split proportions on the planted set are irrelevant for timing; train on 'train'.
    res: dict = {"dataset": {"jumps": args.jumps, "samples_per_jump": args.samples,
                             "train_rows": int(ds.rows_of("train").sum())},
                 "machine": {"python": platform.python_version(), "cpu": platform.processor() or platform.machine()}}
    t_exact, all_exact, m_exact = timed(lambda: train(ds, TrainConfig()), args.exact_runs)
    res["train_exact_s"] = {"median": t_exact, "runs": all_exact, "test_worst_nmae": worst_nmae(m_exact, ds)}
    print(f"exact: median {t_exact:.3f} s over {args.exact_runs} runs", flush=True)
    if args.adam_runs > 0:
        cfg = TrainConfig(solver="adam", adam=AdamConfig(epochs=args.adam_epochs))
        t_adam, all_adam, m_adam = timed(lambda: train(ds, cfg), args.adam_runs)
        res["train_adam_s"] = {"median": t_adam, "runs": all_adam, "epochs": args.adam_epochs,
                               "test_worst_nmae": worst_nmae(m_adam, ds)}
        res["train_speedup_exact_vs_adam"] = t_adam / t_exact
        print(f"adam: median {t_adam:.1f} s over {args.adam_runs} runs", flush=True)
    jumps = np.arange(ds.n_jumps)
    for reset in (None, 0.1):
        key = "full" if reset is None else "0.1"
        t_l, all_l, _ = timed(lambda: rollout(m_exact, ds, jumps, RolloutOptions("lsoda", reset)), args.rollout_runs)
        t_r, all_r, _ = timed(lambda: rollout(m_exact, ds, jumps, RolloutOptions("rk4", reset)), args.rollout_runs)
        res[f"rollout_{key}"] = {"lsoda_median_s": t_l, "rk4_median_s": t_r, "lsoda_runs": all_l,
                                 "rk4_runs": all_r, "speedup": t_l / t_r,
                                 "rk4_us_per_batch_step": t_r / args.samples * 1e6,
                                 "simulated_s": args.jumps * args.samples * ds.dt}
        print(f"rollout {key}: lsoda {t_l:.2f} s, rk4 {t_r:.3f} s", flush=True)

    rows = [("training, exact", f"{t_exact:.3f} s", f"{args.exact_runs}",
             f"{res['train_exact_s']['test_worst_nmae']['full']:.2%}")]
    if "train_adam_s" in res:
        rows.append((f"training, adam ({args.adam_epochs} epochs)", f"{res['train_adam_s']['median']:.1f} s",
                     f"{args.adam_runs}", f"{res['train_adam_s']['test_worst_nmae']['full']:.2%}"))
    for key in ("full", "0.1"):
        r = res[f"rollout_{key}"]
        rows.append((f"rollout {key}, lsoda ({args.jumps} jumps)", f"{r['lsoda_median_s']:.2f} s",
                     f"{args.rollout_runs}", ""))
        rows.append((f"rollout {key}, rk4 batch ({args.jumps} jumps)", f"{r['rk4_median_s']:.3f} s",
                     f"{args.rollout_runs}", ""))
    print("\n| task | median time | runs | worst test nMAE (full horizon) |\n|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    if "train_adam_s" in res:
        print(f"\nexact is {res['train_speedup_exact_vs_adam']:.0f}x faster than adam; "
              f"rk4 batch is {res['rollout_full']['speedup']:.0f}x faster than lsoda (full horizon)")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({**provenance(), **res}, indent=1))


if __name__ == "__main__":
    main()
