"""Benchmark of one Adam mini-batch step of the paper's gradient training (``symrom.learn.adam``),
with torch's autograd and with the gradients in closed form (``sindy_grad``, ``recon_grads``),
and the update by torch's optimizer and by ``AdamStep``, side by side in one process on one
thread (not a test). The gradients agree to round-off (``tests/test_planted.py`` checks them
against autograd), the two updates to the bit (checked there too).

    python benchmarks/bench_adam_step.py --steps 2000 --out benchmarks/results/adam_step.json
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
from symrom.learn.adam import AdamStep, recon_grads, sindy_grad


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
    f64 = dict(dtype=torch.float64)
    gen = torch.Generator().manual_seed(0)
    N, p, l, n, B = args.rows, args.terms, args.latent_dim, 18, 100
    theta, ddxi = torch.randn(N, p, generator=gen, **f64), torch.randn(N, l, generator=gen, **f64)
    ddq, Wd = torch.randn(N, n, generator=gen, **f64), torch.randn(n, l, generator=gen, **f64)
    q, emask = torch.randn(N, n, generator=gen, **f64), torch.ones(n, **f64)
    batches = [torch.randperm(N, generator=gen)[:B] for _ in range(64)]

    def sindy(kind: str) -> float:
        Xi = torch.zeros((p, l), **f64, requires_grad=kind == "autograd")
        mask = torch.ones((p, l), **f64)
        if kind == "own":  # the closed form's gradient, the update by AdamStep
            own = AdamStep(Xi, 1e-3, torch)
            t = time.perf_counter()
            with torch.no_grad():
                for s in range(args.steps):
                    idx = batches[s % len(batches)]
                    own.step(sindy_grad(theta[idx], ddxi[idx], ddq[idx], Wd, Xi, mask, 1e-4))
            return (time.perf_counter() - t) / args.steps
        opt = torch.optim.Adam([Xi], lr=1e-3)
        t = time.perf_counter()
        for s in range(args.steps):
            idx = batches[s % len(batches)]
            if kind == "autograd":
                z = theta[idx] @ (Xi * mask)
                loss = (((ddxi[idx] - z) ** 2).sum(1).mean() + ((ddq[idx] - z @ Wd.T) ** 2).sum(1).mean()
                        + 1e-4 * (Xi * mask).abs().sum())
                opt.zero_grad()
                loss.backward()
            else:
                with torch.no_grad():
                    Xi.grad = sindy_grad(theta[idx], ddxi[idx], ddq[idx], Wd, Xi, mask, 1e-4)
            opt.step()
        return (time.perf_counter() - t) / args.steps

    def recon(kind: str) -> float:
        shapes = ((l, n), (l,), (n, l), (n,))
        with torch.no_grad():
            if kind in ("flat", "own"):
                flat = torch.randn(2 * l * n + l + n, generator=gen, **f64)
                params = [v.view(s) for v, s in zip(flat.split([l * n, l, n * l, n]), shapes)]
                opt = AdamStep(flat, 1e-3, torch) if kind == "own" else torch.optim.Adam([flat], lr=1e-3)
            else:
                params = [torch.randn(s, generator=gen, **f64) for s in shapes]
                opt = torch.optim.Adam(params, lr=1e-3)
            t = time.perf_counter()
            for s in range(args.steps):
                grads = recon_grads(q[batches[s % len(batches)]], *params, emask)
                if kind == "own":
                    opt.step(torch.cat([g.reshape(-1) for g in grads]))
                    continue
                if kind == "flat":
                    flat.grad = torch.cat([g.reshape(-1) for g in grads])
                else:
                    for par, g in zip(params, grads):
                        par.grad = g
                opt.step()
            return (time.perf_counter() - t) / args.steps

    variants = {"sindy_autograd": lambda: sindy("autograd"), "sindy_closed_form": lambda: sindy("closed"),
                "recon_closed_form_per_tensor": lambda: recon("per_tensor"),
                "recon_closed_form_one_vector": lambda: recon("flat"),
                "sindy_closed_form_adamstep": lambda: sindy("own"),
                "recon_closed_form_one_vector_adamstep": lambda: recon("own")}
    times: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(args.repeats):
        for k, fn in variants.items():
            times[k].append(fn())
    med = {k: statistics.median(v) for k, v in times.items()}
    for k, v in med.items():
        print(f"{k}: {v * 1e3:.3f} ms a step (median of {args.repeats})")
    print(f"step (c): closed form {med['sindy_autograd'] / med['sindy_closed_form']:.2f}x faster than autograd; "
          f"steps (a)-(b): one vector {med['recon_closed_form_per_tensor'] / med['recon_closed_form_one_vector']:.2f}x "
          f"faster than one tensor per array; AdamStep's update instead of torch's optimizer: step (c) "
          f"{med['sindy_closed_form'] / med['sindy_closed_form_adamstep']:.2f}x, steps (a)-(b) "
          f"{med['recon_closed_form_one_vector'] / med['recon_closed_form_one_vector_adamstep']:.2f}x faster")
    if args.out:
        record = {**provenance(), "settings": {k: v for k, v in vars(args).items() if k != "out"} | {"batch": B},
                  "seconds_per_step": {k: [float(x) for x in v] for k, v in times.items()},
                  "median_ms": {k: float(np.round(v * 1e3, 4)) for k, v in med.items()}}
        write_text_atomic(args.out, json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
