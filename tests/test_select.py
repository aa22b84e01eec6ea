"""Selection on validation data: the test split is never read, the rule is applied as stated."""

import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

from symrom.cli import app
from symrom.data.io import write_dataset
from symrom.experiments.select import SelectionConfig, choose, parse_library, select, selection_rule, to_refine

GRID = SelectionConfig(encoders=("all", "base_position"), latent_dims=(2,), libraries=("poly1+trig+inputs",),
                       thresholds=(1e-3, 1e-2), refine_top=1)


@pytest.fixture(scope="module")
def selected(small_block):
    return small_block, select(small_block, GRID)


def test_selection_table_and_choice(selected):
    ds, sel = selected
    # 2 encoders x 1 dim x 1 library x 2 thresholds, then 1 refined
    assert len(sel.rows) == 5 and sum(r["refine"] for r in sel.rows) == 1
    assert sel.chosen is not None and sel.model is not None
    r = sel.rows[sel.chosen]
    assert r["encoder"] == "all"  # base_position cannot see the planted latents
    assert sel.model.provenance.selection.encoder == "all"
    ok = [x for x in sel.rows if x["score"] is not None]
    best = min(x["score"] for x in ok)
    assert r["score"] <= (1 + GRID.tolerance) * best
    assert r["active_terms"] == min(x["active_terms"] for x in ok if x["score"] <= (1 + GRID.tolerance) * best)
    d = sel.to_dict()
    assert d["chosen"] == sel.chosen and "within 5% of the best" in d["rule"]


def test_selection_never_reads_the_test_split(selected):
    ds, sel = selected
    test = ds.rows_of("test")
    blind = replace(ds, **{k: np.where(test[:, None] if getattr(ds, k).ndim == 2 else test,
                                       np.nan, getattr(ds, k)) for k in ("t", "q", "dq", "ddq", "tau", "u")})
    assert np.isnan(blind.q[test]).all()
    again = select(blind, GRID)
    assert again.chosen == sel.chosen
    for a, b in zip(again.rows, sel.rows):
        assert (a["encoder"], a["threshold"], a["refine"], a["active_terms"]) == \
               (b["encoder"], b["threshold"], b["refine"], b["active_terms"])
        assert a["score"] == b["score"] or (a["score"] is None and b["score"] is None)
    np.testing.assert_array_equal(again.model.Xi, sel.model.Xi)


def _r(score, terms, worst=(None, None)):
    return {"score": score, "active_terms": terms,
            "horizons": {"full": {"worst": worst[0], "score": score}, "0.1": {"worst": worst[1], "score": score}}}


def test_rule_rejects_diverged_and_prefers_sparse():
    rows = [_r(None, 3), _r(1.0, 40), _r(1.04, 20), _r(1.2, 5)]
    assert choose(rows, 0.05) == 2
    assert choose(rows, 0.0) == 1
    assert choose([_r(None, 1)], 0.05) is None
    # With a reference: the sparsest that meets it on every component at both horizons.
    rows = [_r(0.5, 60, (0.9, 0.8)), _r(0.7, 12, (0.99, 0.95)), _r(0.3, 8, (1.4, 0.5)), _r(0.2, 90, (0.6, 0.5))]
    assert choose(rows, 0.05, reference=True) == 1
    assert choose(rows, 0.05) == 3  # without: the best score (no other within 5 %)
    assert choose([_r(0.3, 8, (1.4, 0.5))], 0.05, reference=True) == 0  # none meets it: the tolerance rule


