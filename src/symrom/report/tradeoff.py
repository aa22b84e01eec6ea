"""Renderer of the latent-dimension sweep: encoder heatmaps and accuracy vs complexity.

A sweep entry's ``result`` is its sweep.json, ``encoders`` an optional folder of
``W_e_l<k>.json``; ``of`` names the learned experiment whose data it swept.
"""

from __future__ import annotations

import json

import numpy as np

from symrom.evaluate.paper import PAPER_BEST_DIMS, PAPER_LAMBDA
from symrom.evaluate.records import ManifestEntry
from symrom.names import N_Q
from symrom.report import figures
from symrom.report.context import Context
from symrom.report.document import Figure, Para, Table
from symrom.report.format import fmt
from symrom.report.run import READ_ERRORS, Run

HEATMAP_DIMS = (2, 18)


def encoder_weights(run: Run, entry: ManifestEntry, l: int) -> tuple[np.ndarray, str] | None:
    """W_e (l, 18) for the heatmap and where it came from: the sweep's encoders, the model
    of the swept experiment if of that dimension, or step (a) of the exact solver on its
    training data."""
    folder = run.path(entry, "encoders") if "encoders" in entry.files else None
    p = None if folder is None else folder / f"W_e_l{l}.json"
    if p is not None and p.is_file():
        try:
            W = np.asarray(json.loads(p.read_text())["W_e"], dtype=float)
        except (*READ_ERRORS, KeyError, TypeError) as e:
            run.note(f"{p.name}: unreadable ({e}); the heatmap is computed instead")
        else:
            if W.shape == (l, N_Q):
                return W, f"{entry.files['encoders']}/{p.name}"
    swept = run.entry(entry.of)
    if swept is None:
        return None
    model = run.model(swept) if "model" in swept.files else None
    if model is not None and model.latent_dim == l:
        return model.autoencoder.W_e, swept.files["model"]
    ds = run.dataset(swept)
    if ds is None:
        return None
    from symrom.learn.training import contact_rows, principal_encoder

    rows = contact_rows(ds, ds.rows_of("train"), "contact")
    return principal_encoder(ds.q[rows], l), f"exact solver step (a) on {swept.name} training data"


def sweep_rows(sweep: dict) -> list[list[str]]:
    s = figures.sweep_stats(sweep)
    best = figures.best_dim(sweep)
    return [[f"{d}{' (best)' if d == best else ''}", f"{fmt(s['E_mean'][i])}±{fmt(s['E_std'][i])}",
             f"{s['A_mean'][i]:.1f}±{s['A_std'][i]:.1f}", fmt(s["L_mod"][i])]
            for i, d in enumerate(s["dims"])]


def sweep_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    for e in entries:
        blocks.append(f"Encoder weights ({e.of or e.name})")
        for l in HEATMAP_DIMS:
            got = encoder_weights(run, e, l)
            if got is None:
                blocks.append(Para(f"W_e for l = {l}: no encoder or data of {e.of!r}; heatmap skipped.", note=True))
                continue
            W, source = got
            path = ctx.draw(figures.encoder_heatmap, W, ctx.fig_dir / f"encoder_{ctx.slug(e)}_l{l}.png",
                            title=rf"$W_e^T$, {e.of or e.name}, l = {l}")
            blocks.append(Figure(path, f"Heatmap of W_e^T (rows: the 18 configuration components, columns: "
                                       f"latent 1..{l}); source: {source}"))
        blocks += _experiment_encoder(run, e, ctx)
        blocks.append(f"Accuracy vs complexity ({e.name})")
        sweep = run.json(e, "result")
        if sweep is None:
            blocks.append(Para(f"{e.name}: no sweep result; trade-off skipped.", note=True))
            continue
        lam, best = sweep.get("lambda", PAPER_LAMBDA), figures.best_dim(sweep)
        path = ctx.draw(figures.tradeoff_figure, sweep, ctx.fig_dir / f"tradeoff_{ctx.slug(e)}.png")
        blocks.append(Figure(path, "E_dec and |Xi| (mean ± std over seeds) and L_mod per latent dimension"))
        blocks.append(Para(f"L_mod = 2 E_dec + 2 λ log|Xi| with λ = {lam:g}; best latent dimension: {best} "
                           f"(the paper finds {PAPER_BEST_DIMS[0]}–{PAPER_BEST_DIMS[1]}). "
                           f"Seeds: {sweep.get('seeds', '?')}."))
        blocks.append(Table(["latent dim l", "E_dec (mean±std)", "|Xi| (mean±std)", "L_mod"], sweep_rows(sweep),
                            caption="Trade-off per latent dimension"))
    return blocks


def _experiment_encoder(run: Run, e: ManifestEntry, ctx: Context) -> list:
    """The swept experiment's own encoder (the one its selection chose)."""
    swept = run.entry(e.of)
    model = run.model(swept) if swept is not None and "model" in swept.files else None
    if model is None:
        return []
    encoder = (swept.facts.get("config") or {}).get("encoder", "as trained")
    W = model.autoencoder.W_e
    path = ctx.draw(figures.encoder_heatmap, W, ctx.fig_dir / f"encoder_{ctx.slug(swept)}.png",
                    title=rf"$W_e^T$, {swept.name} model, l = {W.shape[0]}")
    return [Figure(path, f"Heatmap of W_e^T of the {swept.name} model (encoder: {encoder}; the heatmaps above "
                         "are the paper's default encoder)")]
