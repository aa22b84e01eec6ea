"""The result tables of docs/results.md, printed from a run directory of ``symrom reproduce``.

    python benchmarks/summary_tables.py runs/paper

Table 2 (RMSE beside the paper's implied RMSE, bold where ours is at or below
it), the selected settings of each experiment, and the baselines beside the
learned models (full-horizon CoM MAE and ratios), all read from the run's
``summary.json`` and files; nothing is recomputed.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from symrom.evaluate.paper import PAPER_ASLIP, at_or_below_paper, implied_rmse, paper_row
from symrom.evaluate.tables import fmt_value as fmt
from symrom.names import TABLE2_COMPONENTS

HORIZONS = (("full", "full"), ("0.1", "0.1 s"))


def table2(summary: dict) -> list[str]:
    head = "| experiment | horizon | RMSE | " + " | ".join(TABLE2_COMPONENTS) + " | diverged test jumps |"
    lines = [head, "|" + "---|" * (len(TABLE2_COMPONENTS) + 4)]
    rows = []
    for name, exp in summary["experiments"].items():
        rows.append((name, name, exp["metrics"]))
        if "paper_defaults" in exp:
            rows.append((f"{name} (paper defaults)", name, exp["paper_defaults"]["metrics"]))
        if "before_finetune" in exp:
            rows.append((f"{name} (before fine-tuning)", name, exp["before_finetune"]))
    for label, key, metrics in rows:
        for h, hl in HORIZONS:
            paper = paper_row(key, h)
            if paper and "(" not in label:
                lines.append(f"| {label} | {hl} | paper | "
                             + " | ".join(fmt(implied_rmse(*paper[c])) for c in TABLE2_COMPONENTS) + " | |")
            hm = metrics["horizons"][h]
            comps = hm["components"]
            below = at_or_below_paper(key, h, {c: comps[c]["rmse"] for c in comps}) or []
            wins = len(below)
            cells = ["div." if c not in comps else f"**{fmt(comps[c]['rmse'])}**" if c in below
                     else fmt(comps[c]["rmse"]) for c in TABLE2_COMPONENTS]
            tail = f"{hm['diverged_jumps']}" + (f" ({wins}/12 ≤ paper)" if paper and comps else "")
            lines.append(f"| {label} | {hl} | ours | " + " | ".join(cells) + f" | {tail} |")
    return lines


def selections(summary: dict) -> list[str]:
    lines = ["| experiment | encoder | l | library | threshold | refined | active terms | candidates |",
             "|---|---|---|---|---|---|---|---|"]
    for name, exp in summary["experiments"].items():
        c = exp.get("config", {})
        if "encoder" not in c:
            continue
        refined = "no" if not c["refine"] else f"yes, budget {c['max_terms']} terms" if c.get("max_terms") else "yes"
        lines.append(f"| {name} | {c['encoder']} | {c['latent_dim']} | {c['library']} | {c['threshold']:g} | "
                     f"{refined} | {sum(exp['active_terms'].values())} | {c['candidates']} |")
    return lines


def baselines(summary: dict) -> list[str]:
    lines = ["| experiment | CoM | learned MAE [m] | aSLIP (residual fit) | aSLIP (rollout fit) | Newton | "
             "Newton fitted | paper: learned / aSLIP |", "|---|---|---|---|---|---|---|---|"]
    for name, exp in summary["experiments"].items():
        b = exp.get("baselines")
        if not b:
            continue
        learned = exp["metrics"]["horizons"]["full"]["components"]
        for c in ("x", "z"):
            lm = learned[c]["mae"]
            cells = []
            for key in ("aslip", "aslip_rollout", "newton", "newton_fitted"):
                if key not in b:
                    cells.append("")
                    continue
                comps = b[key]["horizons"]["full"]["components"]
                cells.append(f"{fmt(comps[c]['mae'])} ({comps[c]['mae'] / lm:.3g}×)" if c in comps else "div.")
            p = PAPER_ASLIP.get(c) if name == "go1_sim" else None
            paper = f"{fmt(p['learned'])} / {fmt(p['aslip'])} ({p['aslip'] / p['learned']:.3g}×)" if p else ""
            lines.append(f"| {name} | {c} | {fmt(lm)} | " + " | ".join(cells) + f" | {paper} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    args = ap.parse_args()
    summary = json.loads((args.run / "summary.json").read_text())
    for block in (table2(summary), selections(summary), baselines(summary)):
        print("\n".join(block) + "\n")


if __name__ == "__main__":
    main()
