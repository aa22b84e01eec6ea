"""The flight polish's weight, read from the committed val comparison of ``benchmarks/polish_weight.py``.

The ratios are recomputed from the stored val RMSE and the paper's Table 2, not read from the
record's own ``worst`` (docs/results.md, "Compact models").
"""

import json
from pathlib import Path

from symrom.evaluate.paper import implied_rmse, paper_row
from symrom.experiments.select import REFERENCE_FLOOR
from symrom.learn.regressors.refine import Refine
from symrom.names import TABLE2_COMPONENTS

RECORD = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "polish_weight.json"


def worst(row: dict) -> float:
    """The largest val RMSE / paper ratio over both horizons (the paper's A1 held its hip abduction)."""
    out = 0.0
    for h in ("full", "0.1"):
        paper = paper_row("a1_sim", h)
        rmse = row["horizons"][h]["rmse"]
        assert row["horizons"][h]["diverged_jumps"] == 0, (row["variant"], h)
        out = max(out, max(rmse[c] / implied_rmse(*paper[c]) for c in TABLE2_COMPONENTS
                           if implied_rmse(*paper[c]) >= REFERENCE_FLOOR))
    return out


def test_the_default_weight_is_the_one_val_puts_furthest_under_the_paper():
    assert RECORD.is_file(), f"{RECORD} is missing; write it with benchmarks/polish_weight.py"
    r = json.loads(RECORD.read_text())
    assert r["default_polish_weight"] == Refine().polish_weight
    rows = {row["polish_weight"]: row for row in r["val"]}
    assert None in rows and Refine().polish_weight in rows
    for row in r["val"]:  # the polish keeps the support: the budget holds
        assert row["active_terms"] <= r["max_terms"] <= 60
        assert row["active_per_phase"] == rows[None]["active_per_phase"]
    ratio = {w: worst(row) for w, row in rows.items()}
    assert ratio[Refine().polish_weight] == min(ratio.values())
    assert ratio[Refine().polish_weight] <= 1.0 < ratio[None]  # the polish makes it meet the paper on val
