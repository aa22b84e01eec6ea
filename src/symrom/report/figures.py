"""The report's figures, as PNG files written atomically (matplotlib, Agg backend).

- ``encoder_heatmap``: W_e^T (18 x l), the paper's encoder figures (l = 2, 18);
- ``jump_figure``: truth vs rollouts of one jump (delegates to
  ``evaluate.plots.plot_jump``), the paper's joint-angle / CoM-pose figures;
- ``com_figure``: CoM x and z of one jump, truth vs learned vs the baselines;
- ``tradeoff_figure``: accuracy vs complexity over latent dimensions;
- ``selection_figure``: validation score vs active terms of a selection's candidates.
- ``horizon_figure``: RMSE per component and horizon beside the reconstruction floor.

Every function takes plain arrays (or the evaluation objects it plots) and a
path, and returns the path written.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from symrom.atomic import write_with
from symrom.data.dataset import Dataset
from symrom.evaluate.plots import plot_jump, shade_phases
from symrom.names import Q_NAMES, TABLE2_COMPONENTS
from symrom.rollout.integrate import Rollout

DPI = 110


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: str | os.PathLike) -> Path:
    plt = _pyplot()
    write_with(path, lambda tmp: fig.savefig(tmp, dpi=DPI, format="png"))
    plt.close(fig)
    return Path(path)


def encoder_heatmap(W_e: np.ndarray, path: str | os.PathLike, title: str = "",
                    row_names: tuple[str, ...] = Q_NAMES) -> Path:
    """Heatmap of W_e^T: rows the 18 configuration components, columns latents 1..l.

    W_e (l, 18), dimensionless for a unit-norm encoder (latent per unit of q).
    Diverging colormap centred at 0; cell values printed when l <= 6.
    """
    plt = _pyplot()
    W = np.asarray(W_e, dtype=float)
    l = W.shape[0]
    if W.shape[1] != len(row_names):
        raise ValueError(f"W_e has {W.shape[1]} columns, expected {len(row_names)}")
    vmax = float(np.abs(W).max()) or 1.0
    fig, ax = plt.subplots(figsize=(max(3.6, 1.6 + 0.42 * l), 6.2))
    im = ax.imshow(W.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, aspect="auto")
    ax.set_yticks(range(len(row_names)), row_names, fontsize=8)
    ax.set_xticks(range(l), [str(i + 1) for i in range(l)], fontsize=8)
    ax.set_xlabel("latent dimension")
    ax.set_ylabel("configuration component")
    if l <= 6:
        for i in range(l):
            for j in range(len(row_names)):
                v = W[i, j]
                ax.text(i, j, f"{v:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if abs(v) > 0.6 * vmax else "black")
    fig.colorbar(im, ax=ax, label="encoder weight")
    ax.set_title(title or rf"Encoder weights $W_e^T$ (l = {l})", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def jump_figure(ds: Dataset, rollouts: dict[str, Rollout], jump: int, path: str | os.PathLike,
                title: str = "") -> Path:
    """True vs predicted fl/rr joint angles and CoM pose of ``jump`` (index into ``ds``)
    for each horizon in ``rollouts`` (``full``, ``0.1``), phases shaded."""
    plot_jump(ds, rollouts, jump, path, title=title)
    return Path(path)


def com_figure(t: np.ndarray, true: np.ndarray, learned: np.ndarray, baselines: dict[str, np.ndarray],
               phase: np.ndarray, phase_names: list[str], path: str | os.PathLike, title: str = "") -> Path:
    """CoM x and z of one jump: truth, the learned model and each baseline (full horizon).

    t (n,) s; true, learned and each baseline (n, 3) CoM x, y, z in m, baselines by
    label; phase (n,) indices into ``phase_names``. NaN rows (a diverged rollout) are gaps.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.4), sharex=True)
    seen: set = set()
    for ax, (c, name) in zip(axes, ((0, "x"), (2, "z"))):
        shade_phases(ax, t, np.asarray(phase), phase_names, seen)
        ax.plot(t, true[:, c], color="k", lw=1.8, label="true")
        ax.plot(t, learned[:, c], color="C3", lw=1.3, label="learned (symbolic)")
        for i, (label, pred) in enumerate(baselines.items()):
            ax.plot(t, pred[:, c], color=f"C{i}", lw=1.2, ls=("--", ":", "-.")[i % 3], label=label)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"CoM {name} [m]")
        ax.grid(alpha=0.3)
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 5), fontsize=9, frameon=False)
    fig.suptitle(title or "CoM position: learned model vs baselines (full horizon)", fontsize=11)
    fig.tight_layout(rect=(0, 0.1, 1, 0.95))
    return _save(fig, path)