def test_budget_limits_the_choice_to_candidates_within_it():
    rows = [_r(0.5, 188, (0.9, 0.8)),   # meets the reference, far over the budget
            _r(0.9, 70, (0.9, 0.95)),   # meets it, just over
            _r(0.62, 60, (1.2, 0.9)),   # at the budget, misses the reference
            _r(0.6, 45, (1.1, 1.3))]    # within it, misses the reference, best score among those within
    assert choose(rows, 0.05, reference=True) == 1  # no budget: the sparsest that meets the reference
    assert choose(rows, 0.05, reference=True, max_terms=70) == 1  # the budget is inclusive
    assert choose(rows, 0.05, reference=True, max_terms=60) == 3  # none within meets: tolerance among them
    assert choose(rows, 0.0, reference=True, max_terms=60) == 3
    assert choose(rows[:3], 0.05, reference=True, max_terms=60) == 2
    # No candidate within the budget stands: all compete.
    assert choose(rows[:2] + [_r(None, 30)], 0.05, reference=True, max_terms=60) == 1
    # The budget reaches the refinement through the training configuration, and only there.
    cfg = replace(GRID, max_terms=12)
    assert cfg.train_config("all", 2, "poly1+inputs", 1e-3, refine=True).regressor().max_terms == 12
    assert cfg.train_config("all", 2, "poly1+inputs", 1e-3).max_terms is None
    assert "at most 12 active terms" in selection_rule(cfg)
    with pytest.raises(ValueError, match="max_terms"):
        replace(GRID, max_terms=0)
    # Polishing is a stage of the budget's refinements only.
    assert cfg.train_config("all", 2, "poly1+inputs", 1e-3, refine=True).regressor().polish == ("flight",)
    assert GRID.train_config("all", 2, "poly1+inputs", 1e-3, refine=True).regressor().polish == ()
    assert "flight refined again alone" in selection_rule(cfg)


def _cand(cell, terms, short, meets_short=False):
    """An exact candidate of cell (encoder, l, library) with ``terms`` and 0.1 s score ``short``."""
    worst = None if short is None else (0.9 if meets_short else 1.5)
    return {"encoder": cell[0], "latent_dim": cell[1], "library": cell[2], "refine": False, "active_terms": terms,
            "score": None, "horizons": {"full": {"worst": None, "score": None},
                                        "0.1": {"worst": worst, "score": short}}}


def test_budget_refines_the_best_cell_at_short_horizons_nearest_above_the_budget():
    a, b = ("pose+joints", 6, "poly1+inputs"), ("pose+joints", 7, "poly1+inputs")
    rows = [_cand(a, 157, 0.39, True), _cand(a, 188, 0.40, True), _cand(a, 114, 0.46),
            _cand(b, 98, None), _cand(b, 154, None), _cand(b, 215, 0.358, True), _cand(b, 257, 0.357, True),
            _cand(b, 40, 0.8)]
    assert to_refine(rows, 2, reference=True) == [0, 1]  # no budget: the sparsest meeting at 0.1 s
    # With one: those, then the cell best at 0.1 s from its sparsest thresholds at or above the
    # budget (its own 0.1 s scores do not matter: diverged ones too), then the densest below it.
    assert to_refine(rows, 2, reference=True, max_terms=60) == [0, 1, 3, 4]
    assert to_refine(rows, 5, reference=True, max_terms=60) == [0, 1, 5, 6, 2, 3, 4, 7]
    # a budget the usual picks fit in refines nothing more
    assert to_refine(rows, 1, reference=True, max_terms=300) == [0]
    assert to_refine(rows[:1] + rows[3:], 1, reference=True, max_terms=150) == [0, 2]  # 157 > 150: 154 of b
    # none pruned beyond PRUNE_REACH (3) times the budget: of b's only 40 within 3 x 30 = 90 terms
    assert to_refine(rows, 2, reference=True, max_terms=30) == [0, 1, 7]
    # a candidate a check refuses for good (physics, integrator) is not refined
    rows[0]["refused"] = [{"check": "physics", "reason": "its flight falls upward"}]
    rows[1]["refused"] = [{"check": "free", "reason": "its free prediction diverged"}]
    assert to_refine(rows, 2, reference=True) == [1, 5]


def test_bad_grids_are_named():
    with pytest.raises(ValueError, match="unknown encoder"):
        SelectionConfig(encoders=("joints",))
    with pytest.raises(ValueError, match="unknown block 'cubic'"):
        parse_library("poly1+cubic")
    with pytest.raises(ValueError, match="needs a poly"):
        parse_library("trig+inputs")
    assert parse_library("poly2+inputs") == {"poly_order": 2, "trig": False, "inputs": True}


