"""`symrom reproduce` end to end on tiny simulated datasets placed in the run directory."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import pytest
from _simdata import reference_file

from symrom.experiments.reproduce import ReproduceConfig, reproduce
from symrom.learn.training import AdamConfig


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("reproduce")
    (d / "data").mkdir()
    # Datasets already in DIR are reused, never regenerated: these small ones stand in for
    # the paper-sized sets so that the whole orchestration runs in seconds.
    shutil.copy(reference_file("pronk"), d / "data" / "go1_sim.h5")
    shutil.copy(reference_file("froggy"), d / "data" / "a1_sim.h5")
    shutil.copy(reference_file("pronk", noise=True), d / "data" / "go1_noisy.h5")
    shutil.copy(reference_file("pronk"), d / "data" / "go1_proxy.h5")
    shutil.copy(reference_file("pronk", noise=True), d / "data" / "go1_randomized.h5")
    shutil.copy(reference_file("pronk"), d / "data" / "go1_proxy_mujoco.h5")
    shutil.copy(reference_file("froggy"), d / "data" / "a1_randomized.h5")
    shutil.copy(reference_file("froggy"), d / "data" / "a1_proxy_mujoco.h5")
    before = {p.name: p.stat().st_mtime for p in (d / "data").iterdir()}
    quick = ReproduceConfig.quick()
    # One train and one val jump per file: too few to judge a model's physics or its free prediction
    # by (tests/test_select_use.py does), so the checks refuse nothing here; the table holds them.
    # The evaluations' jump figures are left out (the report draws its own; the demo's test and
    # tests/test_frontdoor.py see them drawn), a third of this run otherwise.
    cfg = replace(quick, sweep_dims=(1, 2), sweep_seeds=2, workers=1,
                  adam=AdamConfig(epochs=2, refine_epochs=1, threshold_every=1),
                  selection=replace(quick.selection, checks=()), jump_figures=False)
    summary = reproduce(d, cfg, command="test")
    return d, summary, before, cfg


def test_summary_follows_the_contract(run):
    d, summary, before, _ = run
    on_disk = json.loads((d / "summary.json").read_text())
    assert on_disk["experiments"].keys() == {"go1_sim", "a1_sim", "go1_proxy"}
    for name, exp in on_disk["experiments"].items():
        for key in ("latent_dim", "poly_order", "n_candidates", "active_terms", "equations", "metrics"):
            assert key in exp, (name, key)
        assert set(exp["metrics"]["horizons"]) == {"full", "0.1"}
        assert set(exp["active_terms"]) == set(exp["equations"])
    assert set(on_disk["experiments"]["a1_sim"]["active_terms"]) == {"contact", "partial", "flight"}
    # the BLAS kernels the run's arithmetic went through (their rounding is in the data's bits)
    from symrom.execution import blas_kernels

    assert on_disk["run"]["versions"]["blas"] == "; ".join(blas_kernels()) != ""
    for name in ("go1_sim", "a1_sim"):
        for b in ("aslip", "aslip_rollout", "newton"):
            assert (set(on_disk["experiments"][name]["baselines"][b]["horizons"]["full"]["components"])
                    == {"x", "y", "z"})
    assert set(on_disk["experiments"]["go1_sim"]["solvers"]) == {"exact", "adam"}
    sweep = on_disk["sweep"]
    assert sweep["latent_dims"] == [1, 2] and len(sweep["E_dec"]) == 2 and len(sweep["E_dec"][0]) == 2
    assert sweep["best_latent_dim"] in (1, 2) and len(sweep["L_mod"]) == 2
    after = {p.name: p.stat().st_mtime for p in (d / "data").iterdir()}
    assert {k: after[k] for k in before} == before  # reused
    assert (d / "go1_sim" / "eval" / "metrics.json").is_file() and not list(d.rglob("jump_*.png"))  # as asked
    # beside them, each target as its logs and as imported through the repair
    assert set(after) - set(before) == {f"{t}{x}" for t in ("go1_proxy", "go1_proxy_mujoco", "a1_proxy_mujoco")
                                        for x in (".csv", "_repaired.h5")}
    go1 = on_disk["experiments"]["go1_sim"]
    assert set(go1["paper_defaults"]["metrics"]["horizons"]) == {"full", "0.1"}
    from symrom.model.persistence import load_model

    # The summary states the settings the validation selection chose, and the model file has them.
    table = json.loads((d / "go1_sim" / "selection" / "selection.json").read_text())
    chosen = table["rows"][table["chosen"]]
    assert {k: go1["config"][k] for k in ("encoder", "latent_dim", "library", "threshold", "refine")} == \
        {k: chosen[k] for k in ("encoder", "latent_dim", "library", "threshold", "refine")}
    model = load_model(d / go1["model"])
    assert model.latent_dim == chosen["latent_dim"] and model.provenance.selection.encoder == chosen["encoder"]
    if chosen["encoder"] == "base_position":
        assert abs(model.autoencoder.W_e[:, :12]).max() == 0 and abs(model.autoencoder.W_e[:, 15:]).max() == 0
    paper = load_model(d / go1["paper_defaults"]["model"])
    assert paper.library.n_features == 15 and paper.latent_dim == 2  # the paper's Table 1
    assert load_model(d / "a1_sim" / "paper_defaults" / "model.json").library.n_features == 29


def test_manifest_lists_every_experiment_with_its_role(run):
    from symrom.evaluate.records import Metrics, read_manifest

    d, summary, *_ = run
    entries = read_manifest(json.loads((d / "summary.json").read_text())["manifest"])
    roles = {e.name: e.role for e in entries}
    expected = {"go1_sim/solvers/exact": "solver", "go1_sim/solvers/adam": "solver",
                "go1_proxy": "fine_tuned", "sweep": "sweep"}
    for name in ("go1_sim", "a1_sim"):
        expected |= {name: "learned", f"{name}/paper_defaults": "learned", f"{name}/selection": "selection",
                     f"{name}/aslip": "baseline", f"{name}/aslip_rollout": "baseline", f"{name}/newton": "baseline",
                     f"{name}/newton_fitted": "baseline"}
    assert roles == expected
    for e in entries:
        for key, rel in e.files.items():
            assert (d / rel).exists(), (e.name, key, rel)
        if "metrics" in e.files:
            Metrics.read(d / e.files["metrics"])  # every metrics file reads as typed records
    by = {e.name: e for e in entries}
    assert by["go1_sim/paper_defaults"].of == "go1_sim" and by["go1_sim"].paper == "go1_sim"
    assert by["go1_sim/solvers/adam"].facts["wall_time_s"] > 0
    assert Metrics.read(d / by["go1_proxy"].files["before"]).to_dict() == summary["experiments"]["go1_proxy"][
        "before_finetune"]


def test_sim2real_table_on_every_target(run):
    from symrom.data.io import read_dataset
    from symrom.experiments.reproduce import DEFAULT_METHOD, PROXY_METHODS, proxy_selection, sim2real_checks

    d, summary, _, cfg = run
    tolerance = proxy_selection(cfg).tolerance
    s2r = json.loads((d / "summary.json").read_text())["sim2real"]
    assert s2r["sources"] == {"noisy": "go1_noisy", "randomized": "go1_randomized", "a1_randomized": "a1_randomized"}
    assert set(s2r["targets"]) == {"go1_proxy", "go1_proxy_mujoco", "a1_proxy_mujoco"}
    for name, t in s2r["targets"].items():
        choice = json.loads((d / name / "finetune_choice.json").read_text())
        n_sources = 2 if name.startswith("go1") else 1  # x 2 variants
        assert choice["split"] == "val" and len(choice["rows"]) == 2 * n_sources * len(PROXY_METHODS)
        # fitted and judged on the target imported through the repair: these clean logs come through as logged
        logged, repaired = read_dataset(d / t["data_logged"]), read_dataset(d / t["data"])
        assert t["data"] == f"data/{name}_repaired.h5" and t["repair"]["planted"] is None
        assert t["repair"]["found"]["jumps"] == logged.n_jumps and t["repair"]["found"]["changed"] == 0
        for k in ("t", "q", "dq", "tau", "contact"):
            assert (getattr(repaired, k) == getattr(logged, k)).all(), k
        assert (repaired.split == logged.split).all()
        assert t["chosen_source"] == choice["rows"][choice["chosen"]]["source"]
        tuned = [r for r in choice["rows"] if r["finetune"] == DEFAULT_METHOD and r["score"] is not None]
        if not tuned:  # no default fine-tuning scored on val (one train jump here): the chosen row's source
            assert t["source_model"] == t["chosen_source"]
        else:
            near = {r["source"] for r in tuned if r["score"] <= (1 + tolerance) * min(u["score"] for u in tuned)}
            as_is = {r["source"]: r["score"] for r in choice["rows"] if r["finetune"] == "none"}
            assert t["source_model"] in near  # fine-tuned, within the selection's tolerance of the best on val
            if all(as_is.get(s) is not None for s in near):  # of those, the best as it is on val
                assert as_is[t["source_model"]] == min(as_is[s] for s in near)
        for col in ("logged", "source", "fine_tuned", "target_alone", "chosen"):
            e = t[col]
            if col == "fine_tuned" and "refused" in e:  # refused on val (a train jump or two here): the reason kept
                assert set(e) == {"refused"} and "val" in e["refused"]
                assert json.loads((d / name / "fine_tuned" / "refused.json").read_text()) == e
                continue
            assert {"x_rmse", "z_rmse", "diverged_jumps", "drifted_jumps", "flight_acc", "flight_ratio"} <= set(e)
            folder = {"logged": f"sources_eval_logged/{t['source_model']}",
                      "source": f"sources_eval/{t['source_model']}", "fine_tuned": "fine_tuned/eval",
                      "target_alone": "target_alone/eval", "chosen": "eval"}[col]
            metrics = json.loads((d / name / folder / "metrics.json").read_text())
            assert e["z_rmse"] == metrics["horizons"]["full"]["components"]["z"]["rmse"]
        assert t["checks"] == sim2real_checks(t)


def test_rerun_resumes_without_retraining(run):
    d, _, _, cfg = run
    stamp = (d / "go1_sim" / "model.json").stat().st_mtime
    again = reproduce(d, cfg, command="test")
    assert (d / "go1_sim" / "model.json").stat().st_mtime == stamp
    assert again["experiments"]["go1_sim"]["metrics"] == json.loads(
        (d / "go1_sim" / "eval" / "metrics.json").read_text())


def test_report_builds_from_the_run(run):
    from symrom.report.html import build_report

    d, *_ = run
    html, md = build_report(d, d / "report.html")
    text = html.read_text()
    for section in ("Table 2", "aSLIP", "trade-off", "equations", "Data", "ommand"):
        assert section.lower() in text.lower(), section
    assert md.is_file()
    md_text = md.read_text()
    # one floor row per table: joints and base pose of the 5 learned and fine-tuned models
    assert "with the paper's defaults" in md_text and md_text.count("reconstruction floor RMSE") == 10
    assert "the go1_sim model (encoder: " in md_text
    assert "Model selection on the validation split" in md_text and "stability of each phase" in md_text
    assert "go1_proxy before fine-tuning" in md_text and "| exact |" in md_text and "| adam |" in md_text
    assert "Sim-to-real: logged, repaired and fine-tuned" in md_text
    assert "| go1_proxy_mujoco | repaired: target alone |" in md_text
    assert "| a1_proxy_mujoco | as logged: source as is (a1_randomized/" in md_text
    assert "a1_proxy_mujoco: logged without faults; repaired 0 of 3 jumps" in md_text


def test_an_unrefined_model_drops_what_only_the_refinement_reads():
    """The exact source and an unrefined target-alone model of a sim-to-real target are trained
    with the SIM settings less the refinement: its term budget and polish stages go with it."""
    from symrom.experiments.reproduce.sim2real import unrefined
    from symrom.learn.training import TrainConfig

    refined = TrainConfig(latent_dim=3, refine=True, max_terms=60, polish=("flight",))
    plain = unrefined(refined)
    assert not plain.refine and plain.max_terms is None and plain.polish == ()
    assert plain.latent_dim == 3 and unrefined(plain) == plain
    assert unrefined(TrainConfig(refine=True, max_terms=60, keep=("flight",))).keep == ()


def test_sim_to_real_leaves_out_the_soft_budget_s_pruning():
    """A SIM pick pruned to the soft budget (``keep``) gives the sources and targets its
    unpruned refinement's settings; a hard budget (``reproduce --max-terms``) stays."""
    from symrom.experiments.reproduce.sim2real import transferred
    from symrom.learn.training import TrainConfig

    soft = TrainConfig(latent_dim=4, refine=True, max_terms=60, keep=("flight",))
    unpruned = transferred(soft, None)
    assert unpruned.refine and unpruned.max_terms is None and unpruned.keep == () and unpruned.latent_dim == 4
    hard = TrainConfig(latent_dim=4, refine=True, max_terms=60, polish=("flight",))
    assert transferred(hard, 60) == hard