def baseline_jump_com(ds: Dataset, jump: int, params: dict, method: str = "lsoda") -> np.ndarray | None:
    """The CoM x, y, z (n, 3), m, a baseline described by ``params`` (params.json) predicts
    for ``jump`` (index into ``ds``), full horizon; NaN rows after a divergence; None if
    the parameters describe no known baseline."""
    from symrom.baselines import from_params
    from symrom.rollout.integrate import RolloutOptions, rollout

    model = from_params(params)
    return None if model is None else rollout(model, ds, [int(jump)], RolloutOptions(method=method)).q_pred[0]


def sweep_stats(sweep: dict) -> dict[str, np.ndarray]:
    """Per latent dimension (D,): mean and std over seeds of E_dec and |Xi|, L_mod.

    ``sweep``: the sweep.json layout, ``E_dec`` and ``active_terms`` (D, S) lists
    (null for a failed seed). L_mod is taken from the file when given, else
    computed as 2 E_dec + 2 lambda log|Xi| on the seed means.
    """
    dims = np.asarray(sweep["latent_dims"], dtype=int)

    def table(key):
        rows = [[np.nan if v is None else float(v) for v in np.atleast_1d(r)] for r in sweep[key]]
        width = max(len(r) for r in rows)
        return np.array([r + [np.nan] * (width - len(r)) for r in rows])

    E, A = table("E_dec"), table("active_terms")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN row (every seed failed) stays NaN
        out = {"dims": dims, "E_mean": np.nanmean(E, 1), "E_std": np.nanstd(E, 1),
               "A_mean": np.nanmean(A, 1), "A_std": np.nanstd(A, 1)}
    if sweep.get("L_mod") is not None:
        out["L_mod"] = np.array([np.nan if v is None else float(v) for v in sweep["L_mod"]])
    else:
        lam = float(sweep.get("lambda", 1e-3))
        out["L_mod"] = 2 * out["E_mean"] + 2 * lam * np.log(np.maximum(out["A_mean"], 1.0))
    return out


def best_dim(sweep: dict) -> int:
    """The latent dimension named best by the sweep, else the argmin of L_mod."""
    if sweep.get("best_latent_dim") is not None:
        return int(sweep["best_latent_dim"])
    s = sweep_stats(sweep)
    return int(s["dims"][int(np.nanargmin(s["L_mod"]))])


def tradeoff_figure(sweep: dict, path: str | os.PathLike, title: str = "") -> Path:
    """Accuracy vs complexity over latent dimensions, one panel per quantity (one y-axis each).

    (a) E_dec, the reconstruction error sum_c (q_c - q_rec,c)^2 averaged over the training
    rows (joint angles and orientation in rad, positions in m: rad^2 and m^2 summed), with
    error bars over seeds, log scale; (b) active coefficients |Xi| with error bars;
    (c) L_mod, its best dimension starred. The best dimension is marked in every panel.
    """
    plt = _pyplot()
    s = sweep_stats(sweep)
    dims, best = s["dims"], best_dim(sweep)
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.6), sharex=True)
    ax_e, ax_a, ax_l = axes
    ax_e.errorbar(dims, s["E_mean"], yerr=s["E_std"], color="C0", marker="o", ms=4, capsize=3)
    ax_e.set_yscale("log")
    ax_e.set_title(r"(a) reconstruction error $\mathcal{E}_{dec}$", fontsize=10)
    ax_e.set_ylabel(r"mean $\sum_c (q_c-\hat q_c)^2$ (rad$^2$ + m$^2$)")
    ax_a.errorbar(dims, s["A_mean"], yerr=s["A_std"], color="C1", marker="s", ms=4, capsize=3)
    ax_a.set_title(r"(b) active coefficients $|\Xi|$", fontsize=10)
    ax_a.set_ylabel("terms (all phases)")
    ax_l.plot(dims, s["L_mod"], color="C3", lw=1.8, marker="^", ms=4)
    ax_l.set_title(r"(c) combined loss $\mathcal{L}_{mod}$", fontsize=10)
    ax_l.set_ylabel(r"$2\,\mathcal{E}_{dec} + 2\lambda \log|\Xi|$")
    if best in dims:
        i = int(np.flatnonzero(dims == best)[0])
        for ax in axes:
            ax.axvline(best, color="C3", ls=":", lw=1.2)
        ax_l.plot([best], [s["L_mod"][i]], marker="*", ms=14, color="C3", ls="none", label=f"best l = {best}")
        ax_l.legend(fontsize=8, frameon=False)
    for ax in axes:
        ax.set_xticks(dims)
        ax.set_xlabel("latent dimension l")
        ax.grid(alpha=0.3)
    fig.suptitle(title or "Accuracy vs complexity over latent dimensions", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)


# A horizon panel keeps its minor ticks (labelled where no power of ten falls inside) only when its
# values span less than this ratio.
MINOR_TICKS_BELOW = 100.0