def test_cli_train_select(small_block, tmp_path):
    ds = small_block
    data = tmp_path / "d.h5"
    write_dataset(ds, data)
    r = CliRunner().invoke(app, ["train", str(data), "--select", "--select-dims", "2", "--out", str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    assert {p.name for p in (tmp_path / "m").iterdir()} == {"model.json", "selection.json", "equations.txt"}
    assert "chosen of" in r.output
    # on two local workers (their fork server started before the command imports the selection)
    # the table is the same
    r = CliRunner().invoke(app, ["train", str(data), "--select", "--select-dims", "2", "--workers", "2",
                                 "--out", str(tmp_path / "m2")])
    assert r.exit_code == 0, r.output
    one, two = (json.loads((tmp_path / d / "selection.json").read_text()) for d in ("m", "m2"))
    assert _table(two["rows"]) == _table(one["rows"]) and two["chosen"] == one["chosen"]
    assert two["execution"]["workers"] == 2
    # explicit settings --select would not use are refused, before any work
    one_line_error(CliRunner().invoke(app, ["train", str(data), "--select", "--threshold", "0.05", "--no-trig",
                                            "--out", str(tmp_path / "ignored")]),
                   "--threshold", "--trig/--no-trig", "not used with --select")
    assert not (tmp_path / "ignored").exists()
    no_val = tmp_path / "noval.h5"
    write_dataset(replace(ds, split=np.where(ds.split == "val", "train", ds.split)), no_val)
    one_line_error(CliRunner().invoke(app, ["train", str(no_val), "--select", "--out", str(tmp_path / "n")]),
                   "'val'")
    assert not (tmp_path / "n").exists()


def _table(rows):
    """Rows as JSON would store them, without their timings."""
    return [{k: v for k, v in r.items() if k != "seconds"} for r in json.loads(json.dumps(rows))]


def test_interrupted_selection_resumes_from_its_cells(selected, tmp_path):
    ds, sel = selected
    cells = tmp_path / "cells"

    class Interrupted(Exception):
        pass

    def stop_after_one(done, total, what):
        if done == 1:
            raise Interrupted

    with pytest.raises(Interrupted):
        select(ds, GRID, progress=stop_after_one, cells_dir=cells)
    assert len(list(cells.glob("*.json"))) == 1
    seen = []
    again = select(ds, GRID, progress=lambda done, total, what: seen.append(what), cells_dir=cells)
    assert sum(w.endswith("(reused)") for w in seen) == 1
    assert again.execution["cells_reused"] == 1 and again.execution["cells_run"] == 1
    assert _table(again.rows) == _table(sel.rows) and again.chosen == sel.chosen
    assert len(list(cells.glob("*.json"))) == 2
    # A setting that changes the rows of a cell leaves the stored cells unused.
    other = select(ds, replace(GRID, alpha=1e-3), cells_dir=cells)
    assert other.execution["cells_reused"] == 0


def test_cli_train_select_resume(small_block, tmp_path):
    ds = small_block
    data = tmp_path / "d.h5"
    write_dataset(ds, data)
    out = tmp_path / "m"
    parts = tmp_path / "m.parts"
    parts.mkdir()
    (parts / "all_l02_poly1+inputs.json").write_text("{}")  # a stale cell: run again
    args = ["train", str(data), "--select", "--select-dims", "2", "--out", str(out)]
    one_line_error(CliRunner().invoke(app, args), "m.parts holds an interrupted selection", "--resume")
    one_line_error(CliRunner().invoke(app, ["train", str(data), "--out", str(out), "--resume"]),
                   "--resume apply to --select")
    r = CliRunner().invoke(app, [*args, "--resume"])
    assert r.exit_code == 0, r.output
    assert not parts.exists() and (out / "selection.json").exists()
    table = json.loads((out / "selection.json").read_text())
    assert table["version"] == 3 and table["execution"]["backend"] == "local"
    assert table["execution"]["cells_run"] == len(SelectionConfig(latent_dims=(2,)).cells())
    assert table["execution"]["cells_reused"] == 0
    refused = table["refusals"]
    assert (f"refused for use: {refused['physics']} candidate(s) on physics, {refused['integrator']} by the "
            f"integrator, {refused['free']} in free prediction") in " ".join(r.output.split())
