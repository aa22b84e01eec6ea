"""Benchmark of one Adam mini-batch step of the paper's gradient training (``symrom.learn.adam``):
symrom's compiled epochs (``adam_sindy_epoch``, ``adam_recon_epoch``) against the same steps in
torch as the earlier versions ran them (the gradients in closed form, one torch call per
operation, torch.optim.Adam's update), side by side in one process on one thread, on the same
mini-batches of the same random rows (not a test; torch only for the comparison:
``pip install torch==2.13.0``). Both follow Adam on the same losses; their numbers agree to
round-off, not bit for bit (``tests/test_planted.py`` holds the compiled epochs to the losses'
gradients and to Adam's update).

    python benchmarks/bench_adam_step.py --steps 2000 --out benchmarks/results/adam_step_compiled.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
from provenance import provenance

from symrom.atomic import write_text_atomic
from symrom.learn.compiled import adam_recon_epoch, adam_sindy_epoch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=2000, help="mini-batch steps per timing")
    ap.add_argument("--repeats", type=int, default=3, help="timings per variant (interleaved); medians reported")
    ap.add_argument("--rows", type=int, default=44000, help="rows of the training set (SIM Go1's contact phase)")
    ap.add_argument("--terms", type=int, default=30, help="library terms p")
    ap.add_argument("--latent-dim", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()

    import torch

    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    N, p, l, n, B = args.rows, args.terms, args.latent_dim, 18, 100
    theta, ddxi, ddq = rng.normal(size=(N, p)), rng.normal(size=(N, l)), rng.normal(size=(N, n))
    Wd, q, emask = rng.normal(size=(n, l)), rng.normal(size=(N, n)), np.ones(n)
    # every step a fresh batch of random rows, as in an epoch: whole permutations one after another
    order = np.concatenate([rng.permutation(N) for _ in range(-(-args.steps * B // N))])[:args.steps * B]
    t_theta, t_ddxi, t_ddq, t_Wd, t_q = (torch.from_numpy(a) for a in (theta, ddxi, ddq, Wd, q))
    t_order = torch.from_numpy(order)

    def torch_sindy() -> float:
        Xi, mask = torch.zeros((p, l), dtype=torch.float64, requires_grad=True), torch.ones((p, l), dtype=torch.float64)
        opt = torch.optim.Adam([Xi], lr=1e-3)
        t = time.perf_counter()
        with torch.no_grad():
            for s in range(args.steps):
                idx = t_order[s * B:(s + 1) * B]
                th = t_theta[idx]
                Xm = Xi * mask
                z = th @ Xm
                d = ((z - t_ddxi[idx]) + (z @ t_Wd.T - t_ddq[idx]) @ t_Wd) * (2.0 / B)
                Xi.grad = (th.T @ d + 1e-4 * Xm.sign()) * mask
                opt.step()
        return (time.perf_counter() - t) / args.steps

    def torch_recon() -> float:
        flat = torch.zeros(2 * l * n + l + n, dtype=torch.float64, requires_grad=True)
        W_e, B_e, W_d, B_d = (v.view(s) for v, s in zip(flat.split([l * n, l, n * l, n]), ((l, n), (l,), (n, l), (n,))))
        em = torch.from_numpy(emask)
        opt = torch.optim.Adam([flat], lr=1e-3)
        t = time.perf_counter()
        with torch.no_grad():
            for s in range(args.steps):
                qb = t_q[t_order[s * B:(s + 1) * B]]
                h = qb @ (W_e * em).T + B_e
                d = (h @ W_d.T + B_d - qb) * (2.0 / B)
                dh = d @ W_d
                flat.grad = torch.cat([((dh.T @ qb) * em).reshape(-1), dh.sum(0), (d.T @ h).reshape(-1), d.sum(0)])
                opt.step()
        return (time.perf_counter() - t) / args.steps

    rows, M = np.hstack([theta, ddxi + ddq @ Wd]), np.eye(l) + Wd.T @ Wd

    def compiled_sindy() -> float:
        Xi, mask, m, v = np.zeros((p, l)), np.ones((p, l)), np.zeros(p * l), np.zeros(p * l)
        t = time.perf_counter()
        adam_sindy_epoch(rows, M, Xi, mask, order, B, 1e-4, m, v, 0, 1e-3)
        return (time.perf_counter() - t) / args.steps

    def compiled_recon() -> float:
        flat = np.zeros(2 * l * n + l + n)
        m, v = np.zeros(flat.size), np.zeros(flat.size)
        t = time.perf_counter()
        adam_recon_epoch(q, order, B, flat, 0, l, emask, m, v, 0, 1e-3)
        return (time.perf_counter() - t) / args.steps

    compiled_sindy(), compiled_recon()  # numba's compile or its disk cache's load, not timed
    variants = {"sindy_torch": torch_sindy, "sindy_compiled": compiled_sindy,
                "recon_torch": torch_recon, "recon_compiled": compiled_recon}
    times: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(args.repeats):
        for k, fn in variants.items():
            times[k].append(fn())
    med = {k: statistics.median(v) for k, v in times.items()}
    for k, v in med.items():
        print(f"{k}: {v * 1e6:.1f} us a step (median of {args.repeats})")
    print(f"compiled against torch: step (c) {med['sindy_torch'] / med['sindy_compiled']:.1f}x, steps (a)-(b) "
          f"{med['recon_torch'] / med['recon_compiled']:.1f}x faster")
    if args.out:
        record = {**provenance(), "settings": {k: v for k, v in vars(args).items() if k != "out"} | {"batch": B},
                  "seconds_per_step": {k: [float(x) for x in v] for k, v in times.items()},
                  "median_us": {k: float(np.round(v * 1e6, 2)) for k, v in med.items()}}
        write_text_atomic(args.out, json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
