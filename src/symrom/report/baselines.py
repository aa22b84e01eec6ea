"""Renderer of baselines: their errors beside the learned model's on the same jumps.

A baseline entry names the learned experiment it is compared with (``of``);
with ``paper = "aslip"`` the paper's aSLIP ratios are shown too. A baseline
whose ``params`` file holds an aSLIP's ``k_s``, ``l_0`` and ``m`` is also
drawn on the learned model's figure jump.
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

ASLIP_KEYS = ("k_s", "l_0", "m")
UNITS = {"k_s": "N/m", "l_0": "m", "m": "kg"}


def comparison_rows(learned, baseline, paper: str | None) -> list[list[str]]:
    """Full-horizon MAE per component the baseline reports: learned, baseline, their ratio,
    and with ``paper == "aslip"`` the paper's learned, aSLIP and ratio (x and z)."""
    rows = []
    lo, bo = learned.horizons.get("full"), baseline.horizons.get("full")
    for c in (bo.components if bo else {}):
        om, am = (lo.stat(c, "mae") if lo else None), bo.stat(c, "mae")
        row = [c, DASH if om is None else fmt(om), fmt(am), f"{am / om:.3g}" if om else DASH,
               "✓" if om is not None and om <= am else "✗"]
        if paper == "aslip":
            p = PAPER_ASLIP.get(c)
            row += [fmt(p["learned"]), fmt(p["aslip"]), f"{p['aslip'] / p['learned']:.3g}"] if p else [DASH] * 3
        rows.append(row)
    return rows


def baseline_blocks(run: Run, entries: list[ManifestEntry], ctx: Context) -> list:
    blocks: list = []
    for e in entries:
        learned_entry = run.entry(e.of)
        blocks.append(f"{e.title or e.name}" + (f" vs {e.of}" if e.of else ""))
        metrics = run.metrics(e)
        learned = run.metrics(learned_entry) if learned_entry else None
        if metrics is None or learned is None:
            blocks.append(Para(f"{e.name}: its metrics or those of {e.of!r} are missing; no comparison.",
                               note=True))
            continue
        header = ["component", f"{e.of} MAE", f"{e.name} MAE", "baseline / learned", "learned ≤ baseline"]
        if e.paper == "aslip":
            header += ["paper learned", "paper aSLIP", "paper aSLIP / learned"]
            blocks.append(Para("The paper reports a full-horizon CoM MAE of 1.6e-2 m (learned) vs 5.7e-2 m "
                               "(aSLIP) in x and 4.0e-2 m vs 9.5e-2 m in z."))
        blocks.append(Table(header, comparison_rows(learned, metrics, e.paper),
                            caption=f"Full horizon, {metrics.split} split, MAE in the units of each component"))
        blocks.append(Para(f"Diverged {metrics.split} jumps — {e.of}: {diverged_text(learned)}; "
                           f"{e.name}: {diverged_text(metrics)}."))
        params = run.json(e, "params") if "params" in e.files else None
        if params:
            blocks.append(Table(["parameter", "value"],
                                [[f"{k} [{UNITS[k]}]" if k in UNITS else k, f"{v:.4g}"]
                                 for k, v in params.items() if isinstance(v, (int, float))],
                                caption=f"{e.name} parameters ({params.get('source', 'fitted on the train split')})"))
        blocks += _figure(e, learned_entry, params, metrics.integrator, ctx)
    return blocks


def _figure(e: ManifestEntry, learned_entry: ManifestEntry, params: dict | None, method: str | None,
            ctx: Context) -> list:
    """CoM x and z of the learned model's figure jump: truth, learned, and an aSLIP baseline."""
    got = ctx.jumps.get(learned_entry)
    if got is None:
        return []
    ds, j, ros = got
    a, b = ds.jump_bounds()[j]
    is_aslip = params is not None and all(isinstance(params.get(k), (int, float)) for k in ASLIP_KEYS)
    pred = figures.aslip_jump_com(ds, j, params, method or "lsoda") if is_aslip else None
    path = figures.aslip_figure(ds.t[a:b], ds.q[a:b, BASE_POS], ros["full"].q_pred[0][:, BASE_POS], pred,
                                ds.phase[a:b], ds.phase_names, ctx.fig_dir / f"baseline_{ctx.slug(e)}.png",
                                title=f"{learned_entry.name} test jump {j}: CoM position, learned vs {e.name}")
    return [Figure(path, f"CoM x and z of {learned_entry.name} test jump {j}: truth, learned model"
                         + (f", {e.name}" if pred is not None else " (no rollout of this baseline to draw)"))]
