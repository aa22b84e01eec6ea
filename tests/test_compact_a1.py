"""The compact SIM A1 model of ``benchmarks/compact_a1.py``, read from its committed record.

The counts are recomputed from the stored RMSE and the paper's Table 2, not read from the
record's own lists (docs/results.md, "Compact models").
"""

import json
from pathlib import Path

import pytest

from symrom.evaluate.paper import implied_rmse, paper_row
from symrom.experiments.select import HORIZONS, REFERENCE_FLOOR
from symrom.names import TABLE2_COMPONENTS

RECORD = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "compact_a1.json"
NOT_HX = [c for c in TABLE2_COMPONENTS if not c.endswith("_hx")]  # the paper's A1 held its hips' abduction


def record() -> dict:
    assert RECORD.is_file(), f"{RECORD} is missing; write it with benchmarks/compact_a1.py"
    return json.loads(RECORD.read_text())


def ratios(h: str, rmse: dict[str, float]) -> dict[str, float]:
    paper = paper_row("a1_sim", h)
    return {c: rmse[c] / implied_rmse(*paper[c]) for c in TABLE2_COMPONENTS
            if implied_rmse(*paper[c]) >= REFERENCE_FLOOR}


def test_the_chosen_model_is_compact_and_meets_the_paper_on_val():
    r = record()
    assert r["active_terms"] <= r["max_terms"] <= 60
    assert r["active_terms"] == sum(r["active_per_phase"].values())
    chosen = r["val"][r["chosen"]]
    assert chosen["active_terms"] == r["active_terms"]
    for h in ("full", "0.1"):
        hz = chosen["horizons"][h]
        assert hz["diverged_jumps"] == 0, h
        assert max(ratios(h, hz["rmse"]).values()) <= 1.0, h
    # the rule: no other variant meeting both horizons within the budget has a better val score
    for row in r["val"]:
        if all(max(ratios(h, row["horizons"][h]["rmse"]).values()) <= 1.0 for h in ("full", "0.1")):
            assert (row["active_terms"], row["score"]) >= (chosen["active_terms"], chosen["score"])


def test_on_test_jumps_it_meets_the_paper_over_whole_jumps_without_divergence():
    test = record()["test"]
    assert set(test) == {"full" if h is None else str(h) for h in HORIZONS}
    for h in test:
        assert test[h]["diverged_jumps"] == 0 and test[h]["drifted_jumps"] == 0, h
    assert all(ratios("full", test["full"]["rmse"])[c] <= 1.0 for c in NOT_HX)


@pytest.mark.xfail(strict=True, reason="not met: on the test jumps, with 0.1 s resets, rr_hy is 1.05 times the "
                                       "paper (every other non-hx component at most 0.81; docs/results.md)")
def test_on_test_jumps_it_meets_the_paper_with_resets():
    test = record()["test"]
    assert all(ratios("0.1", test["0.1"]["rmse"])[c] <= 1.0 for c in NOT_HX)
