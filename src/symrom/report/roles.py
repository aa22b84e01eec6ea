"""The report's registry: which sections a role of experiment fills, and in what order.

A run's manifest lists its experiments with a role (``symrom.evaluate.records``).
For each section, in ``SECTIONS`` order, every role that contributes to it
renders all its entries at once (``Renderer(run, entries, ctx) -> blocks``), so a
new experiment of a known role appears with no code edit. A role with no
renderer still appears, in the section ``other``, with its metrics if it has
any. Adding a role: its renderer and one line in ``ROLES`` (and its section in
``SECTIONS`` if it needs a new one).
"""

from __future__ import annotations

from collections.abc import Callable

from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, SELECTION, SOLVER, SWEEP, ManifestEntry
from symrom.report.baselines import baseline_blocks
from symrom.report.context import Context
from symrom.report.document import Para, Section, Table
from symrom.report.format import DASH, fmt, horizon_label
from symrom.report.learned import equations_blocks, predictions_blocks, table2_blocks
from symrom.report.run import Run
from symrom.report.selection import finetune_choice_blocks, selection_blocks
from symrom.report.solvers import solver_blocks
from symrom.report.tradeoff import sweep_blocks

Renderer = Callable[[Run, list[ManifestEntry], Context], list]

SECTIONS: dict[str, str] = {
    "table2": "Table 2 — prediction errors, paper vs ours",
    "predictions": "Predictions of a test jump",
    "selection": "Model selection on the validation split",
    "baselines": "Learned model vs baselines",
    "tradeoff": "Latent dimension: encoder weights and accuracy vs complexity",
    "equations": "Learned equations per phase",
    "solvers": "Solvers",
    "other": "Other experiments",
}

ROLES: dict[str, list[tuple[str, Renderer]]] = {
    LEARNED: [("table2", table2_blocks), ("predictions", predictions_blocks), ("equations", equations_blocks)],
    FINE_TUNED: [("table2", table2_blocks), ("predictions", predictions_blocks), ("selection", finetune_choice_blocks),
                 ("equations", equations_blocks)],
    BASELINE: [("baselines", baseline_blocks)],
    SWEEP: [("tradeoff", sweep_blocks)],
    SOLVER: [("solvers", solver_blocks)],
    SELECTION: [("selection", selection_blocks)],
}

INTROS: dict[str, str] = {
    "table2": "Signed error predicted − true over all samples of the test split (joint angles and orientation "
              "in rad, CoM position in m), full-horizon rollouts and rollouts reset to the true latent state "
              "every 0.1 s. The paper's mean±std gives an implied RMSE √(mean²+std²); ✓ marks a component "
              "where our RMSE is not larger. A diverged jump is scored up to the time it diverged, and counted "
              "(the note under each table names it and when). "
              "Each experiment's table is split into its joints and its base pose.",
    "predictions": "Truth (black) and the learned model's prediction of the front-left and rear-right joint "
                   "angles and the CoM pose, full horizon (red, dashed, drawn on top) and with 0.1 s resets "
                   "(wide, pale blue); shaded spans mark the phases other than the first.",
}


def other_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    """Entries of a role without a renderer: name, role and, if any, RMSE per horizon."""
    blocks: list = []
    for e in entries:
        blocks.append(f"{e.name} ({e.role})")
        metrics = run.metrics(e) if "metrics" in e.files else None
        if metrics is None:
            blocks.append(Para(f"No renderer for role {e.role!r}; files: "
                               + (", ".join(f"{k}: {v}" for k, v in e.files.items()) or "none") + "."))
            continue
        comps = list(dict.fromkeys(c for h in metrics.horizons.values() for c in h.components))
        rows = [[horizon_label(k), str(h.diverged_jumps)] + [DASH if h.stat(c, "rmse") is None
                                                            else fmt(h.stat(c, "rmse")) for c in comps]
                for k, h in metrics.horizons.items()]
        blocks.append(Table(["horizon", "diverged"] + comps, rows, caption=f"{e.name}: RMSE per component"))
    return blocks


def build_sections(run: Run, ctx: Context) -> list[Section]:
    """The sections the run's manifest fills, in ``SECTIONS`` order (empty ones left out)."""
    by_role: dict[str, list[ManifestEntry]] = {}
    for e in run.entries:
        by_role.setdefault(e.role if e.role in ROLES else "?", []).append(e)
    plan: dict[str, list[tuple[Renderer, list[ManifestEntry]]]] = {sid: [] for sid in SECTIONS}
    for role, entries in by_role.items():
        for sid, render in ROLES.get(role, [("other", other_blocks)]):
            plan[sid].append((render, entries))
    sections = []
    for sid, parts in plan.items():
        if not parts:
            continue
        blocks = [b for render, entries in parts for b in render(run, entries, ctx)]
        if not blocks:  # nothing to show (a model folder without its evaluation has no Table 2)
            continue
        sec = Section(sid, SECTIONS[sid])
        if sid in INTROS:
            sec.add(Para(INTROS[sid]))
        sections.append(sec.add(*blocks))
    return sections
