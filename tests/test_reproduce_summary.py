"""The reproduction's SIM results, read from the committed record of its summary.

``benchmarks/results/reproduce_summary.json`` is written by
``python benchmarks/sim_experiment.py a1_sim go1_sim --run RUN --max-terms 60`` (reproduce's
functions and settings with the compact term budget, ``reproduce --max-terms 60``;
docs/results.md). The counts are recomputed here from the stored test RMSE and the
paper's Table 2, not read from the record's own lists.
"""

import json
from pathlib import Path

import pytest

from symrom.evaluate.paper import implied_rmse, paper_row
from symrom.experiments.reproduce import MAX_TERMS
from symrom.names import TABLE2_COMPONENTS

RECORD = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "reproduce_summary.json"
HX = ("fl_hx", "rr_hx")  # the paper's A1 hip abduction errors are 1e-10 rad: a joint it held still


def experiment(name: str) -> dict:
    assert RECORD.is_file(), f"{RECORD} is missing; write it with benchmarks/sim_experiment.py"
    exps = json.loads(RECORD.read_text())["experiments"]
    assert name in exps, f"{RECORD} has no {name} entry"
    return exps[name]


def at_or_below_paper(name: str, h: str, rmse: dict[str, float]) -> set[str]:
    paper = paper_row(name, h)
    return {c for c in TABLE2_COMPONENTS if c in rmse and rmse[c] <= implied_rmse(*paper[c])}


def meets_paper_but_hx(h: str) -> tuple[bool, list[str]]:
    """Whether SIM A1 is at or below the paper at ``h`` on 10 of 12 components, every one but
    the hip abduction; and the components that are not."""
    hz = experiment("a1_sim")["horizons"][h]
    assert set(hz["rmse"]) == set(TABLE2_COMPONENTS), h  # every component scored
    ok = at_or_below_paper("a1_sim", h, hz["rmse"])
    return len(ok) >= 10 and set(TABLE2_COMPONENTS) - set(HX) <= ok, sorted(set(TABLE2_COMPONENTS) - ok)


def test_sim_a1_is_compact_does_not_diverge_and_meets_the_paper_over_whole_jumps():
    a1 = experiment("a1_sim")
    assert MAX_TERMS <= 60
    assert a1["config"]["max_terms"] == MAX_TERMS
    assert a1["active_terms"] == sum(a1["active_per_phase"].values())
    assert a1["active_terms"] <= 60
    for h in ("full", "0.1"):
        assert a1["horizons"][h]["diverged_jumps"] == 0, h
    met, missed = meets_paper_but_hx("full")
    assert met, missed


def test_sim_a1_meets_the_paper_with_resets():
    met, missed = meets_paper_but_hx("0.1")
    assert met, missed


@pytest.mark.parametrize("horizon", ["full", "0.1"])
def test_sim_go1_keeps_its_five_terms_and_meets_the_paper_on_every_component(horizon):
    go1 = experiment("go1_sim")
    assert go1["config"]["max_terms"] == MAX_TERMS  # selected under the budget
    assert go1["active_terms"] <= 5
    hz = go1["horizons"][horizon]
    assert hz["diverged_jumps"] == 0
    assert at_or_below_paper("go1_sim", horizon, hz["rmse"]) == set(TABLE2_COMPONENTS)
