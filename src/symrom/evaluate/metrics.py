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

Drift (``format_version`` 3): a rollout that stays within its latent bound can
still leave the physically possible. Before its divergence (if any), a jump
drifts at the first sample where the predicted base is below the ground (z = 0)
by more than the robot's leg length, or where a predicted base position x, y
(either way) or z (upwards) lies outside the jump's own logged range widened
by a margin: the largest
range of that coordinate over one training jump of the dataset, and at least a
leg length (``drift_limits``). A drifted jump is still scored (up to its
divergence, as any other): its errors are real; ``drifted_jumps`` and
``drifted`` (jump, time in s, the component, its predicted value and the limit
it passed) report it beside the divergences. A robot without a description
(planted data) has no leg length: only the travel rule applies, its margin the
training range alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from symrom.data.dataset import Dataset
from symrom.evaluate.records import Metrics
from symrom.names import BASE_POS, Q_NAMES
from symrom.robots import RobotDescriptionError
from symrom.robots.stance import leg_length
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


METRICS_VERSION = 3
# The base coordinates the drift rules watch, in q's order.
DRIFT_COMPONENTS = tuple(Q_NAMES[BASE_POS])  # x, y, z


@dataclass(frozen=True)
class DriftLimits:
    """What a rollout may not do without being flagged as drifted (module docstring).

    leg_length: m (None for a robot without a description: no ground rule); margin:
    per base coordinate (x, y, z), m beyond a jump's logged range.
    """

    leg_length: float | None
    margin: dict[str, float]

    @classmethod
    def of(cls, ds: Dataset) -> DriftLimits:
        """The limits for rollouts along ``ds``: its robot's leg length and, per base
        coordinate, the largest range over one of its training jumps (all jumps if it has
        none), at least a leg length."""
        try:
            leg = leg_length(ds.robot)
        except RobotDescriptionError:
            leg = None
        jumps = ds.jumps_in("train")
        bounds = ds.jump_bounds()[jumps if jumps.size else np.arange(ds.n_jumps)]
        ranges = np.max([np.ptp(ds.q[a:b, BASE_POS], axis=0) for a, b in bounds], axis=0)
        return cls(leg, {c: float(max(r, leg or 0.0)) for c, r in zip(DRIFT_COMPONENTS, ranges)})

    def to_dict(self) -> dict:
        return {"leg_length": self.leg_length, "margin": dict(self.margin)}


def drift_events(ds: Dataset, ro: Rollout, limits: DriftLimits) -> list[dict]:
    """Per drifted jump of ``ro``: ``{"jump", "t" (s), "component", "value", "limit"}`` at
    its first sample (before any divergence) that breaks ``limits``; value and limit in m.
    Components the rollout does not predict are not checked."""
    comps = ro.components or Q_NAMES
    watched = [(c, comps.index(c), Q_NAMES.index(c)) for c in DRIFT_COMPONENTS if c in comps]
    bounds, events = ds.jump_bounds(), []
    for i, j in enumerate(ro.jumps):
        a, b = bounds[j]
        n = b - a if not ro.diverged[i] else int(ro.diverged_at[i])
        first = None  # (sample, component, value, limit)
        for c, col, qcol in watched:
            pred, true = ro.q_pred[i][:n, col], ds.q[a:b, qcol]
            lo, hi = true.min() - limits.margin[c], true.max() + limits.margin[c]
            if c == "z" and limits.leg_length is not None:
                lo = -limits.leg_length  # downwards the ground decides (z = 0), not the data's range
            for k in np.flatnonzero((pred < lo) | (pred > hi))[:1]:
                if first is None or k < first[0]:
                    v = float(pred[k])
                    first = (int(k), c, v, float(lo if v < lo else hi))
        if first is not None:
            k, c, v, lim = first
            events.append({"jump": int(j), "t": round(k * ro.dt, 6), "component": c,
                           "value": round(v, 6), "limit": round(lim, 6)})
    return events


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