# Table 2's components by unit, one panel each.
HORIZON_PANELS = (("joint angles [rad]", TABLE2_COMPONENTS[:6]), ("CoM position [m]", TABLE2_COMPONENTS[6:9]),
                  ("orientation [rad]", TABLE2_COMPONENTS[9:]))
HORIZON_STYLES = (dict(color="C3", marker="o", mfc="none"), dict(color="C0", marker="s"),
                  dict(color="C2", marker="D"), dict(color="C4", marker="^"))


def horizon_figure(rmse: dict[str, dict[str, float | None]], floor: dict[str, float] | None,
                   path: str | os.PathLike, title: str = "",
                   paper: dict[str, dict[str, float]] | None = None) -> Path:
    """RMSE per Table-2 component for each horizon (``{label: {component: rmse}}``) beside
    the reconstruction floor (decode-encode of the true configurations; a rollout with
    exact latent dynamics errs by it) and, where given, the paper's implied RMSE per horizon
    (``{label: {component: rmse}}``, the labels of ``rmse``: drawn as a short bar in the
    horizon's colour, beside its point); log scale, one panel per unit (rad or m)."""
    plt = _pyplot()
    from matplotlib.ticker import NullLocator

    fig, axes = plt.subplots(1, 3, figsize=(11, 3.4), gridspec_kw={"width_ratios": [6, 3, 3]})
    for ax, (unit, comps) in zip(axes, HORIZON_PANELS):
        x = np.arange(len(comps))
        if floor is not None:
            ax.plot(x, [floor[c] for c in comps], color="k", ls="none", marker="_", ms=24, mew=2,
                    label="reconstruction floor", zorder=2)
        for k, (label, vals) in enumerate(rmse.items()):
            y = [np.nan if vals.get(c) is None else vals[c] for c in comps]
            style = HORIZON_STYLES[k % len(HORIZON_STYLES)]
            dx = x + 0.12 * (k - (len(rmse) - 1) / 2)
            ax.plot(dx, y, ls="none", ms=6, label=f"ours, {label}", zorder=3, **style)
            if paper and label in paper:
                ax.plot(dx, [paper[label].get(c, np.nan) for c in comps], ls="none", marker="_", ms=11, mew=2.5,
                        color=style["color"], alpha=0.75, label=f"paper, {label}", zorder=4)
        ax.set_xticks(x, comps)
        ax.set_yscale("log")
        shown = np.concatenate([np.asarray(ln.get_ydata(), dtype=float) for ln in ax.get_lines()] or [[]])
        shown = shown[np.isfinite(shown) & (shown > 0)]  # what the panel draws
        if shown.size and shown.max() >= MINOR_TICKS_BELOW * shown.min():
            # Over many decades the powers of ten label the panel, and the minor ticks, each a
            # gridline, would only crowd it (and take half of the figure's drawing time).
            ax.yaxis.set_minor_locator(NullLocator())
        ax.set_title(unit, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("RMSE (unit of the panel)")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.suptitle(title or "Error per component and horizon, and the reconstruction floor", fontsize=11)
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    return _save(fig, path)


def selection_figure(rows: list[dict], chosen: int | None, path: str | os.PathLike, title: str = "",
                     yardstick: str = "spread") -> Path:
    """Validation score (lower is better) vs active terms of every candidate row of a
    selection table (``selection.json``): a colour per encoder, open markers for the
    refined ones, rejected candidates (a diverged validation jump) at the top with
    their 0.1 s score, the chosen one starred; ``yardstick`` names what the score divides each
    component's RMSE by (the y label: the spread, or the paper's implied RMSE)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.2))
    encoders = list(dict.fromkeys(r["encoder"] for r in rows))
    ok = [r["score"] for r in rows if r["score"] is not None]
    top = 1.15 * max(ok) if ok else 1.0
    for i, enc in enumerate(encoders):
        for refined in (False, True):
            pick = [r for r in rows if r["encoder"] == enc and r["refine"] == refined]
            if not pick:
                continue
            x = [r["active_terms"] for r in pick]
            y = [r["score"] if r["score"] is not None else top for r in pick]
            ax.scatter(x, y, s=28 if not refined else 60, marker="o" if not refined else "D",
                       facecolors="none" if refined else f"C{i}", edgecolors=f"C{i}",
                       label=f"{enc}{' (refined)' if refined else ''}")
    if chosen is not None:
        r = rows[chosen]
        ax.plot([r["active_terms"]], [r["score"]], marker="*", ms=18, color="k", ls="none", label="chosen")
    if ok:
        ax.axhline(top, color="0.6", ls=":", lw=1)
        ax.text(ax.get_xlim()[1], top, " rejected (diverged)", va="bottom", ha="right", fontsize=8, color="0.4")
    ax.set_xlabel("active terms (all phases)")
    ax.set_ylabel(f"validation score (mean RMSE / {yardstick})")
    ax.set_xscale("log")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2, frameon=False)
    ax.set_title(title or "Selection: accuracy vs complexity", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)
