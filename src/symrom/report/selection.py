"""Renderer of a validation selection: accuracy versus active terms of every candidate.

The selection table (``selection.json``, ``symrom.experiments.select``) holds one
row per candidate. The report draws all of them (validation score against
active terms), states the rule and the chosen row, and lists, per encoder and
latent dimension, the best candidate next to the chosen one. A fine-tuned
experiment's choice (``finetune_choice.json``: source model x fine-tuning
method, scored the same way) is listed whole.
"""

from __future__ import annotations

from symrom.evaluate.records import ManifestEntry
from symrom.report import figures
from symrom.report.context import Context
from symrom.report.document import Figure, Para, Table
from symrom.report.format import DASH
from symrom.report.run import Run

HEADER = ["encoder", "l", "library", "threshold", "refined", "active terms", "val score full",
          "val score 0.1 s", "diverged val jumps (full, 0.1 s)", "chosen"]


def _stat(r: dict, horizon: str, field: str) -> str:
    """A row's per-horizon ``score`` or ``worst``, or a dash where it diverged."""
    v = r["horizons"][horizon][field]
    return DASH if v is None else f"{v:.3g}"


def _row(r: dict, chosen: bool) -> list[str]:
    h = r["horizons"]
    refined = "no" if not r["refine"] else f"yes, ≤ {r['max_terms']} terms" if r.get("max_terms") else "yes"
    return [r["encoder"], str(r["latent_dim"]), r["library"], f"{r['threshold']:g}", refined,
            str(r["active_terms"]), _stat(r, "full", "score"), _stat(r, "0.1", "score"),
            f"{h['full']['diverged_jumps']}, {h['0.1']['diverged_jumps']}", "★" if chosen else ""]


def best_rows(rows: list[dict], chosen: int | None) -> list[int]:
    """Indices of the best-scoring row of each (encoder, latent dim), and the chosen row."""
    best: dict[tuple, int] = {}
    for i, r in enumerate(rows):
        key = (r["encoder"], r["latent_dim"])
        s = r["score"] if r["score"] is not None else float("inf")
        if key not in best or s < (rows[best[key]]["score"] or float("inf")):
            best[key] = i
    picked = sorted(set(best.values()) | ({chosen} if chosen is not None else set()))
    return picked


def selection_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    for e in entries:
        blocks.append(e.title or e.name)
        table = run.json(e, "table") if "table" in e.files else None
        if not table or not isinstance(table.get("rows"), list):
            blocks.append(Para(f"{e.name}: no selection table; skipped.", note=True))
            continue
        rows, chosen = table["rows"], table.get("chosen")
        blocks.append(Para(f"{len(rows)} candidate models in {table.get('seconds', 0):.0f} s. "
                           f"Rule: {table.get('rule', '')}."))
        if chosen is None:
            blocks.append(Para("No candidate survived: every one diverged on a validation jump or broke the data's "
                               "momentum balance.", note=True))
        by_paper = (table.get("config") or {}).get("reference") is not None  # scored against the paper's RMSE
        path = ctx.draw(figures.selection_figure, rows, chosen, ctx.fig_dir / f"selection_{ctx.slug(e)}.png",
                        title=f"{e.of or e.name}: validation score vs active terms",
                        yardstick="paper's RMSE" if by_paper else "spread")
        blocks.append(Figure(path, f"{e.of or e.name}: every candidate of the selection (lower is better)"))
        blocks.append(Table(HEADER, [_row(rows[i], i == chosen) for i in best_rows(rows, chosen)],
                            caption="The best candidate per encoder and latent dimension, and the chosen one "
                                    f"(the full table: {e.files['table']})"))
    return blocks


CHOICE_HEADER = ["source model", "fine-tuning", "active terms", "val score full", "val score 0.1 s",
                 "worst ratio full", "worst ratio 0.1 s", "diverged val jumps (full, 0.1 s)", "chosen"]


def _choice_row(r: dict, chosen: bool) -> list[str]:
    if r.get("refused"):
        return [r["source"], r["finetune"], DASH, DASH, DASH, DASH, DASH, f"refused: {r['refused']}", ""]
    h = r["horizons"]
    return [r["source"], r["finetune"], str(r["active_terms"]), _stat(r, "full", "score"), _stat(r, "0.1", "score"),
            _stat(r, "full", "worst"), _stat(r, "0.1", "worst"),
            f"{h['full']['diverged_jumps']}, {h['0.1']['diverged_jumps']}", "★" if chosen else ""]


def finetune_choice_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    """A fine-tuned experiment's candidates (source model x fine-tuning method) on its val split."""
    blocks: list = []
    for e in entries:
        choice = run.json(e, "choice") if "choice" in e.files else None
        if not choice or not isinstance(choice.get("rows"), list):
            continue
        blocks.append(f"{e.title or e.name}: fine-tuning chosen on the validation split")
        blocks.append(Para(f"Rule: {choice.get('rule', '')}. Scores are RMSE over the paper's implied RMSE "
                           "(1 = the paper's level)."))
        blocks.append(Table(CHOICE_HEADER, [_choice_row(r, i == choice.get("chosen"))
                                            for i, r in enumerate(choice["rows"])],
                            caption=f"Every candidate (the table: {e.files['choice']})"))
    return blocks