def horizon_metrics(ds: Dataset, ro: Rollout, limits: DriftLimits | None = None) -> dict:
    """One horizon of ``metrics.json``: diverged jumps (count, and each with the time it left
    its bound, s), drifted jumps (count, and each with the time and the limit it passed;
    ``limits`` default ``DriftLimits.of(ds)``), the split's samples and how many were
    scored, the component stats."""
    err = rollout_errors(ds, ro)
    drifted = drift_events(ds, ro, DriftLimits.of(ds) if limits is None else limits)
    return {"diverged_jumps": int(ro.diverged.sum()), "diverged": ro.divergence_times(),
            "drifted_jumps": len(drifted), "drifted": drifted,
            "samples": int(sum(p.shape[0] for p in ro.q_pred)), "scored_samples": int(err.shape[0]),
            "components": component_stats(err, ro.components or Q_NAMES)}


def horizons(resets=None) -> tuple[float | None, ...]:
    """The horizons of an evaluation: the full jump (None), then each reset period of
    ``resets`` (s; default 0.1) in increasing order, each checked to be a positive number."""
    import math

    for r in resets or ():
        if not (math.isfinite(r) and r > 0):
            raise ValueError(f"resets={r:g}: a reset period must be a positive number of seconds")
    return (None, *sorted(set(resets or (0.1,))))


def evaluate_model(model: Rollable, ds: Dataset, split: str = "test", resets: tuple[float | None, ...] = (None, 0.1),
             options: RolloutOptions = RolloutOptions(), model_name: str = "", data_name: str = "",
             progress: Callable[[int, int], None] | None = None,
             phases: str = "logged") -> tuple[Metrics, dict[str, Rollout]]:
    """Roll out every jump of ``split`` at each horizon; the metrics (``Metrics``, what
    ``metrics.json`` holds: ``to_dict``) and the rollouts by horizon key.

    ``progress(done, total)`` counts rolled-out jumps over all horizons (total: jumps x
    horizons), whichever integrator reports them. ``phases``: ``logged`` (the logged phase
    sequence) or ``predicted`` (the learned model's guards, ``symrom.evaluate.switching``,
    rk4 only; the metrics then hold ``switching``: the switching-time errors per transition
    over the full horizon).
    """
    from symrom.evaluate.switching import PHASE_SOURCES, predicted_rollout, switching_errors

    if phases not in PHASE_SOURCES:
        raise ValueError(f"phases must be one of {PHASE_SOURCES}, got {phases!r}")
    if phases == "predicted":
        if getattr(model, "guards", None) is None:
            raise ValueError("predicted phases need a model with contact guards (model file format 4, "
                             "trained with this symrom); this model has none")
        if options.method != "rk4":
            raise ValueError(f"predicted phases are rolled out with rk4, not {options.method!r} "
                             "(integrator='rk4')")
    jumps = ds.jumps_in(split)
    if jumps.size == 0:
        raise ValueError(f"the dataset has no {split!r} jumps")
    horizons, rollouts, full = {}, {}, None
    limits = DriftLimits.of(ds)
    total = len(resets) * int(jumps.size)
    for h, reset in enumerate(resets):
        key = horizon_key(reset)
        tick = None if progress is None else (
            lambda i, n, before=h * int(jumps.size): progress(before + i, total))
        if phases == "predicted":
            ro, predicted = predicted_rollout(model, ds, jumps, replace(options, reset=reset), tick)
            if reset is None:
                full = ro, predicted
        else:
            ro = rollout(model, ds, jumps, replace(options, reset=reset), tick)
        rollouts[key] = ro
        horizons[key] = horizon_metrics(ds, ro, limits)
    metrics = {"format_version": METRICS_VERSION, "model": model_name, "data": data_name, "split": split,
               "n_jumps": int(jumps.size), "integrator": options.method, "drift_limits": limits.to_dict(),
               "phases": phases, "horizons": horizons}
    if phases == "predicted":  # switching times from the full horizon, rolled out for them if not asked
        ro, predicted = full or predicted_rollout(model, ds, jumps, replace(options, reset=None))
        metrics["switching"] = switching_errors(model, ds, jumps, predicted, np.where(ro.diverged, ro.diverged_at, -1))
    return Metrics.from_dict(metrics), rollouts
