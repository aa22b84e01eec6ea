"""Rollouts with predicted phases and their switching-time errors (``evaluate --phases predicted``).

With ``phases="logged"`` a rollout follows the logged phase sequence; with
``predicted`` the model's guards decide it (``HybridModel.predict_path``) from
the logged start state and inputs, along the motion's phase sequence. With
periodic resets the state and the phase are set to the truth at each reset, the
time already spent in that phase counted from the logged stay's start, and the
place in the phase sequence from the logged switches before it. A jump that leaves its bound stays
diverged, as in ``rollout``.

Switching-time errors compare, per transition (``contact->flight``, ...),
the k-th predicted switch of a jump with its k-th logged one (full horizon):
error = predicted - logged time, s. Logged switches without a predicted one
are ``missed``, predicted ones without a logged one ``extra``.
"""

from __future__ import annotations

import numpy as np

from symrom.data.dataset import Dataset
from symrom.model.guards import stage_along
from symrom.rollout.integrate import Rollout, RolloutOptions, reset_mask

PHASE_SOURCES = ("logged", "predicted")


def predicted_rollout(model, ds: Dataset, jumps: np.ndarray, options: RolloutOptions,
                      progress=None) -> tuple[Rollout, list[np.ndarray]]:
    """Rollouts of ``model`` (a ``HybridModel`` with guards) along ``jumps`` of ``ds`` with
    predicted phases; the ``Rollout`` and per jump its phase indices (n_j,)."""
    model.check_data(ds)
    logged = model.phase_index(ds)
    bounds, l = ds.jump_bounds(), model.latent_dim
    seq = model.phase_sequence()
    q_pred, xs, vs, phases, div_at = [], [], [], [], []
    for i, j in enumerate(jumps):
        a, b = bounds[j]
        n = b - a
        starts = list(np.flatnonzero(reset_mask(n, options.reset, ds.dt))) + [n]
        X, V = np.full((n, l), np.nan), np.full((n, l), np.nan)
        ph, d = logged[a:b].copy(), -1
        for s, e in zip(starts[:-1], starts[1:]):
            p0 = int(logged[a + s])
            stay = s - next((k for k in range(s, -1, -1) if logged[a + k] != p0), -1) - 1  # samples already in p0
            p = model.predict_path(ds.q[a + s], ds.dq[a + s], ds.u[a + s:a + e], ds.dt,
                                   phase0=model.phase_names[p0], options=options, dwell0=stay * ds.dt,
                                   stage0=stage_along(seq, logged[a:a + s + 1]))
            X[s:e], V[s:e], ph[s:e] = p.xi, p.dxi, p.phase
            if p.diverged:
                d = s + p.diverged_at
                X[d:], V[d:] = np.nan, np.nan
                break
        xs.append(X)
        vs.append(V)
        phases.append(ph)
        div_at.append(d)
        q_pred.append(model.autoencoder.decode(X))
        if progress:
            progress(i + 1, len(jumps))
    div = np.array(div_at, dtype=int)
    return Rollout(np.asarray(jumps), q_pred, xs, vs, div >= 0, div, tuple(model.components), ds.dt), phases


def _switch_list(phase: np.ndarray, names: list[str]) -> list[tuple[str, int]]:
    cut = np.flatnonzero(np.diff(phase)) + 1
    return [(f"{names[int(phase[k - 1])]}->{names[int(phase[k])]}", int(k)) for k in cut]


def switching_errors(model, ds: Dataset, jumps: np.ndarray, predicted: list[np.ndarray],
                     diverged_at: np.ndarray | None = None) -> dict:
    """Per transition: ``{"logged", "matched", "missed", "extra", "median_abs_s", "p95_abs_s",
    "mean_s", "errors": [{"jump", "logged_t", "predicted_t"}]}``; predicted (per jump, its
    phase indices) from a full-horizon ``predicted_rollout``; a diverged jump's switches
    count up to its divergence (logged ones after it are missed)."""
    logged, bounds, names = model.phase_index(ds), ds.jump_bounds(), list(model.phase_names)
    out: dict[str, dict] = {}
    for i, j in enumerate(jumps):
        a, b = bounds[j]
        stop = b - a if diverged_at is None or diverged_at[i] < 0 else int(diverged_at[i])
        true, pred = _switch_list(logged[a:b], names), _switch_list(predicted[i][:stop], names)
        for key in {t for t, _ in true} | {t for t, _ in pred}:
            rec = out.setdefault(key, {"logged": 0, "matched": 0, "missed": 0, "extra": 0, "errors": []})
            tk, pk = [k for t, k in true if t == key], [k for t, k in pred if t == key]
            rec["logged"] += len(tk)
            rec["missed"] += max(len(tk) - len(pk), 0)
            rec["extra"] += max(len(pk) - len(tk), 0)
            for x, y in zip(tk, pk):
                rec["matched"] += 1
                rec["errors"].append({"jump": int(j), "logged_t": round(x * ds.dt, 6),
                                      "predicted_t": round(y * ds.dt, 6)})
    for rec in out.values():
        e = np.array([r["predicted_t"] - r["logged_t"] for r in rec["errors"]])
        rec["median_abs_s"] = float(np.median(np.abs(e))) if e.size else None
        rec["p95_abs_s"] = float(np.percentile(np.abs(e), 95)) if e.size else None
        rec["mean_s"] = float(e.mean()) if e.size else None
    return dict(sorted(out.items()))


def switching_table(switching: dict) -> str:
    """Markdown: per transition, logged, matched, missed, extra, median and p95 |error| (ms)."""
    lines = ["| transition | logged | matched | missed | extra | median abs error [ms] | p95 abs error [ms] "
             "| mean error [ms] |", "|---|---|---|---|---|---|---|---|"]
    for key, r in switching.items():
        ms = [("-" if r[k] is None else f"{1e3 * r[k]:.1f}") for k in ("median_abs_s", "p95_abs_s", "mean_s")]
        lines.append(f"| {key} | {r['logged']} | {r['matched']} | {r['missed']} | {r['extra']} | "
                     + " | ".join(ms) + " |")
    return "\n".join(lines) + "\n"
