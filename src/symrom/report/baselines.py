"""Renderer of baselines: their errors beside the learned model's on the same jumps.

Baseline entries name the learned experiment they are compared with (``of``);
all baselines of one experiment share one table (full-horizon MAE of each CoM
component, and each baseline's ratio to the learned model), one table of their
parameters and one figure of the learned model's figure jump. With ``paper =
"aslip"`` the paper's aSLIP ratios are shown too. A baseline is drawn when its
``params`` file describes it (``symrom.baselines.from_params``).
"""

from __future__ import annotations

from symrom.evaluate.paper import PAPER_ASLIP
from symrom.evaluate.records import ManifestEntry
from symrom.names import BASE_POS
from symrom.report import figures
from symrom.report.context import Context
from symrom.report.document import Figure, Para, Table
from symrom.report.format import DASH, diverged_text, fmt
from symrom.report.run import Run

UNITS = {"k_s": "N/m", "l_0": "m", "m": "kg", "A": "-", "c": "m/s²", "c_f": "m/s²"}


def comparison_rows(learned, baselines: list[tuple[str, object]], stat: str = "mae") -> list[list[str]]:
    """Per CoM component the baselines report: the learned model's full-horizon ``stat``,
    then per baseline its ``stat`` and its ratio to the learned one (> 1: the learned
    model is better)."""
    lo = learned.horizons.get("full")
    comps = list(dict.fromkeys(c for _, m in baselines if m.horizons.get("full")
                               for c in m.horizons["full"].components))
    rows = []
    for c in comps:
        om = lo.stat(c, stat) if lo else None
        row = [c, DASH if om is None else fmt(om)]
        for _, m in baselines:
            h = m.horizons.get("full")
            bm = h.stat(c, stat) if h else None
            row += [DASH if bm is None else fmt(bm), f"{bm / om:.3g}" if bm is not None and om else DASH]
        rows.append(row)
    return rows


def _paper_rows() -> list[list[str]]:
    return [[c, fmt(p["learned"]), fmt(p["aslip"]), f"{p['aslip'] / p['learned']:.3g}"]
            for c, p in PAPER_ASLIP.items()]


def baseline_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    groups: dict[str | None, list[ManifestEntry]] = {}
    for e in entries:
        groups.setdefault(e.of, []).append(e)
    for of, group in groups.items():
        learned_entry = run.entry(of)
        learned = run.metrics(learned_entry) if learned_entry else None
        blocks.append(f"{of}: learned model vs " + ", ".join(e.title or e.name for e in group))
        have = [(e, run.metrics(e)) for e in group]
        missing = [e.name for e, m in have if m is None]
        if learned is None or missing:
            blocks.append(Para(f"Metrics missing ({', '.join(missing) or of}); no comparison for those.", note=True))
        have = [(e, m) for e, m in have if m is not None]
        if learned is None or not have:
            continue
        header = ["component", f"{of} (learned)"]
        for e, _ in have:
            header += [e.title or e.name, "ratio to learned"]
        blocks.append(Table(header, comparison_rows(learned, [(e.name, m) for e, m in have]),
                            caption=f"Full-horizon MAE on the {learned.split} split (m); a ratio above 1 "
                                    "means the learned model errs less"))
        if any(e.paper == "aslip" for e, _ in have):
            blocks.append(Table(["component", "paper learned", "paper aSLIP", "paper aSLIP / learned"],
                                _paper_rows(), caption="The paper's full-horizon CoM MAE (m), Go1 simulation"))
        blocks.append(Para("Diverged jumps — " + "; ".join(
            [f"learned: {diverged_text(learned)}"] + [f"{e.title or e.name}: {diverged_text(m)}" for e, m in have])
            + "."))
        params = {e.name: run.json(e, "params") for e, _ in have if "params" in e.files}
        rows = [[e.title or e.name, f"{k} [{UNITS[k]}]" if k in UNITS else k, text]
                for e, _ in have for k, v in (params.get(e.name) or {}).items()
                if k != "format_version" and (text := _number_text(v))]  # the file's version, not a parameter
        if rows:
            blocks.append(Table(["baseline", "parameter", "value"], rows,
                                caption="Baseline parameters; "
                                        + "; ".join(f"{e.title or e.name}: {p.get('source', '')}"
                                                    for e, _ in have if (p := params.get(e.name)))))
        blocks += _figure(learned_entry, [(e, params.get(e.name)) for e, _ in have], learned.integrator, ctx)
    return blocks


def _number_text(v) -> str:
    """A parameter's value as text: a number, or a (nested) list of numbers; '' for anything else."""
    if isinstance(v, bool):
        return ""
    if isinstance(v, (int, float)):
        return f"{v:.4g}"
    items = [_number_text(x) for x in v] if isinstance(v, list) else []
    return "[" + ", ".join(items) + "]" if items and all(items) else ""


def _figure(learned_entry: ManifestEntry, baselines: list[tuple[ManifestEntry, dict | None]],
            method: str | None, ctx: Context) -> list:
    """CoM x and z of the learned model's figure jump: truth, learned, and every baseline."""
    got = ctx.jumps.get(learned_entry)
    if got is None:
        return []
    ds, j, ros = got
    a, b = ds.jump_bounds()[j]
    preds = {}
    for e, params in baselines:
        pred = figures.baseline_jump_com(ds, j, params, method or "lsoda") if params else None
        if pred is not None:
            preds[e.title or e.name] = pred
    path = ctx.draw(figures.com_figure, ds.t[a:b], ds.q[a:b, BASE_POS], ros["full"].q_pred[0][:, BASE_POS], preds,
                    ds.phase[a:b], ds.phase_names, ctx.fig_dir / f"baselines_{ctx.slug(learned_entry)}.png",
                    title=f"{learned_entry.name}, {ds.split[j]} jump 0 (dataset jump {j}): CoM position, "
                          "learned vs baselines")
    return [Figure(path, f"CoM x and z of {learned_entry.name}, {ds.split[j]} jump 0 (dataset jump {j}): truth, "
                         "learned model" + (", " + ", ".join(preds) if preds else " (no baseline rollout to draw)"))]
