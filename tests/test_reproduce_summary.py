"""The counting behind the reproduction's results, on a small synthetic run.

``benchmarks/sim_experiment.py`` writes the record of docs/results.md's compact models and
``benchmarks/summary_tables.py`` prints docs/results.md's tables from a run's ``summary.json``;
both count the components at or below the paper's implied RMSE (``evaluate.paper``) and the
baselines' ratios. Here they run on metrics planted around the paper's numbers, so the counts
are known. The committed record is checked for its provenance in tests/test_benchmark_records.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from symrom.evaluate.paper import PAPER_ASLIP, at_or_below_paper, implied_rmse, paper_rmse, paper_row
from symrom.names import TABLE2_COMPONENTS

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import sim_experiment  # noqa: E402
import summary_tables  # noqa: E402

sys.path.pop(0)


def planted_metrics(name: str, below: dict[str, set[str]], diverged: int = 0, mae: float = 0.01) -> dict:
    """metrics.json of ``name`` whose RMSE is half the paper's implied RMSE on the components of
    ``below[h]`` and twice it elsewhere, at horizons ``full`` and ``0.1``."""
    horizons = {}
    for h, comps in below.items():
        ref = paper_rmse(name, h)
        horizons[h] = {"diverged_jumps": diverged, "components": {
            c: {"mean": 0.0, "std": 0.0, "mae": mae, "rmse": ref[c] * (0.5 if c in comps else 2.0)}
            for c in TABLE2_COMPONENTS}}
    return {"format_version": 3, "n_jumps": 6, "split": "test", "horizons": horizons}


BELOW = {"full": set(TABLE2_COMPONENTS[:7]), "0.1": set(TABLE2_COMPONENTS) - {"fl_hx", "rr_hx"}}


def test_at_or_below_paper_counts_components_at_the_implied_rmse():
    ref = paper_rmse("a1_sim", "full")
    rmse = {c: ref[c] for c in TABLE2_COMPONENTS}  # exactly at the paper: counted
    rmse["z"] = ref["z"] * (1 + 1e-9)  # just above: not
    rmse["yaw"] = None  # not scored (a diverged component): not
    got = at_or_below_paper("a1_sim", "full", rmse)
    assert got == [c for c in TABLE2_COMPONENTS if c not in ("z", "yaw")]
    assert at_or_below_paper("a1_sim", "0.3", rmse) is None and paper_rmse("nope", "full") is None
    row = paper_row("go1_sim", "0.1")
    assert paper_rmse("go1_sim", "0.1")["x"] == pytest.approx(implied_rmse(*row["x"]))


def test_the_record_counts_the_planted_components_and_the_chosen_budget():
    entry = {"metrics": planted_metrics("a1_sim", BELOW), "config": {"encoder": "pose+joints", "latent_dim": 7},
             "active_terms": {"contact": 30, "partial": 12, "flight": 18}}
    selection = {"rows": [{"max_terms": None}, {"max_terms": 60}], "chosen": 1, "seconds": 12.5, "rule": "r"}
    rec = sim_experiment.record("a1_sim", entry, selection)
    assert rec["active_terms"] == 60 and rec["config"]["max_terms"] == 60 and rec["candidates"] == 2
    for h, comps in BELOW.items():
        hz = rec["horizons"][h]
        assert hz["at_or_below_paper"] == [c for c in TABLE2_COMPONENTS if c in comps]
        assert hz["paper_rmse"] == paper_rmse("a1_sim", h) and hz["jumps"] == 6
    # A horizon the paper has no row for: no comparison, the RMSE kept.
    entry["metrics"]["horizons"]["0.3"] = entry["metrics"]["horizons"]["full"]
    assert sim_experiment.record("a1_sim", entry, selection)["horizons"]["0.3"]["at_or_below_paper"] is None


def test_summary_tables_count_wins_and_baseline_ratios():
    go1 = planted_metrics("go1_sim", {"full": set(TABLE2_COMPONENTS), "0.1": {"x", "z"}}, mae=0.02)
    aslip = planted_metrics("go1_sim", {"full": set(), "0.1": set()}, mae=0.05)
    summary = {"experiments": {"go1_sim": {
        "metrics": go1, "baselines": {"aslip": aslip},
        "paper_defaults": {"metrics": planted_metrics("go1_sim", {"full": set(), "0.1": set()}, diverged=6)}}}}
    lines = summary_tables.table2(summary)
    ours = [line for line in lines if line.startswith("| go1_sim | ") and "| ours |" in line]
    assert ours[0].endswith("| 0 (12/12 ≤ paper) |") and ours[1].endswith("| 0 (2/12 ≤ paper) |")
    assert ours[0].count("**") == 2 * 12 and ours[1].count("**") == 2 * 2
    defaults = [line for line in lines if line.startswith("| go1_sim (paper defaults) |")]
    assert defaults[0].endswith("| 6 (0/12 ≤ paper) |")  # its 6 diverged test jumps, none under the paper
    base = summary_tables.baselines(summary)
    x = next(line for line in base if line.startswith("| go1_sim | x |"))
    assert "(2.5×)" in x  # aSLIP MAE 0.05 over the learned 0.02
    p = PAPER_ASLIP["x"]
    assert f"({p['aslip'] / p['learned']:.3g}×)" in x