def test_the_solver_comparison_beside_the_run_gives_what_it_gives_in_the_run(run, tmp_path):
    # With more than one worker the comparison runs in a process of its own beside the rest;
    # the run then reads what it wrote. The numbers are those of the run's own process (adam on
    # one thread, seeded): a process that computed wrong, or a read-back that lost a key, differs.
    from symrom.experiments.reproduce.run import solvers_beside
    from symrom.experiments.reproduce.steps import selected_config
    from symrom.model.persistence import load_model

    d, summary, _, cfg = run
    (tmp_path / "go1_sim").mkdir()
    settings = selected_config(load_model(d / "go1_sim" / "model.json"))
    said = []
    beside = solvers_beside(tmp_path, d / "data" / "go1_sim.h5", settings, replace(cfg, workers=2),
                     lambda msg, transient=False: said.append(msg))
    assert beside.process is not None and "beside the rest" in said[0]
    got = beside.result()
    assert not beside.process.is_alive() and beside.process.exitcode == 0
    inline = summary["experiments"]["go1_sim"]["solvers"]
    for solver in ("exact", "adam"):
        mine = {k: v for k, v in got[solver]["metrics"].items() if k != "model"}  # where the model is
        assert mine == {k: v for k, v in json.loads(json.dumps(inline[solver]["metrics"])).items() if k != "model"}
        assert got[solver]["active_terms"] == inline[solver]["active_terms"]
        assert (tmp_path / "go1_sim" / "solvers" / solver / "model.json").is_file()


def test_a_step_beside_the_run_that_fails_is_done_again_in_the_run_and_its_error_raised(tmp_path, capfd):
    # The process beside the run exits with 1 and prints nothing; the run's own process then does
    # the step itself and raises its error, naming what is wrong.
    from symrom.experiments.reproduce.config import DatasetSpec, ReproduceConfig
    from symrom.experiments.reproduce.run import Beside, ensure_datasets

    bad = DatasetSpec("bad", "no_such_robot", "pronk", 2)
    said = []
    step = Beside("datasets: bad", ensure_datasets, (tmp_path, [bad]), ReproduceConfig(workers=2),
                  lambda m, transient=False: said.append(m))
    assert step.process is not None and said == ["datasets: bad: beside the rest of the run"]
    step.process.join()
    assert step.process.exitcode == 1
    with pytest.raises(Exception, match="no_such_robot"):
        step.result()
    assert not (tmp_path / "data" / "bad.h5").exists()
    assert "Traceback" not in capfd.readouterr().err
