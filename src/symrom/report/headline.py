"""The report's first section: what the run found, before any detail.

Per experiment set beside a row of the paper's Table 2 (``paper``): how many of its 12
components are at or below the paper's implied RMSE at each horizon, its diverged test jumps
and its active terms; per baseline, its full-horizon CoM error as a multiple of the learned
model's (the paper's aSLIP multiple beside it); per sim-to-real target, the targets met. A model
folder gets its model's terms and errors. Every number is read from the run's files, as the
sections below show them.
"""

from __future__ import annotations

from symrom.evaluate.paper import PAPER_ASLIP, PAPER_LABELS, at_or_below_paper
from symrom.evaluate.records import BASELINE, FINE_TUNED, LEARNED, ManifestEntry, Metrics
from symrom.names import TABLE2_COMPONENTS
from symrom.report.document import Para, Table
from symrom.report.format import DASH, fmt, horizon_label
from symrom.report.run import Run

HORIZONS = ("full", "0.1")
CHECK_NAMES = {"source_z": "source z", "fine_tuned_z": "fine-tuned z", "not_above_source": "not above the source",
               "flight_gravity": "flight gravity", "vs_target_alone": "vs target alone"}


def table2_counts(paper_key: str, metrics: Metrics) -> dict[str, int | None]:
    """Per horizon of ``HORIZONS``: the components at or below the paper's implied RMSE
    (a diverged component counts as not), or None where the run or the paper has no such horizon."""
    out: dict[str, int | None] = {}
    for key in HORIZONS:
        h = metrics.horizons.get(key)
        below = (at_or_below_paper(paper_key, key, {c: h.stat(c, "rmse") for c in TABLE2_COMPONENTS})
                 if h is not None else None)
        out[key] = None if below is None else len(below)
    return out


def _terms(run: Run, e: ManifestEntry) -> str:
    model = run.model(e) if "model" in e.files else None
    if model is None:
        return DASH
    per = model.active_terms()
    return f"{sum(per.values())} ({', '.join(f'{p} {n}' for p, n in per.items())})"


def _table2_block(run: Run) -> list:
    rows = []
    for e in run.entries:
        if e.role not in (LEARNED, FINE_TUNED) or e.of is not None:
            continue
        metrics = run.metrics(e)
        if metrics is None:
            continue
        counts = table2_counts(e.paper, metrics) if e.paper in PAPER_LABELS else dict.fromkeys(HORIZONS)
        full = metrics.horizons.get("full")
        rows.append([e.name, PAPER_LABELS.get(e.paper, "none")]
                    + [DASH if counts[k] is None else f"{counts[k]} of {len(TABLE2_COMPONENTS)}" for k in HORIZONS]
                    + [DASH if full is None else f"{full.diverged_jumps} of {metrics.n_jumps}", _terms(run, e)])
    if not rows:
        return []
    return [Table(["experiment", "paper's Table 2 row"] + [f"at or below the paper, {horizon_label(k)}"
                                                           for k in HORIZONS]
                  + ["diverged test jumps (full)", "active terms (per phase)"], rows,
                  caption="Table 2: components whose test RMSE is at or below the paper's implied RMSE")]


def _baseline_block(run: Run) -> list:
    rows = []
    for e in run.entries:
        if e.role != BASELINE:
            continue
        learned_entry = run.entry(e.of)
        learned = run.metrics(learned_entry) if learned_entry else None
        base = run.metrics(e)
        if learned is None or base is None or "full" not in learned.horizons or "full" not in base.horizons:
            continue
        cells = []
        for c in ("x", "z"):
            lo, bm = learned.horizons["full"].stat(c, "mae"), base.horizons["full"].stat(c, "mae")
            ratio = None if lo is None or bm is None or lo == 0 else bm / lo
            cells.append(DASH if ratio is None else f"{ratio:.3g}× ({fmt(bm)} m)" if ratio < 1000
                         else f"{ratio:.0f}× ({fmt(bm)} m)")
        paper = DASH
        if e.paper == "aslip" and learned_entry is not None and learned_entry.paper == "go1_sim":
            paper = ", ".join(f"{c} {p['aslip'] / p['learned']:.3g}×" for c, p in PAPER_ASLIP.items())
        rows.append([e.of, e.title or e.name, *cells, paper])
    if not rows:
        return []
    return [Table(["experiment", "baseline", "CoM x: MAE / learned", "CoM z: MAE / learned", "paper: aSLIP / learned"],
                  rows, caption="Baselines: full-horizon CoM mean absolute error as a multiple of the learned "
                                "model's (above 1: the learned model is closer)")]


def _sim2real_block(run: Run) -> list:
    targets = (run.summary.get("sim2real") or {}).get("targets") or {}
    rows = []
    for name, t in targets.items():
        checks = {k: v for k, v in (t.get("checks") or {}).items() if k in CHECK_NAMES}
        met = [CHECK_NAMES[k] for k, v in checks.items() if v is True]
        missed = [CHECK_NAMES[k] for k, v in checks.items() if v is False]
        unknown = [CHECK_NAMES[k] for k, v in checks.items() if v is None]
        rest = ", ".join(missed) or ("none" if not unknown else "")
        if unknown:  # a column diverged or is missing
            rest += ("; " if rest else "") + "not checked: " + ", ".join(unknown)
        rows.append([name, str(t.get("engine", DASH)), f"{len(met)} of {len(checks)}", rest])
    if not rows:
        return []
    return [Table(["target", "engine", "targets met", "not met"], rows,
                  caption="Sim-to-real targets met on the test jumps")]


def _model_folder_blocks(run: Run) -> list:
    rows = []
    for e in run.entries:
        metrics = run.metrics(e) if "metrics" in e.files else None
        full = metrics.horizons.get("full") if metrics else None
        rmse = [DASH if full is None or full.stat(c, "rmse") is None else fmt(full.stat(c, "rmse"))
                for c in ("x", "z")]
        rows.append([e.name, _terms(run, e),
                     DASH if metrics is None else f"{metrics.n_jumps} ({metrics.split})",
                     DASH if full is None else str(full.diverged_jumps), *rmse])
    return [Table(["model", "active terms (per phase)", "evaluated jumps", "diverged (full)",
                   "CoM x RMSE, full [m]", "CoM z RMSE, full [m]"], rows, caption="The model at a glance")]


def headline_blocks(run: Run) -> list:
    """The headline's blocks (empty when the run holds nothing to sum up)."""
    if run.kind == "model folder":
        return _model_folder_blocks(run) if run.entries else []
    blocks = _table2_block(run) + _baseline_block(run) + _sim2real_block(run)
    if blocks:
        blocks.insert(0, Para("What this run found; the sections below give each number's table, figures and "
                              "notes. The paper's implied RMSE is √(mean²+std²) of its Table 2 row."))
    return blocks
