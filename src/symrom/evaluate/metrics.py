"""Error metrics of rollouts, in the layout of ``metrics.json`` (``docs/design.md``).

One implementation for every model that can be rolled out (``Rollable``: the
learned model, the aSLIP, Newton): per configuration component it predicts,
``mean`` and ``std`` of the signed error predicted - true over all scored
samples of the split (the paper's Table 2), ``mae`` and ``rmse``. A diverged
jump still counts: its samples up to the divergence (where the prediction is
still finite and within its bound) are scored, the rest are not; it is counted
in ``diverged_jumps`` and listed in ``diverged`` with the time (s) at which it
left its bound. ``samples`` and ``scored_samples`` say how much of the split
the statistics cover. Files of ``format_version`` 1 (without it) excluded
diverged jumps entirely.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from symrom.data.dataset import Dataset
from symrom.names import Q_NAMES
from symrom.rollout.integrate import Rollout, RolloutOptions, rollout
from symrom.rollout.system import Rollable


def horizon_key(reset: float | None) -> str:
    """``full`` or the reset period as text, e.g. ``0.1``."""
    return "full" if reset is None else f"{reset:g}"


def component_stats(err: np.ndarray, names: tuple[str, ...] | list[str] = Q_NAMES) -> dict:
    """err (N, C) signed errors -> {name: {mean, std, mae, rmse}}."""
    if err.shape[0] == 0:
        return {}
    return {n: {"mean": float(np.mean(e)), "std": float(np.std(e)),
                "mae": float(np.mean(np.abs(e))), "rmse": float(np.sqrt(np.mean(e ** 2)))}
            for n, e in zip(names, err.T)}


METRICS_VERSION = 2


def prediction_errors(ds: Dataset, jumps: np.ndarray, predictions: list[np.ndarray],
                      diverged_at: np.ndarray, columns: slice | list[int] = slice(None)) -> np.ndarray:
    """Signed errors predicted - true (N, C) over ``jumps``, each up to its divergence.

    predictions: per jump (n_j, C), compared with ``ds.q[:, columns]`` of that jump;
    diverged_at (J,): per jump the first sample past its bound (-1: none), where its
    scored samples end.
    """
    bounds = ds.jump_bounds()
    errs = []
    for i, j in enumerate(jumps):
        a, b = bounds[j]
        n = b - a if diverged_at[i] < 0 else int(diverged_at[i])
        errs.append(predictions[i][:n] - ds.q[a:a + n][:, columns])
    return np.concatenate(errs) if errs else np.zeros((0, ds.q[:1, columns].shape[1]))


def rollout_errors(ds: Dataset, ro: Rollout) -> np.ndarray:
    """Signed errors (N, C) of ``ro.components`` over the jumps of ``ro``, each up to its
    divergence."""
    return prediction_errors(ds, ro.jumps, ro.q_pred, np.where(ro.diverged, ro.diverged_at, -1),
                             [Q_NAMES.index(c) for c in ro.components or Q_NAMES])


def reconstruction_floor(model, ds: Dataset, split: str = "test") -> dict[str, float]:
    """Per component, the RMSE of decode(encode(q)) over the split's true configurations.

    A rollout whose latent state were exact would still make this error, so no
    latent dynamics can predict a component better than its floor.
    """
    q = ds.q[ds.rows_of(split)]
    err = model.autoencoder.reconstruct(q) - q
    return {n: float(np.sqrt(np.mean(e ** 2))) for n, e in zip(Q_NAMES, err.T)}


def horizon_metrics(ds: Dataset, ro: Rollout) -> dict:
    """One horizon of ``metrics.json``: diverged jumps (count, and each with the time it left
    its bound, s), the split's samples and how many were scored, the component stats."""
    err = rollout_errors(ds, ro)
    return {"diverged_jumps": int(ro.diverged.sum()), "diverged": ro.divergence_times(),
            "samples": int(sum(p.shape[0] for p in ro.q_pred)), "scored_samples": int(err.shape[0]),
            "components": component_stats(err, ro.components or Q_NAMES)}


def evaluate(model: Rollable, ds: Dataset, split: str = "test", resets: tuple[float | None, ...] = (None, 0.1),
             options: RolloutOptions = RolloutOptions(), model_name: str = "", data_name: str = "",
             progress: Callable[[int, int], None] | None = None) -> tuple[dict, dict[str, Rollout]]:
    """Roll out every jump of ``split`` at each horizon; the metrics dict and the rollouts.

    ``progress(done, total)`` counts rolled-out jumps over all horizons (total: jumps x
    horizons), whichever integrator reports them.
    """
    jumps = ds.jumps_in(split)
    if jumps.size == 0:
        raise ValueError(f"the dataset has no {split!r} jumps")
    horizons, rollouts = {}, {}
    total = len(resets) * int(jumps.size)
    for h, reset in enumerate(resets):
        key = horizon_key(reset)
        tick = None if progress is None else (
            lambda i, n, before=h * int(jumps.size): progress(before + i, total))
        ro = rollout(model, ds, jumps, replace(options, reset=reset), tick)
        rollouts[key] = ro
        horizons[key] = horizon_metrics(ds, ro)
    metrics = {"format_version": METRICS_VERSION, "model": model_name, "data": data_name, "split": split,
               "n_jumps": int(jumps.size), "integrator": options.method, "horizons": horizons}
    return metrics, rollouts
